"""The documentation keeps up with the code: hooks, install command, links, file names."""

from __future__ import annotations

import inspect
import re
from pathlib import Path

import pytest

from msrr.core import hookspecs

from msrr_test_support import ROOT

HOOKS = sorted(name for name in dir(hookspecs) if name.startswith("msrr_"))


def _signature(hook: str) -> str:
    """``def msrr_x(robot: str, register: Register[Planner]) -> None``, as declared."""
    sig = inspect.signature(getattr(hookspecs, hook))
    params = ", ".join(f"{name}: {p.annotation}" for name, p in sig.parameters.items())
    return f"def {hook}({params}) -> {sig.return_annotation}"


@pytest.mark.parametrize("hook", HOOKS)
def test_every_hook_is_documented_in_the_plugin_guide(hook: str) -> None:
    lines = (ROOT / "docs/writing-a-plugin.md").read_text().splitlines()
    assert _signature(hook) in lines, f"the guide lacks the line: {_signature(hook)}"


def _install_command(text: str) -> str:
    return re.search(r"^pip install -e .*$", text, re.MULTILINE).group(0)


def test_ci_installs_with_the_readme_command() -> None:
    readme = _install_command((ROOT / "README.md").read_text())
    assert readme == _install_command((ROOT / ".ci/run").read_text())


def test_ci_tests_with_the_readme_command() -> None:
    readme = (ROOT / "README.md").read_text().split("## Test", 1)[1]
    command = re.search(r"^pytest.*$", readme, re.MULTILINE).group(0)
    assert re.search(rf"^{re.escape(command)}$", (ROOT / ".ci/run").read_text(), re.MULTILINE)


def test_readme_links_resolve() -> None:
    for target in re.findall(r"\]\(((?:docs|examples)/[^)#]+)\)", (ROOT / "README.md").read_text()):
        assert (ROOT / target).exists(), target


DOCUMENTS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")),
             *sorted(ROOT.glob("plugins/*/README.md")), *sorted(ROOT.glob("examples/*/README.md"))]
"""Every page a user reads in the repository."""

_NAMED = re.compile(r"`([^`\s]+)`|\]\(([^)\s#]+)(?:#[^)]*)?\)")
"""A code span without spaces, or a Markdown link's target."""


def _named_files(doc: Path) -> list[tuple[str, list[Path]]]:
    """The repository files ``doc`` names, each with the places it may be: paths under a
    top-level folder of the repository (``core/plan.py``, ``plugins/mmrp/configs/t.json``),
    relative links, and bare page names (``DESIGN.md``). Placeholders (``<stamp>``,
    ``*.json``, ``…``) and paths outside the repository (``runs/``, a user's files) are
    not names of repository files."""
    top = {p.name for p in ROOT.iterdir() if not p.name.startswith(".git")} - {"runs"}
    found = []
    for match in _NAMED.finditer(doc.read_text()):
        name = (match.group(1) or match.group(2)).rstrip("/")
        if name.startswith(("http:", "https:", "mailto:")) or any(c in name for c in "<>*{}$…|"):
            continue
        if "/" in name and name.split("/")[0] in top:
            found.append((name, [ROOT / name]))
        elif match.group(2):
            found.append((name, [doc.parent / name]))
        elif re.fullmatch(r"[\w.-]+\.md", name):
            found.append((name, [ROOT / name, ROOT / "docs" / name, doc.parent / name]))
    return found


@pytest.mark.parametrize("doc", DOCUMENTS, ids=lambda p: str(p.relative_to(ROOT)))
def test_docs_name_only_files_that_exist(doc: Path) -> None:
    missing = [name for name, places in _named_files(doc) if not any(p.exists() for p in places)]
    assert not missing, f"{doc.relative_to(ROOT)} names files not in the repository: {missing}"


def test_the_file_check_finds_a_missing_file(tmp_path: Path) -> None:
    page = tmp_path / "page.md"
    page.write_text("See `DESIGN.md`, `core/nothing.py`, [x](gone.md), `core/plan.py`, "
                    "`runs/<stamp>/run.rrd` and `my/own.json`.")
    missing = [n for n, places in _named_files(page) if not any(p.exists() for p in places)]
    assert missing == ["DESIGN.md", "core/nothing.py", "gone.md"]
