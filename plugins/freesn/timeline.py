"""FreeSN's views in the rerun timeline: one plot per connector end.

A strut's command carries, per connector end, the target connection vector (and
effort) in the docked node's horizontal frame (:mod:`msrr.plugins.freesn.sim.commands`);
the timeline logs joint ``a.dir_x`` of strut ``S4`` as ``commands/S4/a/dir_x``. Rerun's
view contents take no wildcard inside a path (only a ``/**`` suffix), so each view
names every strut of the run.
"""

from __future__ import annotations

from msrr.core import hookimpl

__all__ = ["msrr_timeline_views"]


@hookimpl
def msrr_timeline_views(run, register) -> None:
    from .robot import SPEC, STRUT  # imported when called: see plugin.py

    if run.robot != SPEC.name:
        return
    import rerun.blueprint as rrb  # only a recorded run pays for the rerun import

    struts = [e.id for e in run.plan.start.edges() if e.kind == STRUT.name]
    for end in (p.name for p in STRUT.ports):
        register(rrb.TimeSeriesView(name=f"Connector {end} targets", origin="commands",
                                    contents=[f"$origin/{s}/{end}/**" for s in struts]))
