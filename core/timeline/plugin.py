"""Hook implementations of the timeline plugin: one recorder per run with a recording path.

Registered through the entry-point group like any plugin; the views other plugins add
(``msrr_timeline_views``) are collected here, when a recorded run starts, and handed to
the recorder.

The recorder module (and with it the rerun SDK, about 0.3 s to import) is imported
when a run with a recording starts, not when the plugin loads: every ``platform``
command loads the plugins, and ``platform --help`` should not pay for rerun.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..hookspecs import hookimpl

if TYPE_CHECKING:  # annotations only: the plugin loads on every --help
    from ..events import ActionStatus, FaultEvent, Run, RunResult, Tick, TopologyEvent
    from ..plan import Action
    from .recorder import TimelineRecorder

__all__ = ["abort", "msrr_on_action", "msrr_on_fault", "msrr_on_run_end", "msrr_on_run_start",
           "msrr_on_tick", "msrr_on_topology_change"]

_recorders: dict[int, TimelineRecorder] = {}


def _recorder(run: Run) -> TimelineRecorder | None:
    return _recorders.get(id(run))


@hookimpl
def msrr_on_run_start(run: Run) -> None:
    if run.recording is not None:
        from .. import plugins
        from .recorder import TimelineRecorder  # rerun: measured start-up cost, see above

        _recorders[id(run)] = TimelineRecorder(run, views=plugins.timeline_views(run))


@hookimpl
def msrr_on_tick(run: Run, tick: Tick) -> None:
    if (recorder := _recorder(run)) is not None:
        recorder.tick(tick)


@hookimpl
def msrr_on_action(run: Run, action: Action, status: ActionStatus) -> None:
    if (recorder := _recorder(run)) is not None:
        recorder.action(action, status)


@hookimpl
def msrr_on_topology_change(run: Run, change: TopologyEvent) -> None:
    if (recorder := _recorder(run)) is not None:
        recorder.topology_change(change)


@hookimpl
def msrr_on_fault(run: Run, fault: FaultEvent) -> None:
    if (recorder := _recorder(run)) is not None:
        recorder.fault(fault)


@hookimpl
def msrr_on_run_end(run: Run, result: RunResult) -> None:
    if (recorder := _recorders.pop(id(run), None)) is not None:
        recorder.finish(result)


def abort(run: Run) -> None:
    """Drop the partial recording of ``run`` (a run interrupted before ``run_end``)."""
    if (recorder := _recorders.pop(id(run), None)) is not None:
        recorder.abort()
