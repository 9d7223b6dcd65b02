"""core/app/journal.py: results on disk as they arrive, read back on resume."""

from __future__ import annotations

import json
import math

import pytest

from msrr.core.app.journal import Journal, journal_path
from msrr.core.errors import ConfigurationError

IDENTITY = {"library": "S6N3", "seed": 0, "edges": ["a", "b", "c"]}


def test_journal_beside_the_output(tmp_path):
    assert journal_path(tmp_path / "S6N3.check.json") == tmp_path / "S6N3.check.json.journal"


def test_results_are_on_disk_at_once_and_read_back_on_resume(tmp_path):
    path = tmp_path / "out.journal"
    journal = Journal.open(path, IDENTITY, kind="check", resume=False)
    journal.add("a", {"x": 1.25, "nan": math.nan})
    journal.error("b", "WorkerLost: the worker was killed by SIGKILL (3 attempts)")
    # flushed already: a crash here (the file never closed) loses nothing
    lines = path.read_text().splitlines()
    assert json.loads(lines[0])["identity"] == IDENTITY and len(lines) == 3
    journal.close()
    again = Journal.open(path, IDENTITY, kind="check", resume=True)
    assert again.resumed == 1 and set(again.results) == {"a"}  # the failed one runs again
    assert again.results["a"]["x"] == 1.25 and math.isnan(again.results["a"]["nan"])
    again.add("b", 2)
    again.close()
    last = Journal.open(path, IDENTITY, kind="check", resume=True)
    assert last.results == {"a": last.results["a"], "b": 2}
    last.finish()
    assert not path.exists()


def test_an_unfinished_journal_is_never_overwritten_without_resume(tmp_path):
    path = tmp_path / "out.journal"
    journal = Journal.open(path, IDENTITY, kind="library check", resume=False)
    journal.add("a", 1)
    journal.close()
    with pytest.raises(ConfigurationError, match=r"holds an unfinished library check \(1 "
                                                 r"finished\); continue it with --resume"):
        Journal.open(path, IDENTITY, kind="library check", resume=False)
    assert Journal.open(path, IDENTITY, kind="check", resume=True).results == {"a": 1}


def test_resume_refuses_the_journal_of_another_batch(tmp_path):
    path = tmp_path / "out.journal"
    Journal.open(path, IDENTITY, kind="check", resume=False).close()
    with pytest.raises(ConfigurationError, match=r"another check \(its seed differ"):
        Journal.open(path, {**IDENTITY, "seed": 1}, kind="check", resume=True)


def test_a_line_cut_off_by_a_crash_is_dropped(tmp_path):
    path = tmp_path / "out.journal"
    journal = Journal.open(path, IDENTITY, kind="check", resume=False)
    journal.add("a", 1)
    journal.close()
    with path.open("ab") as file:
        file.write(b'{"key":"b","resu')  # the crash came in the middle of a write
    again = Journal.open(path, IDENTITY, kind="check", resume=True)
    assert again.results == {"a": 1}
    again.add("b", 2)
    again.close()
    assert Journal.open(path, IDENTITY, kind="check", resume=True).results == {"a": 1, "b": 2}


def test_a_damaged_journal_is_refused_in_one_line(tmp_path):
    path = tmp_path / "out.journal"
    Journal.open(path, IDENTITY, kind="check", resume=False).close()
    with path.open("ab") as file:
        file.write(b"not json\n" + b'{"key":"a","result":1}\n')
    with pytest.raises(ConfigurationError, match="line 2 is damaged"):
        Journal.open(path, IDENTITY, kind="check", resume=True)
    (tmp_path / "other").write_text("hello\n")
    with pytest.raises(ConfigurationError, match="is not a journal of a check"):
        Journal.open(tmp_path / "other", IDENTITY, kind="check", resume=True)


def test_one_command_at_a_time_writes_a_journal(tmp_path):
    path = tmp_path / "out.journal"
    journal = Journal.open(path, IDENTITY, kind="sweep", resume=False)
    try:
        with pytest.raises(ConfigurationError, match="is in use by another sweep"):
            Journal.open(path, IDENTITY, kind="sweep", resume=True)
    finally:
        journal.close()
