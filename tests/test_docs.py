"""The documentation keeps up with the code: hooks, install command, links."""

from __future__ import annotations

import inspect
import re

import pytest

from msrr.core import hookspecs

from msrr_test_support import ROOT

HOOKS = sorted(name for name in dir(hookspecs) if name.startswith("msrr_"))


@pytest.mark.parametrize("hook", HOOKS)
def test_every_hook_is_documented_in_the_plugin_guide(hook: str) -> None:
    params = ", ".join(inspect.signature(getattr(hookspecs, hook)).parameters)
    assert f"`{hook}({params})" in (ROOT / "docs/writing-a-plugin.md").read_text()


def _install_command(text: str) -> str:
    return re.search(r"^pip install -e .*$", text, re.MULTILINE).group(0)


def test_ci_installs_with_the_readme_command() -> None:
    readme = _install_command((ROOT / "README.md").read_text())
    assert readme == _install_command((ROOT / ".ci/run").read_text())


def test_readme_links_resolve() -> None:
    for target in re.findall(r"\]\(((?:docs|examples)/[^)#]+)\)", (ROOT / "README.md").read_text()):
        assert (ROOT / target).exists(), target
