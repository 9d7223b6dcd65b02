"""docs/architecture.md's capability table is what the registered plugins say."""

from __future__ import annotations

import re

from click.testing import CliRunner

from msrr.core.app.cli import get_cli

from msrr_test_support import BUILTIN_ROBOTS, ROOT

DOC = ROOT / "docs" / "architecture.md"
SECTION = re.compile(r"<!-- capabilities:start -->\n(.*?)\n<!-- capabilities:end -->", re.S)


def _rows(table: str) -> dict[str, str]:
    rows = {}
    for line in table.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if cells and cells[0] in BUILTIN_ROBOTS:
            rows[cells[0]] = line.strip()
    return rows


def test_the_capability_table_is_generated_from_the_plugins():
    result = CliRunner().invoke(get_cli(), ["robots", "--markdown"])
    assert result.exit_code == 0, result.output
    generated = result.output.splitlines()
    documented = SECTION.search(DOC.read_text()).group(1)
    assert documented.splitlines()[:2] == generated[:2], "the table's header changed"
    assert _rows(documented) == _rows(result.output), (
        "docs/architecture.md is stale: paste the built-in robots' rows of "
        "`platform robots --markdown` between the capabilities markers")
    assert set(_rows(documented)) == set(BUILTIN_ROBOTS)
