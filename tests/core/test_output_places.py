"""Issue 30, items 1-3: files that are not JSON objects, output places checked before
any work, and a full disk: one line, exit 1, nothing left under a final name."""

from __future__ import annotations

import errno
import json
import os
from pathlib import Path

import pytest
from click.testing import CliRunner
from tiny_robot import installed

from msrr.core import files
from msrr.core.app.cli import get_cli
from msrr.core.errors import ConfigurationError, OutputError
from msrr.core.files import atomic_write_text, read_json

ROOT = Path(__file__).resolve().parents[2]
MMRP = ROOT / "plugins/mmrp/configs"
SOURCES = ROOT / "plugins/freesn/library_sources/S6N3"


def _invoke(*args: str) -> tuple[int, list[str]]:
    result = CliRunner().invoke(get_cli(), list(args))
    assert result.exception is None or isinstance(result.exception, SystemExit), \
        result.exception
    return result.exit_code, result.output.strip().splitlines()


# -- item 1: a file whose whole content is not an object -------------------------------


@pytest.mark.parametrize("content, what", [
    ("null", "null"), ("1", "a number"), ("true", "a boolean"), ('"text"', "a string"),
    ("[1, 2]", "a list"), ("[]", "a list"), ("1e999", "a number"), ("[" * 70 + "]" * 70,
                                                                    "a list")])
def test_a_document_that_is_not_an_object_is_refused_in_one_line(
        tmp_path: Path, content: str, what: str) -> None:
    path = tmp_path / "n.json"
    path.write_text(content)
    with pytest.raises(ConfigurationError) as caught:
        read_json(path)
    assert str(caught.value) == f"{path}: holds {what}, not a JSON object ({{...}})"


READERS = [["validate"], ["show"], ["library", "show"], ["match"], ["plan"]]


@pytest.mark.parametrize("command", READERS, ids=" ".join)
@pytest.mark.parametrize("content", ["null", "1", "true", '"s"', "[]"])
def test_every_reading_command_refuses_a_document_that_is_not_an_object(
        tmp_path: Path, command: list[str], content: str) -> None:
    path = tmp_path / "n.json"
    path.write_text(content)
    other = [str(MMRP / "t.json")] if command[0] in ("match", "plan") else []
    code, lines = _invoke(*command, str(path), *other)
    assert code == 1 and len(lines) == 1 and "not a JSON object" in lines[0], lines


def test_every_reader_refuses_null(tmp_path: Path) -> None:
    from msrr.core import plugins
    from msrr.core.kinematics.tree import load_tree
    from msrr.core.library import load_sources

    path = tmp_path / "n.json"
    path.write_text("null")
    config = plugins.load_configuration(MMRP / "t.json")
    for read in (plugins.load_configuration, plugins.load_plan, plugins.load_library,
                 lambda p: load_sources([p], plugins.resolve),
                 lambda p: load_tree(p, config, modes={})):
        with pytest.raises(ConfigurationError, match="holds null, not a JSON object"):
            read(path)


# -- item 2: output places ---------------------------------------------------------------


@pytest.mark.parametrize("place", ["under-file", "folder", "proc", "empty"])
def test_plan_json_checks_its_place_before_planning(tmp_path: Path, place: str) -> None:
    (tmp_path / "afile").write_text("keep")
    out = {"under-file": tmp_path / "afile" / "p.json", "folder": tmp_path,
           "proc": Path("/proc/x/y.json"), "empty": Path(" ")}[place]
    code, lines = _invoke("plan", str(MMRP / "t.json"), str(MMRP / "series.json"),
                          "--json", str(out))
    assert code == 1 and len(lines) == 1 and "--json" in lines[0], lines
    assert (tmp_path / "afile").read_text() == "keep"


@pytest.mark.parametrize("place", ["under-file", "folder", "proc"])
def test_library_build_checks_its_place_before_building(tmp_path: Path, place: str) -> None:
    (tmp_path / "afile").write_text("keep")
    out = {"under-file": tmp_path / "afile" / "lib.json", "folder": tmp_path,
           "proc": Path("/proc/x/y.json")}[place]
    code, lines = _invoke("library", "build", str(SOURCES), "-o", str(out))
    assert code == 1 and len(lines) == 1 and "--output" in lines[0], lines


# -- item 3: a full disk -----------------------------------------------------------------


def _full_disk(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every atomic write fails as on a full filesystem (after the data was written)."""
    def fsync(fd: int) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(files.os, "fsync", fsync)


def test_a_write_on_a_full_disk_leaves_the_old_file_and_no_temporary(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "a.json"
    path.write_text("old")
    _full_disk(monkeypatch)
    with pytest.raises(OutputError) as caught:
        atomic_write_text(path, "new")
    assert str(caught.value) == (f"{path}: cannot be written: No space left on device; "
                                 "nothing was written under this name")
    assert path.read_text() == "old" and sorted(os.listdir(tmp_path)) == ["a.json"]


def test_plan_json_on_a_full_disk_is_one_line_and_no_file(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    _full_disk(monkeypatch)
    out = tmp_path / "p.json"
    result = CliRunner().invoke(get_cli(), ["plan", str(MMRP / "t.json"),
                                            str(MMRP / "series.json"), "--json", str(out)])
    assert result.exit_code == 1 and result.exception is None or \
        isinstance(result.exception, SystemExit)
    assert result.stderr.strip().splitlines() == [
        f"Error: {out}: cannot be written: No space left on device; nothing was written "
        "under this name"]
    assert os.listdir(tmp_path) == []


def _tiny_run(tmp_path: Path, *args: str, full: pytest.MonkeyPatch | None = None
              ) -> tuple[int, str]:
    (tmp_path / "scenario").mkdir(exist_ok=True)
    with installed(tmp_path / "scenario"):
        if full is not None:
            _full_disk(full)
        result = CliRunner().invoke(get_cli(), ["run", "--robot", "tiny", *args])
    assert result.exception is None or isinstance(result.exception, SystemExit), \
        result.exception
    return result.exit_code, result.stderr


def test_a_run_on_a_full_disk_writes_neither_file_and_says_so(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    out = tmp_path / "run"
    code, errors = _tiny_run(tmp_path, "--out", str(out), "--no-log", full=monkeypatch)
    assert code == 1
    assert errors.strip().splitlines() == [
        f"Error: {out}/plan.json: cannot be written: No space left on device; nothing "
        "was written under this name"]
    assert os.listdir(out) == []


def test_a_recording_that_cannot_be_finished_is_removed_and_named(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from msrr.core.timeline.recorder import TimelineRecorder

    def finish(self: TimelineRecorder, result: object) -> Path:
        self.rec.disconnect()
        raise RuntimeError("Failed to encode LogMsg: No space left on device (os error 28)")

    monkeypatch.setattr(TimelineRecorder, "finish", finish)
    out = tmp_path / "run"
    code, errors = _tiny_run(tmp_path, "--out", str(out))
    lines = errors.strip().splitlines()
    assert code == 1 and len(lines) == 1, lines
    assert lines[0].startswith(f"Error: the recording {out}/run.rrd could not be written (")
    assert lines[0].endswith("; removed run.rrd.part")
    assert sorted(os.listdir(out)) == ["plan.json", "summary.json"]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["success"] is True and summary["recording"] is None
