"""platform sweep: options refused before any run, the CSV, the summary, the plot."""

from __future__ import annotations

import csv
import math
import sys
from dataclasses import replace

import pytest
from click.testing import CliRunner

from msrr.core.app.cli import get_cli
from msrr.core.app.commands.sweep import (
    SweepRow,
    _locomotion,
    setting_label,
    summarize,
    sweep_csv,
    sweep_title,
)
from msrr.core.events import BehaviorVerdict

BASE = ["sweep", "--robot", "mmrp", "--scenario", "series-t", "--driver", "kinematic",
        "--workers", "1"]


def _row(faults: str, seed: int, success: bool, rms: float, time: float,
         reason: str = "") -> SweepRow:
    return SweepRow(faults=faults, seed=seed, success=success, reason=reason, actions_done=8,
                    actions_total=8, docks=2, undocks=2, retries=0, sim_time_s=time,
                    position_rms_m=rms, position_max_m=rms, heading_max_rad=0.0,
                    shape_error_deg=math.nan, faults_met=0)


def test_summary_counts_successes_and_spreads_per_setting():
    rows = [_row("", 0, True, 0.001, 4.0), _row("", 1, True, 0.003, 6.0),
            _row("loss:p=0.5", 0, False, math.nan, 9.0, "action 2 timed out: x"),
            _row("loss:p=0.5", 1, True, 0.002, 5.0)]
    first, second = summarize(rows)
    assert first[:3] == ["none", 2, "2/2 (100%)"]
    assert first[3] == "2.00 / 2.80 / 3.00" and first[5] == "5.0 / 5.8 / 6.0"
    assert first[4] == "-"  # no strut angles for this robot
    assert second[:4] == ["loss:p=0.5", 2, "1/2 (50%)", "2.00 / 2.00 / 2.00"]
    assert first[6] == first[7] == "-"  # no behavior asked a distance or a direction
    assert second[8] == "action 2 timed out (1)"
    table = list(csv.reader(sweep_csv(rows).splitlines()))
    assert table[0][:3] == ["faults", "seed", "success"] and len(table) == 5
    assert table[3][table[0].index("position_rms_m")] == ""  # nan: an empty cell


def test_the_title_names_the_driver_options_and_each_label_its_successes():
    assert sweep_title("freesn", "fig21", 10, ()) == "freesn fig21: 10 seeds"
    assert sweep_title("freesn", "fig21", 10, (("noise", "0.0698"), ("slip", "0.10"))) \
        == "freesn fig21 with noise=0.0698 slip=0.10: 10 seeds"
    rows = [_row("", 0, True, 0.001, 4.0), _row("", 1, False, math.nan, 9.0, "x"),
            _row("loss:p=0.5", 0, True, 0.002, 5.0)]
    assert setting_label(rows, "") == "none\n1/2 succeed"
    assert setting_label(rows, "loss:p=0.5") == "loss:p=0.5\n1/1 succeed"


def test_a_runs_worst_behavior_is_its_least_covered_and_its_largest_heading_error():
    verdicts = [BehaviorVerdict("a", 0, 1, 10.0, 0.5, 0.4, 0.5, math.radians(12.0), "", True, ""),
                BehaviorVerdict("b", 1, 1, 10.0, 0.3, 0.15, 0.6, math.radians(3.0), "", True, ""),
                BehaviorVerdict("turn", 2, 1, 10.0, 0.0, None, None, None, "", True, "")]
    worst = _locomotion(verdicts)
    assert worst["covered_min"] == pytest.approx(0.25)
    assert worst["heading_error_max_deg"] == pytest.approx(12.0)
    assert (worst["covered_min_by"], worst["heading_error_max_by"]) == ("b", "a")
    none = _locomotion(verdicts[2:])
    assert math.isnan(none["covered_min"]) and math.isnan(none["heading_error_max_deg"])
    assert none["covered_min_by"] == none["heading_error_max_by"] == ""
    rows = [replace(_row("", s, True, 0.001, 4.0), **_locomotion(verdicts[:k]))
            for s, k in ((0, 1), (1, 2))]
    covered, heading = summarize(rows)[0][6:8]
    assert covered.endswith(" / 0.80 (least: b)") and heading == "12.0 / 12.0 / 12.0 (a)"


def test_the_table_names_the_behavior_that_strayed_most():
    """A run of two behaviors says which one went off (stop 54 put fig22's misses on its
    wheeled move; they were the node wheels after it, issue 31)."""
    wheeled = BehaviorVerdict("wheeled-move(speed=0.05)", 3, 1, 60.0, 0.9, 0.88, 3.0,
                              math.radians(4.0), "", True, "")
    nodes = BehaviorVerdict("node-wheels(speed=0.03)", 6, 1, 60.0, 0.5, -0.39, 1.8,
                            math.radians(146.0), "", False, "")
    row = replace(_row("", 15, False, math.nan, 174.0, "x"), **_locomotion([wheeled, nodes]))
    assert row.heading_error_max_by == row.covered_min_by == "node-wheels(speed=0.03)"
    table = list(csv.reader(sweep_csv([row]).splitlines()))
    assert table[1][table[0].index("heading_error_max_by")] == "node-wheels(speed=0.03)"
    covered, heading = summarize([row])[0][6:8]
    assert covered.endswith("(least: node-wheels)") and heading.endswith("(node-wheels)")


@pytest.mark.parametrize(("args", "message"), [
    (["--faults", "bogus"], "unknown kind 'bogus'"),
    (["--from", "x.json"], "give both --from and --to"),
    (["--workers", "-1"], "-1 is not in the range x>=0"),
])
def test_bad_options_fail_in_one_line_before_any_run(tmp_path, args, message):
    result = CliRunner().invoke(get_cli(), [*BASE, *args, "--out", str(tmp_path / "o")])
    assert result.exit_code != 0 and message in result.output
    assert not (tmp_path / "o").exists()


def test_sweep_writes_the_table_and_says_how_to_get_the_plot(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    out = tmp_path / "sweep"
    result = CliRunner().invoke(get_cli(), [*BASE, "--runs", "2", "--seed", "3",
                                            "--out", str(out)])
    assert result.exit_code == 0, result.output
    rows = list(csv.DictReader((out / "sweep.csv").open()))
    assert [r["seed"] for r in rows] == ["3", "4"] and all(r["success"] == "True" for r in rows)
    assert all(r["actions_done"] == r["actions_total"] != "0" for r in rows)
    assert "2/2 (100%)" in result.output
    assert "no plot: matplotlib is missing; pip install 'msrr-platform[plot]'" in result.output
    assert not (out / "sweep.png").exists()
    again = CliRunner().invoke(get_cli(), [*BASE, "--runs", "1", "--out", str(out)])
    assert again.exit_code == 1 and "use --force" in again.output
