"""Where ``platform run`` writes: never a shared default folder, every bad output place
refused in one line before any work, an earlier run kept unless ``--force``, files
that honour the umask."""

from __future__ import annotations

import json
import os
from collections.abc import Iterator
from pathlib import Path

import pytest
from click.testing import CliRunner
from tiny_robot import installed

from msrr.core.app import run as run_module
from msrr.core.app.cli import get_cli
from msrr.core.app.run import check_out_dir, claim_out_dir
from msrr.core.errors import ConfigurationError


def _run(tmp_path: Path, *args: str) -> tuple[int, list[str]]:
    scenario = tmp_path / "scenario"
    scenario.mkdir(exist_ok=True)
    with installed(scenario):
        result = CliRunner().invoke(get_cli(), ["run", "--robot", "tiny", *args])
    return result.exit_code, result.output.strip().splitlines()


def test_default_folders_of_runs_in_one_second_are_distinct(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(run_module, "default_out_dir",
                        lambda robot, scenario: Path("runs") / f"20260101-000000-{robot}-{scenario}")
    for _ in range(3):
        code, lines = _run(tmp_path)
        assert code == 0, lines
    folders = sorted(p.name for p in (tmp_path / "runs").iterdir())
    assert folders == ["20260101-000000-tiny-swap", "20260101-000000-tiny-swap-2",
                       "20260101-000000-tiny-swap-3"]
    for folder in folders:
        assert json.loads((tmp_path / "runs" / folder / "summary.json").read_text())["success"]


def test_claiming_a_taken_default_name_picks_the_next(tmp_path: Path) -> None:
    first = claim_out_dir(tmp_path / "stamp", default=True)
    second = claim_out_dir(tmp_path / "stamp", default=True)
    assert (first.name, second.name) == ("stamp", "stamp-2") and second.is_dir()


@pytest.mark.parametrize("place", ["file", "under-file", "unwritable", "empty", "no-log-file"])
def test_every_bad_output_place_is_one_line_before_any_work(tmp_path: Path, place: str) -> None:
    (tmp_path / "a.txt").write_text("keep")
    (tmp_path / "scenario").mkdir()
    out, extra = {"file": (str(tmp_path / "a.txt"), []),
                  "under-file": (str(tmp_path / "a.txt" / "run"), []),
                  "unwritable": ("/proc/msrr-run", []),
                  "empty": ("", []),
                  "no-log-file": (str(tmp_path / "a.txt"), ["--no-log"])}[place]
    before = sorted(p.name for p in tmp_path.iterdir())
    code, lines = _run(tmp_path, "--out", out, *extra)
    assert code == 1 and len(lines) == 1 and lines[0].startswith("Error:"), lines
    assert "--out" in lines[0]
    assert (tmp_path / "a.txt").read_text() == "keep"
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_a_folder_holding_a_run_is_kept_unless_force(tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert _run(tmp_path, "--out", str(out))[0] == 0
    stamp = (out / "summary.json").stat().st_mtime_ns
    code, lines = _run(tmp_path, "--out", str(out))
    assert code == 1 and lines == [
        f"Error: {out}: --out: holds a run (run.rrd, plan.json, summary.json); use --force to "
        "replace it"]
    assert (out / "summary.json").stat().st_mtime_ns == stamp
    code, lines = _run(tmp_path, "--out", str(out), "--force", "--no-log")
    assert code == 0 and lines[0] == (f"note: {out} held a run (run.rrd, plan.json, "
                                      "summary.json): replaced")
    # the earlier run's recording is gone: nothing in the folder describes another run
    assert sorted(p.name for p in out.iterdir()) == ["plan.json", "summary.json"]


def test_an_empty_existing_folder_is_fine(tmp_path: Path) -> None:
    (tmp_path / "out").mkdir()
    assert check_out_dir(tmp_path / "out") == []
    with pytest.raises(ConfigurationError, match="is empty"):
        check_out_dir(Path(" "))


@pytest.fixture
def umask() -> Iterator[None]:
    old = os.umask(0o027)
    yield
    os.umask(old)


def test_every_file_honours_the_umask(tmp_path: Path, umask: None) -> None:
    out = tmp_path / "out"
    assert _run(tmp_path, "--out", str(out))[0] == 0
    modes = {p.name: p.stat().st_mode & 0o777 for p in out.iterdir()}
    assert modes == {"run.rrd": 0o640, "plan.json": 0o640, "summary.json": 0o640}


@pytest.mark.parametrize("place", ["folder", "under-file", "unwritable"])
def test_snapshot_refuses_a_bad_image_place_in_one_line_before_reading(
        tmp_path: Path, place: str) -> None:
    (tmp_path / "a.txt").write_text("keep")
    output = {"folder": tmp_path, "under-file": tmp_path / "a.txt" / "x.png",
              "unwritable": Path("/proc/msrr.png")}[place]
    result = CliRunner().invoke(get_cli(), ["snapshot", str(tmp_path / "missing.rrd"),
                                            "-o", str(output)])
    lines = result.output.strip().splitlines()
    assert result.exit_code == 1 and len(lines) == 1 and "--output" in lines[0], lines


def test_a_saved_plan_runs_as_saved_and_a_bad_one_is_one_line(tmp_path: Path) -> None:
    first = tmp_path / "first"
    assert _run(tmp_path, "--out", str(first), "--no-log")[0] == 0
    saved = json.loads((first / "plan.json").read_text())
    code, lines = _run(tmp_path, "--plan", str(first / "plan.json"), "--out",
                       str(tmp_path / "again"), "--no-log")
    assert code == 0, lines
    again = json.loads((tmp_path / "again" / "plan.json").read_text())
    assert again == saved  # executed as saved: the planner was not asked again
    assert json.loads((tmp_path / "again" / "summary.json").read_text())["success"]

    broken = tmp_path / "broken.json"
    broken.write_text(json.dumps({**saved, "actions": [{**saved["actions"][0], "cost": "x"}]}))
    for args, message in (
            (["--plan", str(broken)], f"Error: {broken}: actions[0].cost:"),
            (["--plan", str(first / "plan.json"), "--scenario", "swap"],
             "Error: give --plan, --scenario or --from/--to, one of them"),
            (["--plan", str(first / "plan.json"), "--planner", "line"],
             "Error: --plan executes a saved plan: it takes no --planner")):
        code, lines = _run(tmp_path, *args, "--out", str(tmp_path / "never"))
        assert code == 1 and len(lines) == 1 and lines[0].startswith(message), lines
        assert not (tmp_path / "never").exists()
