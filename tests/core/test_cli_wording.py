"""The command line reads well (issue 16 item 5): one name per connection, counts that
match their tables, units on goal columns, no empty columns, right plurals, one-line
errors for a missing display or an optional package."""

from __future__ import annotations

import itertools
import math
import re
import sys
from dataclasses import replace
from pathlib import Path

import pytest
from click.testing import CliRunner
from tiny_robot import chain, installed, swap_plan

from msrr.core import Action, ActionType, ConnectionChange, MsrrError, Plan
from msrr.core.app.cli import get_cli
from msrr.core.app.commands.plan import action_rows, plan_counts
from msrr.core.console import counts, plural, require
from msrr.core.plan import natural_key
from msrr.core.plugins import load_configuration

from msrr_test_support import ROOT

SHIPPED = [ROOT / "plugins/freesn/configs/triangle-leg.json", ROOT / "plugins/mmrp/configs/t.json",
           ROOT / "plugins/snailbot/configs/tree5.json"]


def run(*args: str):
    return CliRunner().invoke(get_cli(), list(args))


def test_plural_says_one_thing_and_many_things() -> None:
    assert [plural(n, "connection") for n in (0, 1, 2)] == [
        "0 connections", "1 connection", "2 connections"]
    assert plural(1, "body", "bodies") == "1 body" and plural(3, "body", "bodies") == "3 bodies"


def test_a_connection_has_one_name_whichever_end_comes_first() -> None:
    ids, ports = ["3", "8", "10", "S2", "S10", "N1"], ["T", "B", "a", ""]
    for (m1, m2), p1, p2 in itertools.product(itertools.permutations(ids, 2), ports, ports):
        forward = ConnectionChange(m1, m2, p1 or None, p2 or None)
        backward = ConnectionChange(m2, m1, p2 or None, p1 or None)
        assert forward.label == backward.label == str(forward) == str(backward)
        assert forward.label in (f"{m1}{p1}-{m2}{p2}", f"{m2}{p2}-{m1}{p1}")
        first = forward.ends[0][0]
        assert natural_key(first) <= natural_key(m1 if first == m2 else m2)  # natural order
    assert ConnectionChange("8", "3", "B", "T").label == "3T-8B"
    assert ConnectionChange("10", "9", "T", "B").label == "9B-10T"  # 9 before 10, not "10" < "9"


def test_an_action_is_named_by_what_it_does_to_its_connections() -> None:
    plan = swap_plan()  # undock a-b, move c, dock b-c
    assert [a.label for a in plan.actions] == ["undock aT-bB", "move c", "dock bT-cB"]
    assert [str(a) for a in plan.actions] == [a.label for a in plan.actions]
    swap = Action(ActionType.PARALLEL_CONNECTION, chain(("a", "c")),
                  changes=(ConnectionChange("b", "a", "B", "T"), ConnectionChange("a", "c", "T", "B")))
    assert swap.label == "undock aT-bB; dock aT-cB"  # broken first, as executed


def _moving_plan() -> Plan:
    """undock a-b; move b and c together (two goals, one action); dock b-c."""
    plan = swap_plan()
    plan.actions[1] = replace(plan.actions[1], modules=("b", "c"),
                              goals={"b": [1.0, 0.5, math.pi / 2], "c": [2.0, -0.25, 0.0]})
    return plan


def test_the_plan_table_numbers_actions_and_its_counts_match_its_rows() -> None:
    plan = _moving_plan()
    rows = action_rows(plan.actions)
    assert [r[:2] for r in rows] == [["1", "Undock"], ["2", "Move"], ["2", "Move"], ["3", "Dock"]]
    # goals in their own columns with units (x [m], y [m], yaw [deg]), never in "Face"
    assert rows[1][2:9] == ["b", "", "", "", "+1.000", "+0.500", "+90.0"]
    assert rows[2][6:9] == ["+2.000", "-0.250", "+0.0"]
    text = plan_counts(plan)
    assert text == "3 actions: 1 undock, 1 dock, 1 move (2 modules)"
    actions = {r[0] for r in rows}
    moves = {r[0] for r in rows if r[1] == "Move"}
    assert text.startswith(f"{len(actions)} actions") and f"{len(moves)} move " in text


