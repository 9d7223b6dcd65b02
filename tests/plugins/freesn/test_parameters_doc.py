"""Every figure of the FreeSN robot description has a row in docs/freesn.md's parameter
table (issue 32, item 7): the value the description holds, a source or "assumption"."""

from __future__ import annotations

import re

import pytest

from msrr.plugins.freesn.robot import SPEC
from msrr.plugins.freesn.sim.options import Physical, SimOptions

from msrr_test_support import ROOT

SECTION = "## Hardware parameters and their sources"
_NUMBER = re.compile(r"(?<![\w.])\d+(?:\.\d+)?")


def _rows() -> list[list[str]]:
    """The cells of the section's parameter table (header and rule left out)."""
    text = (ROOT / "docs" / "freesn.md").read_text()
    section = text.split(SECTION, 1)[1].split("\n## ", 1)[0]
    lines = [ln for ln in section.splitlines() if ln.startswith("| ")]
    return [[c.strip() for c in ln.strip("|").split(" | ")] for ln in lines[1:]]


def _numbers(cell: str) -> list[float]:
    return [float(n) for n in _NUMBER.findall(cell)]


def _row(name: str) -> list[list[str]]:
    return [r for r in _rows() if f"`{name}`" in r[0]]


GEOMETRY = [(kind.name, key, float(value)) for kind in SPEC.module_kinds
            for key, value in kind.geometry.items()]


@pytest.mark.parametrize(("kind", "key", "value"), GEOMETRY,
                         ids=[f"{k}.{key}" for k, key, _ in GEOMETRY])
def test_every_geometry_figure_has_its_value_and_a_source(kind: str, key: str,
                                                          value: float) -> None:
    rows = _row(f"{kind}.{key}")
    assert rows, f"docs/freesn.md has no parameter row for `{kind}.{key}`"
    assert any(value in _numbers(r[1]) for r in rows), \
        f"`{kind}.{key}` = {value} is not in the 'ours' cell of its row: {rows}"
    for r in rows:
        assert "assumption" in r[4] or "[" in r[3], f"`{kind}.{key}` has no source: {r}"


def test_the_derived_rates_are_the_simulations_own() -> None:
    """The wheel ratios and the fastest rolling and turning stated for ours are what the
    world is built from (``Physical``), so a changed figure shows in the table."""
    physical = Physical.from_spec(SPEC, SimOptions())
    strut, node = SPEC.kind("strut").geometry, SPEC.kind("node").geometry
    ratios = {"rolling per wheel radian": strut["wheel_radius"] / node["radius"],
              "turning per wheel radian": 2 * strut["wheel_radius"] / strut["wheel_base"]}
    for label, ratio in ratios.items():
        (row,) = [r for r in _rows() if r[0].startswith(label)]
        assert round(ratio, 2) in _numbers(row[1]), (label, ratio, row[1])
    (row,) = [r for r in _rows() if r[0].startswith("fastest rolling")]
    assert _numbers(row[1]) == pytest.approx([physical.max_roll_rate, physical.max_spin_rate], rel=1e-3)
