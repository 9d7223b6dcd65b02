"""Writes one run to a rerun recording (``.rrd``).

Entity paths (stable, documented in ``docs/running.md``):

* ``world/modules/<id>`` -- the module body (box) with its pose per tick;
  ``world/modules/<id>/faces`` -- its ports, active red, passive blue;
  body size and ports come from the module kind in the robot spec
  (:func:`msrr.core.robot.body_half_size`);
* ``world/targets`` -- goal poses of the running action (wireframe boxes);
* ``topology/current``, ``topology/target`` -- graph views (nodes and edges);
* ``action`` -- the running action as text; ``plan``, ``mapping`` -- static text;
* ``commands/<id>/<wheel or joint>``, ``errors/<id>`` -- scalars per module;
* ``events/docks``, ``events/undocks``, ``events/actions``, ``events/faults`` -- text logs
  (faults: injected by ``--faults`` or caught by the driver guard, WARN when the run
  carries on, ERROR when it stops).

Timelines: ``tick`` (sequence) and ``sim_time`` (duration of driver time). The file
is written as ``<name>.part`` and renamed when the run ends, so no half recording
is ever left under the final name.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import rerun as rr

from ..actions import connection_key
from ..configuration import Configuration
from ..events import ActionStatus, FaultEvent, Run, RunResult, Tick, TopologyEvent
from ..plan import Action
from ..robot import DEFAULT_HALF_SIZE, body_half_size
from .blueprint import build_blueprint

__all__ = ["TimelineRecorder"]

ACTIVE = (220, 60, 50)
PASSIVE = (50, 90, 220)
PALETTE = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189),
           (140, 86, 75), (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207)]


def _graph(config: Configuration) -> tuple[rr.GraphNodes, rr.GraphEdges]:
    nodes = config.vertices()
    edges = [(e.source, e.target) for e in config.edges()]
    labels = [f"{v}" for v in nodes]
    return (rr.GraphNodes(node_ids=nodes, labels=labels),
            rr.GraphEdges(edges=edges, graph_type="directed"))


def _topology_key(config: Configuration) -> frozenset:
    return frozenset(connection_key(e.source, e.target, *(e.ports or (None, None)))
                     for e in config.edges())


class TimelineRecorder:
    """Listens to the events of one run and logs them to ``run.recording``."""

    def __init__(self, run: Run):
        if run.recording is None:
            raise ValueError("run has no recording path")
        self.run = run
        self.path = Path(run.recording)
        self.part = self.path.with_name(self.path.name + ".part")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.rec = rr.RecordingStream("msrr", recording_id=f"{run.robot}-{run.scenario}-"
                                      f"{os.getpid()}-{id(run)}")
        self.rec.save(str(self.part))
        self._topology: frozenset | None = None
        self._poses: dict[str, np.ndarray] = {}
        self._colors = {m: PALETTE[i % len(PALETTE)]
                        for i, m in enumerate(run.plan.start.vertices())}
        kinds = {k.name: k for k in run.spec.module_kinds}
        start = run.plan.start
        self._kinds = {m: kinds[start.kind_of(m)] for m in start.vertices()
                       if start.kind_of(m) in kinds}  # virtual vertices have no body
        self._half = {m: body_half_size(k) for m, k in self._kinds.items()}
        self._write_static()

    # -- static -----------------------------------------------------------------------

    def _write_static(self) -> None:
        rec, run = self.rec, self.run
        rec.send_blueprint(build_blueprint())
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        for module, kind in self._kinds.items():
            path = f"world/modules/{module}"
            half = self._half[module]
            rec.log(path, rr.Boxes3D(half_sizes=[half], colors=[self._colors[module]],
                                     fill_mode="solid", labels=[module]), static=True)
            if kind.ports:
                names = [p.name for p in kind.ports]
                positions = [np.multiply(p.normal or (0.0, 0.0, 0.0), half) * 1.05
                             for p in kind.ports]
                colors = [ACTIVE if p.role == "active" else PASSIVE for p in kind.ports]
                rec.log(f"{path}/faces", rr.Points3D(positions, colors=colors, labels=names,
                                                     radii=0.015), static=True)
        plan = run.plan
        lines = [f"# {run.robot}: {run.scenario}", "",
                 f"planner **{plan.planner}**, {len(plan.actions)} actions, "
                 f"{plan.docks} docks, {plan.undocks} undocks", ""]
        lines += [f"{i}. {a}" + (f" -- {a.note}" if a.note else "")
                  for i, a in enumerate(plan.actions)]
        rec.log("plan", rr.TextDocument("\n".join(lines), media_type="text/markdown"),
                static=True)
        mapping = plan.mapping or {m: m for m in plan.start.vertices()}
        rows = ["| start id | goal id |", "|---|---|"] + [f"| {a} | {b} |"
                                                        for a, b in mapping.items()]
        rec.log("mapping", rr.TextDocument("\n".join(rows), media_type="text/markdown"),
                static=True)
        self._time(0, 0.0)
        self._log_topology(plan.start)
        rec.log("topology/target", *_graph(plan.goal))

    # -- events -----------------------------------------------------------------------

    def _time(self, tick: int, sim_time: float) -> None:
        self.rec.set_time("tick", sequence=tick)
        self.rec.set_time("sim_time", duration=sim_time)

    def _log_topology(self, config: Configuration) -> None:
        key = _topology_key(config)
        if key != self._topology:
            self._topology = key
            self.rec.log("topology/current", *_graph(config))

    def tick(self, tick: Tick) -> None:
        rec = self.rec
        self._time(tick.index, tick.time)
        for module, pose in tick.observation.poses.items():
            state = np.concatenate([pose.position, pose.orientation])
            last = self._poses.get(module)
            if last is not None and float(np.max(np.abs(state - last))) < 1e-4:
                continue  # unchanged: latest-at keeps the previous transform
            self._poses[module] = state
            rec.log(f"world/modules/{module}",
                    rr.Transform3D(translation=pose.position,
                                   quaternion=rr.Quaternion(xyzw=pose.orientation)))
        self._log_topology(tick.configuration)
        for module, command in tick.commands.items():
            for name, value in {**command.wheels, **command.joints}.items():
                rec.log(f"commands/{module}/{name}", rr.Scalars(float(value)))
        for module, error in tick.errors.items():
            rec.log(f"errors/{module}", rr.Scalars(float(error)))

    def action(self, action: Action, status: ActionStatus) -> None:
        rec = self.rec
        index = next((i for i, a in enumerate(self.run.plan.actions) if a is action), -1)
        total = len(self.run.plan.actions)
        text = f"**{index + 1}/{total}: {action}** -- {status}"
        if action.note:
            text += f"\n\n{action.note}"
        rec.log("action", rr.TextDocument(text, media_type="text/markdown"))
        level = {ActionStatus.FAILED: "ERROR", ActionStatus.RETRYING: "WARN"}.get(status, "INFO")
        rec.log("events/actions", rr.TextLog(f"action {index}: {action} {status}", level=level))
        if status == ActionStatus.STARTED:
            rec.log("topology/target", *_graph(action.target))
            self._log_goals(action)
        elif status == ActionStatus.SUCCEEDED:
            rec.log("world/targets", rr.Clear(recursive=True))

    def _log_goals(self, action: Action) -> None:
        if not action.goals:
            return
        ids = list(action.goals)
        half = [self._half.get(m, (DEFAULT_HALF_SIZE,) * 3) for m in ids]
        centers = [[action.goals[m][0], action.goals[m][1], h[2]] for m, h in zip(ids, half,
                                                                                 strict=True)]
        quats = [rr.Quaternion(xyzw=[0, 0, np.sin(action.goals[m][2] / 2),
                                     np.cos(action.goals[m][2] / 2)]) for m in ids]
        self.rec.log("world/targets", rr.Boxes3D(
            centers=centers, half_sizes=half,
            quaternions=quats, colors=[self._colors.get(m, (200, 200, 200)) for m in ids],
            fill_mode="majorwireframe", labels=[f"goal {m}" for m in ids]))

    def topology_change(self, event: TopologyEvent) -> None:
        self._time(event.tick, event.time)
        path = "events/docks" if event.kind == "dock" else "events/undocks"
        level = "INFO" if event.expected else "WARN"
        self.rec.log(path, rr.TextLog(f"{event} at t={event.time:.1f} s", level=level))

    def fault(self, event: FaultEvent) -> None:
        self.rec.set_time("sim_time", duration=event.time)
        self.rec.log("events/faults", rr.TextLog(str(event),
                                                 level="WARN" if event.recovered else "ERROR"))

    def finish(self, result: RunResult) -> Path:
        """Log the summary, close the file and move it to its final name."""
        status = "succeeded" if result.success else f"FAILED: {result.reason}"
        self.rec.log("action", rr.TextDocument(
            f"**run {status}**\n\n{result.actions_done}/{result.actions_total} actions, "
            f"{result.docks} docks, {result.undocks} undocks, "
            f"{result.sim_time:.1f} s simulated", media_type="text/markdown"))
        self.rec.flush()
        self.rec.disconnect()
        os.replace(self.part, self.path)
        return self.path

    def abort(self) -> None:
        """Drop the partial file (the run never ended properly)."""
        self.rec.disconnect()
        self.part.unlink(missing_ok=True)
