"""Hook implementations of the timeline plugin: one recorder per run with a recording path."""

from __future__ import annotations

from typing import Any

from ..hookspecs import hookimpl
from .recorder import TimelineRecorder

__all__ = ["abort", "msrr_on_action", "msrr_on_run_end", "msrr_on_run_start", "msrr_on_tick",
           "msrr_on_topology_change"]

_recorders: dict[int, TimelineRecorder] = {}


def _recorder(run: Any) -> TimelineRecorder | None:
    return _recorders.get(id(run))


@hookimpl
def msrr_on_run_start(run: Any) -> None:
    if getattr(run, "recording", None) is not None:
        _recorders[id(run)] = TimelineRecorder(run)


@hookimpl
def msrr_on_tick(run: Any, tick: Any) -> None:
    if (recorder := _recorder(run)) is not None:
        recorder.tick(tick)


@hookimpl
def msrr_on_action(run: Any, action: Any, status: str) -> None:
    if (recorder := _recorder(run)) is not None:
        recorder.action(action, status)


@hookimpl
def msrr_on_topology_change(run: Any, change: Any) -> None:
    if (recorder := _recorder(run)) is not None:
        recorder.topology_change(change)


@hookimpl
def msrr_on_run_end(run: Any, result: Any) -> None:
    if (recorder := _recorders.pop(id(run), None)) is not None:
        recorder.finish(result)


def abort(run: Any) -> None:
    """Drop the partial recording of ``run`` (a run interrupted before ``run_end``)."""
    if (recorder := _recorders.pop(id(run), None)) is not None:
        recorder.abort()
