"""The journal of a batch command: every finished result on disk as it arrives.

``platform library check`` and ``platform sweep`` write their output (the check file,
``sweep.csv``) once, atomically, at the end. Until then each finished task is appended
to ``<output>.journal`` beside it (:func:`journal_path`): JSON lines, the first naming
what the batch is (its *identity*: library digest, seed, options, the task keys...),
then one line per finished task (``{"key": ..., "result": ...}``) or failed one
(``{"key": ..., "error": ...}``, kept for the record and run again on resume). A crash,
SIGKILL or Ctrl-C loses no finished task; ``--resume`` reads the journal back, runs only
the tasks without a result and writes the output from the journal's results and the new
ones. Once the output is written the journal is removed.

Lines are flushed as they are written (a crash of the process loses nothing) and synced
to the disk at most once a second (a crash of the machine loses at most the last
second). A line cut off by a crash in the middle of its write is dropped on resume. One
command at a time may write a journal (an exclusive lock where the system has ``fcntl``).
"""

from __future__ import annotations

import contextlib
import json
import os
import time
from collections.abc import Mapping
from pathlib import Path
from typing import IO, Any

from ..errors import ConfigurationError, OutputError

try:
    import fcntl
except ImportError:  # Windows: no advisory lock
    fcntl = None  # type: ignore[assignment]

__all__ = ["Journal", "journal_path"]

_FORMAT = "msrr-journal"
_SYNC_EVERY = 1.0


def journal_path(output: str | os.PathLike[str]) -> Path:
    """The journal beside an output file: ``S6N3.check.json`` -> ``S6N3.check.json.journal``."""
    path = Path(output)
    return path.with_name(f"{path.name}.journal")


def _normal(value: Any) -> Any:
    """``value`` as it reads back from JSON (tuples become lists)."""
    return json.loads(json.dumps(value))


class Journal:
    """An open journal (see the module's description).

    Attributes:
        path: the journal file.
        kind: what the batch is (``"library check"``, ``"sweep"``), for messages.
        results: the finished tasks' results by key (as JSON values), those read back on
            resume and those added since.
        resumed: how many results were read back.
    """

    def __init__(self, path: Path, kind: str, results: dict[str, Any], file: IO[bytes]):
        self.path, self.kind, self.results = path, kind, results
        self.resumed = len(results)
        self._file: IO[bytes] | None = file
        self._synced = time.monotonic()

    @classmethod
    def open(cls, path: str | os.PathLike[str], identity: Mapping[str, Any], *, kind: str,
             resume: bool, option: str = "--resume") -> Journal:
        """Start a journal at ``path``, or continue the one there with ``resume``.

        Args:
            path: the journal file (:func:`journal_path` of the output).
            identity: what makes two runs the same batch (JSON values); a journal of
                another identity is not continued.
            kind: what the batch is, for messages.
            resume: continue the journal at ``path`` if there is one.
            option: the command's resume option, for messages.

        Raises:
            ConfigurationError: a journal is there and ``resume`` is false; the journal
                there is of another batch, damaged, or in use by another command.
        """
        path = Path(path)
        identity = _normal(dict(identity))
        if path.exists() and not resume:
            raise ConfigurationError(
                f"holds an unfinished {kind} ({_count(path)}); continue it with {option}, "
                "or delete the journal to start over", source=str(path))
        results: dict[str, Any] = {}
        if path.exists():
            results = _read(path, identity, kind)
            file = path.open("ab")
        else:
            path.parent.mkdir(parents=True, exist_ok=True)
            file = path.open("xb")
            header = {"format": _FORMAT, "version": 1, "kind": kind, "identity": identity}
            file.write(_line(header))
        _lock(file, path, kind)
        journal = cls(path, kind, results, file)
        journal._sync(force=True)
        return journal

    def add(self, key: str, result: Any) -> None:
        """Record a finished task's ``result`` (a JSON value; ``NaN`` allowed)."""
        self.results[key] = result
        self._write({"key": key, "result": result})

    def error(self, key: str, error: str) -> None:
        """Record that a task failed (for the record; it runs again on resume)."""
        self._write({"key": key, "error": error})

    def close(self) -> None:
        """Sync and close; the journal stays for ``--resume``."""
        if self._file is not None:
            with contextlib.suppress(OSError):  # a full disk: what is there stays
                self._sync(force=True)
            with contextlib.suppress(OSError):
                self._file.close()
            self._file = None

    def finish(self) -> None:
        """The output is written: close and remove the journal."""
        self.close()
        self.path.unlink(missing_ok=True)

    def _write(self, record: dict[str, Any]) -> None:
        if self._file is None:
            raise ValueError(f"journal {self.path} is closed")
        try:
            self._file.write(_line(record))
            self._sync()
        except OSError as exc:  # a full disk: the batch stops, the journal so far is kept
            raise OutputError(f"cannot write the journal: {exc.strerror or exc}",
                              source=str(self.path)) from None

    def _sync(self, *, force: bool = False) -> None:
        assert self._file is not None
        self._file.flush()
        now = time.monotonic()
        if force or now - self._synced >= _SYNC_EVERY:
            os.fsync(self._file.fileno())
            self._synced = now


def _line(record: dict[str, Any]) -> bytes:
    return (json.dumps(record, separators=(",", ":"), allow_nan=True) + "\n").encode()


def _lock(file: IO[bytes], path: Path, kind: str) -> None:
    if fcntl is None:
        return
    try:
        fcntl.flock(file.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        file.close()
        raise ConfigurationError(f"is in use by another {kind} (a journal is written by one "
                                 "command at a time)", source=str(path)) from None


def _count(path: Path) -> str:
    """``"5 finished"``: how many results a journal holds, for messages."""
    try:
        lines = path.read_bytes().splitlines()[1:]
    except OSError:
        return "unreadable"
    marker = b'"result"'
    return f"{sum(marker in line for line in lines)} finished"


def _read(path: Path, identity: dict[str, Any], kind: str) -> dict[str, Any]:
    """The results of the journal at ``path``, after checking it is of ``identity``; a
    last line cut off by a crash is dropped (and cut from the file)."""
    data = path.read_bytes()
    lines = data.split(b"\n")
    complete = lines[:-1]  # the part after the last newline is empty or was cut off
    if lines[-1]:
        with path.open("r+b") as file:
            file.truncate(len(data) - len(lines[-1]))
    try:
        header = json.loads(complete[0]) if complete else None
    except ValueError:
        header = None
    if not isinstance(header, dict) or header.get("format") != _FORMAT:
        raise ConfigurationError(f"is not a journal of a {kind}", source=str(path))
    theirs = header.get("identity", {})
    if theirs != identity:
        fields = sorted(k for k in {*theirs, *identity} if theirs.get(k) != identity.get(k))
        raise ConfigurationError(
            f"is the journal of another {kind} (its {', '.join(fields)} differ from this "
            "command's); run the same command again, or delete the journal to start over",
            source=str(path))
    results: dict[str, Any] = {}
    for number, line in enumerate(complete[1:], start=2):
        try:
            record = json.loads(line)
            key = record["key"]
        except (ValueError, KeyError, TypeError):
            raise ConfigurationError(f"line {number} is damaged; delete the journal to "
                                     "start over", source=str(path)) from None
        if "result" in record:
            results[key] = record["result"]
    return results
