"""Read a recording back with rerun's own chunk reader: the one reader of ``.rrd`` files.

:func:`read_recording` streams the chunks once and returns every logged row with its
entity path, plus the timelines that index them; :func:`read_rows` and
:func:`summarize_recording` are views of that one read (the rows of some entities;
row counts per entity). Used by ``platform snapshot``, tests and docs.

The rerun SDK is imported inside :func:`read_recording`: importing it costs about
0.3 s and this module is imported with the timeline plugin by every ``platform``
command (see :mod:`msrr.core.timeline`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import MsrrError

__all__ = ["Recording", "RecordingSummary", "Row", "read_recording", "read_rows",
           "summarize_recording"]

_ROW_ID = "rerun.controls.RowId"  # time-ordered id, orders rows logged at one tick
_SKIP = {_ROW_ID, "log_time"}  # log_time: wall clock, not needed


@dataclass(frozen=True)
class Row:
    """One logged row of an entity: its ``tick`` and ``sim_time`` [s] (``None`` when
    static), its non-null components by column name (``"Scalars:scalars"``...) and
    :attr:`order`, which sorts rows of different entities as they were logged (rerun's
    time-ordered row id: a ``Clear`` of a parent and a later row of its child at one
    tick come out in the order the viewer applies them)."""

    tick: int | None
    sim_time: float | None
    values: dict[str, Any]
    row_id: bytes = b""

    @property
    def order(self) -> tuple[int, bytes]:
        """``(tick, row id)``, static rows first: the order the viewer applies rows in."""
        return (-1 if self.tick is None else self.tick, self.row_id)


@dataclass(frozen=True)
class Recording:
    """Everything logged in one ``.rrd`` file.

    Attributes:
        rows: per entity path, its rows: static rows first, then in logging order
            (by tick, then by rerun's row id).
        timelines: names of the timelines that index any row (``"tick"``, ...).
    """

    rows: dict[str, list[Row]]
    timelines: frozenset[str]


@dataclass(frozen=True)
class RecordingSummary:
    """Entity paths with their row counts, and timeline names, of one ``.rrd`` file."""

    rows: dict[str, int]
    timelines: frozenset[str]

    def entities(self, prefix: str = "/") -> list[str]:
        """Entity paths starting with ``prefix``, sorted."""
        return sorted(p for p in self.rows if p.startswith(prefix))


def read_recording(path: str | Path, prefix: str = "/") -> Recording:
    """The rows of every entity whose path starts with ``prefix``, and the timelines.

    Raises:
        MsrrError: the file is missing or rerun cannot read it.
    """
    from rerun.chunk import RrdReader  # measured start-up cost: see the module docstring

    if not Path(path).is_file():
        raise MsrrError(f"{path}: no such recording")
    try:
        chunks = list(RrdReader(path).stream())
    except (RuntimeError, ValueError, OSError) as exc:
        raise MsrrError(f"{path}: rerun cannot read it: {exc}") from None
    out: dict[str, list[Row]] = {}
    timelines: set[str] = set()
    for chunk in chunks:
        entity = chunk.entity_path
        if not entity.startswith(prefix):
            continue
        timelines.update(name for name in chunk.timeline_names if name not in _SKIP)
        batch = chunk.to_record_batch()
        names = [n for n in batch.schema.names if n not in _SKIP]
        columns = {n: batch.column(n).to_pylist() for n in names}
        ids = (batch.column(_ROW_ID).to_pylist() if _ROW_ID in batch.schema.names
               else [b""] * batch.num_rows)
        for i in range(batch.num_rows):
            values = {n: col[i] for n, col in columns.items() if col[i] is not None}
            tick = values.pop("tick", None)
            sim = values.pop("sim_time", None)
            row = Row(tick, sim.total_seconds() if sim is not None else None, values,
                      ids[i] or b"")
            out.setdefault(entity, []).append(row)
    rows = {entity: sorted(found, key=lambda r: r.order) for entity, found in out.items()}
    return Recording(rows, frozenset(timelines))


def read_rows(path: str | Path, prefix: str = "/") -> dict[str, list[Row]]:
    """The rows of :func:`read_recording`, by entity path.

    Raises:
        MsrrError: the file is missing or rerun cannot read it.
    """
    return read_recording(path, prefix).rows


def summarize_recording(path: str | Path) -> RecordingSummary:
    """Entity paths with their row counts and the timelines of the recording at ``path``.

    Raises:
        MsrrError: the file is missing or rerun cannot read it.
    """
    recording = read_recording(path)
    return RecordingSummary({entity: len(rows) for entity, rows in recording.rows.items()},
                            recording.timelines)