def _header(output: str, title: str) -> list[str]:
    lines = output.splitlines()
    at = next(i for i, line in enumerate(lines) if line.startswith(title))
    return [cell.strip() for cell in lines[at + 2].strip("┃ ").split("┃")]


def test_platform_plan_shows_goal_columns_with_units(tmp_path: Path) -> None:
    with installed(tmp_path):
        result = run("plan", "--robot", "tiny", str(tmp_path / "start.json"),
                     str(tmp_path / "goal.json"))
    assert result.exit_code == 0, result.output
    assert _header(result.output, "Actions (line)") == [
        "#", "Action", "ID", "Face", "ID", "Face", "x [m]", "y [m]", "yaw [deg]"]
    assert "3 actions: 1 undock, 1 dock, 1 move" in result.output


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.name)
def test_validate_and_show_agree_on_the_counts(path: Path) -> None:
    said = counts(load_configuration(path))
    assert re.fullmatch(r"\d+ modules?, \d+ connections?", said)
    validated, shown = run("validate", str(path)), run("show", str(path))
    assert validated.exit_code == shown.exit_code == 0, validated.output + shown.output
    assert validated.output.strip().endswith(said)
    assert f"): {said}" in shown.output.splitlines()[0]


def test_show_prints_only_columns_with_something_in_them() -> None:
    mmrp = run("show", str(ROOT / "plugins/mmrp/configs/t.json")).output
    assert _header(mmrp, "Modules (4)") == ["id", "kind", "degree"]
    assert _header(mmrp, "Connections (3)") == ["id", "ends", "ports"]
    freesn = run("show", str(ROOT / "plugins/freesn/configs/triangle-leg.json")).output
    assert _header(freesn, "Vertices (4)") == ["id", "kind", "degree"]  # v1 is a free end
    assert _header(freesn, "Connections (4)") == ["id", "ends", "kind", "z"]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="DISPLAY is X11's")
def test_gui_without_a_display_is_one_line_before_any_work(tmp_path: Path,
                                                           monkeypatch: pytest.MonkeyPatch
                                                           ) -> None:
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    out = tmp_path / "run"
    result = CliRunner().invoke(get_cli(), ["run", "--robot", "nobody", "--gui", "--out", str(out)])
    assert result.exit_code == 1
    assert result.output.startswith("Error: --gui needs a display") and result.output.count("\n") == 1
    assert not out.exists()  # before any work: not even the unknown robot was looked up


def test_a_missing_optional_package_is_named_with_its_extra(monkeypatch: pytest.MonkeyPatch
                                                            ) -> None:
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # as if not installed
    with pytest.raises(MsrrError, match=r"^platform snapshot needs matplotlib: "
                                        r"pip install 'msrr-platform\[plot\]'$"):
        require("matplotlib", "plot", "platform snapshot")
    require("json", "plot", "platform snapshot")  # installed: nothing said


def test_a_parallel_step_is_an_undock_row_and_a_dock_row_as_counted() -> None:
    start = chain(("a", "b"))
    swap = Action(ActionType.PARALLEL_CONNECTION, chain(("a", "c")),
                  changes=(ConnectionChange("b", "a", "B", "T"), ConnectionChange("a", "c", "T", "B")))
    plan = Plan("tiny", "hand", start, swap.target, [swap])
    rows = action_rows(plan.actions)
    assert [r[:6] for r in rows] == [["1", "Undock", "a", "T", "b", "B"],
                                    ["1", "Dock", "a", "T", "c", "B"]]
    assert plan_counts(plan) == "1 action: 1 undock, 1 dock, 0 moves"
    assert sum(r[1] == "Undock" for r in rows) == plan.undocks
    assert sum(r[1] == "Dock" for r in rows) == plan.docks
