"""Read a recording back with rerun's own tooling.

Used by tests and docs to check what a run wrote: which entity paths exist, how
many rows each has, and which timelines index them (``rerun rrd print``), and the
logged values themselves (:func:`read_rows`, rerun's chunk reader).
"""

from __future__ import annotations

import re
import subprocess
import sys
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import MsrrError

__all__ = ["RecordingSummary", "Row", "read_rows", "summarize_recording"]

_CHUNK = re.compile(r"^Chunk\(\S+\) with (\d+) rows \([^)]*\) - (\S+)")
_INDEX = re.compile(r"index_name: (\w+)")
_ROW_ID = "rerun.controls.RowId"  # time-ordered id, orders rows logged at one tick
_SKIP = {_ROW_ID, "log_time"}  # log_time: wall clock, not needed


@dataclass(frozen=True)
class RecordingSummary:
    """Entity paths with their row counts, and timeline names, of one ``.rrd`` file."""

    rows: dict[str, int]
    timelines: frozenset[str]

    def entities(self, prefix: str = "/") -> list[str]:
        """Entity paths starting with ``prefix``, sorted."""
        return sorted(p for p in self.rows if p.startswith(prefix))


def summarize_recording(path: str | Path) -> RecordingSummary:
    """Summarize ``path`` by parsing ``rerun rrd print -vv``.

    Raises:
        MsrrError: the file is missing or rerun cannot read it.
    """
    if not Path(path).is_file():
        raise MsrrError(f"{path}: no such recording")
    proc = subprocess.run([sys.executable, "-m", "rerun", "rrd", "print", "-vv", str(path)],
                          capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise MsrrError(f"{path}: rerun cannot read it: {proc.stderr.strip().splitlines()[-1:]}")
    rows: Counter[str] = Counter()
    timelines: set[str] = set()
    for line in proc.stdout.splitlines():
        match = _CHUNK.match(line)
        if match:
            rows[match.group(2)] += int(match.group(1))
        timelines.update(_INDEX.findall(line))
    return RecordingSummary(dict(rows), frozenset(timelines))


@dataclass(frozen=True)
class Row:
    """One logged row of an entity: its ``tick`` and ``sim_time`` [s] (``None`` when
    static) and its non-null components by column name (``"Scalars:scalars"``...)."""

    tick: int | None
    sim_time: float | None
    values: dict[str, Any]


def read_rows(path: str | Path, prefix: str = "/") -> dict[str, list[Row]]:
    """The rows of every entity whose path starts with ``prefix``, static rows first,
    then in logging order (by tick, then by rerun's row id).

    Raises:
        MsrrError: the file is missing or rerun cannot read it.
    """
    from rerun.chunk import RrdReader  # the SDK is a runtime dependency; keep import cheap

    if not Path(path).is_file():
        raise MsrrError(f"{path}: no such recording")
    try:
        chunks = list(RrdReader(path).stream())
    except (RuntimeError, ValueError, OSError) as exc:
        raise MsrrError(f"{path}: rerun cannot read it: {exc}") from None
    out: dict[str, list[tuple[int, bytes, Row]]] = {}
    for chunk in chunks:
        entity = chunk.entity_path
        if not entity.startswith(prefix):
            continue
        batch = chunk.to_record_batch()
        names = [n for n in batch.schema.names if n not in _SKIP]
        columns = {n: batch.column(n).to_pylist() for n in names}
        ids = (batch.column(_ROW_ID).to_pylist() if _ROW_ID in batch.schema.names
               else [b""] * batch.num_rows)
        for i in range(batch.num_rows):
            values = {n: col[i] for n, col in columns.items() if col[i] is not None}
            tick = values.pop("tick", None)
            sim = values.pop("sim_time", None)
            row = Row(tick, sim.total_seconds() if sim is not None else None, values)
            out.setdefault(entity, []).append((-1 if tick is None else tick, ids[i], row))
    return {entity: [r for _, _, r in sorted(rows, key=lambda t: t[:2])]
            for entity, rows in out.items()}
