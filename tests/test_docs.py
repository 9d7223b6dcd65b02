"""The documentation keeps up with the code: hooks, install command, links."""

from __future__ import annotations

import inspect
import re

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


def test_readme_links_resolve() -> None:
    for target in re.findall(r"\]\(((?:docs|examples)/[^)#]+)\)", (ROOT / "README.md").read_text()):
        assert (ROOT / target).exists(), target
