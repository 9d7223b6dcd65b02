"""Writes one run to a rerun recording (``.rrd``).

Entity paths (stable, documented in ``docs/running.md``):

* ``world/modules/<id>`` -- the module body with its pose per tick: a box, sphere or
  capsule as its kind's geometry says (:func:`msrr.core.timeline.geometry.body_of`);
  ``world/modules/<id>/faces`` -- its ports, active red, passive blue;
  ``world/modules/<id>/connectors`` -- the two ends of an edge module (a FreeSN strut)
  coloured by state (docked, extending, releasing, free), logged when it changes;
* ``world/targets`` -- goal poses of the running action (wireframe boxes), when its
  planner placed the moving modules;
  ``world/ghost/nodes``, ``world/ghost/boxes``, ``world/ghost/struts`` -- otherwise the
  running action's target configuration at the robot's scale (module sizes from their
  kinds' geometry, :func:`~msrr.core.timeline.geometry.shape_layout`), put where the
  robot is by the best planar rigid fit (:func:`~msrr.core.timeline.geometry.fit_layout`)
  when the action starts, and re-fitted every tick during a behavior (it moves with the
  robot); cleared when the action succeeds; at the end of the run, the run's goal
  fitted onto the final poses;
* ``top/modules``, ``top/connections``, ``top/targets`` -- the top-down 2-D view of a
  planar robot (``spec.defaults.planar``); y is logged negated, as the 2-D view's
  y axis points down;
* ``topology/current``, ``topology/target`` -- graph views: nodes at fixed positions
  (one layout of every configuration of the plan), a label node on each edge (ports,
  or the edge module's id); ``topology/connections`` -- docked connections (scalar);
  ``topology/flows`` -- a purple diamond on that line at each flow's handover;
* ``action`` -- the running action as text; ``plan``, ``mapping`` -- static text;
* ``commands/<id>/<wheel or joint>`` (a ``.`` in a joint name is a ``/``),
  ``errors/<id>`` -- scalars per module, NaN on the first tick a module is idle so the
  plots break there; ``shape/angle`` -- RMS connection angle to the action's target [deg]
  (eq. 8 alignment), for robots with connection vectors;
* ``events/docks``, ``events/undocks``, ``events/flows``, ``events/actions``,
  ``events/faults`` -- text logs (a flow: ``flow F1-F2 -> F1-F3`` when its new
  connection docks; faults: injected by ``--faults`` or caught by the driver guard,
  WARN when the run carries on, ERROR when it stops).

Timelines: ``tick`` (sequence) and ``sim_time`` (duration of driver time). The file
is written as ``<name>.part`` and renamed when the run ends, so no half recording
is ever left under the final name. The blueprint is sent at the first tick, when the
module poses that frame the 3-D camera are known. Module poses, scalars and the top
view are kept per tick and sent as columns when the run ends (``send_columns``: one
call per entity rather than one per tick and module).
"""

from __future__ import annotations

import math
import os
from collections import Counter
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from ..configuration import Configuration
from ..driver import Pose
from ..events import ActionStatus, FaultEvent, Run, RunResult, Tick, TopologyEvent
from ..plan import Action, ActionType, links
from ..robot import DEFAULT_HALF_SIZE, ModuleKind
from ..shape import skeletal_errors
from .blueprint import build_blueprint, camera_eye
from .geometry import (
    Body,
    BodyPose,
    body_of,
    capsule_between,
    fit_layout,
    graph_layout,
    label_node,
    palette,
    shape_layout,
)

__all__ = ["CONNECTOR_COLORS", "FLOW_COLOR", "TimelineRecorder", "event_name"]

ACTIVE = (220, 60, 50)
PASSIVE = (50, 90, 220)
CONNECTOR_COLORS = {"docked": (40, 170, 60), "extending": (250, 160, 0),
                    "releasing": (200, 40, 200), "free": (150, 150, 150)}
"""Colour of an edge module's connector in each state."""
GHOST_ALPHA = 70
FLOW_COLOR = (150, 60, 200)
"""Colour of a flow's mark on the docked-connections plot (viewer and snapshot)."""
_GHOST_PATHS = ("world/ghost/nodes", "world/ghost/boxes", "world/ghost/struts")
_REFIT = 1e-3  # [m, rad]: a behavior's target is logged again once it moved this much
_LABEL_COLOR = (120, 120, 120)
_RECTANGLE = np.array([(1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0), (1.0, 1.0)])
"""Corners of a closed rectangle in units of its half extents; 3 -> 4 is the front."""


def event_name(event: TopologyEvent) -> str:
    """A dock or undock in the event log: its kind and the connection's one name
    (:attr:`msrr.core.plan.ConnectionChange.label`), ``"dock N2-S4b"``."""
    return f"{event.kind} {event.change.label}"


_DEFAULT_KIND = ModuleKind("", "", "vertex")  # a kind the spec does not know: a cube


def _yaw_quaternion(yaw: float) -> rr.Quaternion:
    return rr.Quaternion(xyzw=[0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)])


def _has_vectors(config: Configuration) -> bool:
    return any(e.z is not None for e in config.edges())


class TimelineRecorder:
    """Listens to the events of one run and logs them to ``run.recording``.

    Args:
        run: the run.
        views: viewer views other plugins add (``msrr_timeline_views``).
    """

    def __init__(self, run: Run, views: Sequence[object] = ()):
        if run.recording is None:
            raise ValueError("run has no recording path")
        self.run = run
        self._views = tuple(views)
        self.path = Path(run.recording)
        self.part = self.path.with_name(self.path.name + ".part")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.rec = rr.RecordingStream("msrr", recording_id=f"{run.robot}-{run.scenario}-"
                                      f"{os.getpid()}-{id(run)}")
        self.rec.save(str(self.part))
        self.rec.send_recording_name(f"{run.robot}: {run.scenario}")
        self._topology: Configuration | None = None
        self._links: Counter | None = None  # physical links: docked connections
        self._poses: dict[str, np.ndarray] = {}
        start = run.plan.start
        modules = start.modules()
        self._colors = dict(zip(modules, palette(len(modules)), strict=True))
        kinds = {k.name: k for k in run.spec.module_kinds}
        self._kind_names = kinds
        self._kinds = {m: kinds[k] for m, k in modules.items() if k in kinds}
        self._bodies = {m: body_of(k) for m, k in self._kinds.items()}
        spheres = [body_of(k).radius for k in run.spec.module_kinds
                   if k.role == "vertex" and body_of(k).shape == "sphere"]
        self._inset = max(spheres, default=0.0)  # edge modules drawn from sphere surfaces
        self._fit_tolerance = min((min(b.half_size) for b in self._bodies.values()
                                   if b.shape != "capsule"), default=0.0)  # [m]
        self._oriented = [m for m, b in self._bodies.items() if b.shape == "box"]  # headings
        self._planar = run.spec.defaults.planar
        self._vectors = _has_vectors(start) or _has_vectors(run.plan.goal)
        self._layout = graph_layout([start, run.plan.goal, *(a.target for a in run.plan.actions)])
        self._connectors: dict[str, str] = {}  # last logged states, by edge module
        self._commanded: dict[str, set[str]] = {}
        self._erroring: set[str] = set()
        self._ghost_action: int | None = None  # whose target the ghost shows
        self._ghost_layout: dict[str, BodyPose] = {}
        self._ghost_placed: dict[str, BodyPose] = {}
        self._ghost_logged: set[str] = set()
        self._last: tuple[int, float, Mapping[str, Pose]] | None = None  # last tick
        self._blueprint_sent = False
        self._top_ids: list[str] | None = None
        self._pose_rows: dict[str, list[tuple[int, float, np.ndarray]]] = {}
        self._scalar_rows: dict[str, list[tuple[int, float, float]]] = {}
        self._top_rows: list[tuple[int, float, np.ndarray, np.ndarray]] = []
        self._write_static()

    # -- static -----------------------------------------------------------------------

    def _write_static(self) -> None:
        rec, run = self.rec, self.run
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        for module, body in self._bodies.items():
            kind = self._kinds[module]
            self._log_body(f"world/modules/{module}", body, self._colors[module], module,
                           kind.name)
            ports = [p for p in kind.ports if p.normal is not None]
            if ports and body.shape != "capsule":
                positions = [np.multiply(p.normal, body.half_size) * 1.05 for p in ports]
                colors = [ACTIVE if p.role == "active" else PASSIVE for p in ports]
                rec.log(f"world/modules/{module}/faces",
                        rr.Points3D(positions, colors=colors, labels=[p.name for p in ports],
                                    radii=0.015), static=True)
        plan = run.plan
        lines = [f"# {run.robot}: {run.scenario}", "",
                 f"planner **{plan.planner}**, {len(plan.actions)} actions, "
                 f"{plan.docks} docks, {plan.undocks} undocks", ""]
        lines += [f"{i}. {a}" + (f" -- {a.note}" if a.note else "")
                  + (f" -- retrieved: {a.retrieved}" if a.retrieved else "")
                  for i, a in enumerate(plan.actions, start=1)]  # numbered as printed
        lines += ["", *plan.notes] if plan.notes else []
        rec.log("plan", rr.TextDocument("\n".join(lines), media_type="text/markdown"),
                static=True)
        mapping = plan.mapping or {m: m for m in plan.start.vertices()}
        rows = ["| start id | goal id |", "|---|---|"] + [f"| {a} | {b} |"
                                                        for a, b in mapping.items()]
        rec.log("mapping", rr.TextDocument("\n".join(rows), media_type="text/markdown"),
                static=True)
        self._time(0, 0.0)
        self._log_topology(plan.start)
        self._log_graph("topology/target", plan.goal)
        rec.log("topology/connections", rr.SeriesLines(colors=[(0, 0, 0)], names=["docked"]),
                static=True)
        rec.log("topology/flows", rr.SeriesPoints(colors=[FLOW_COLOR], markers=["diamond"],
                                                  names=["flow"], marker_sizes=[6.0]),
                static=True)

    def _log_body(self, path: str, body: Body, color: tuple[int, ...], label: str,
                  kind: str, static: bool = True) -> None:
        """The body of a module, with its kind's name (``kind``: hover, snapshot legend)."""
        if body.shape == "capsule":
            a, b = body.ends(self._inset)
            archetype = rr.Capsules3D(lengths=[float(b[2] - a[2])], radii=[body.radius],
                                      translations=[a], colors=[color], labels=[label],
                                      fill_mode="solid")
        elif body.shape == "sphere":
            archetype = rr.Ellipsoids3D(half_sizes=[body.half_size], colors=[color],
                                        fill_mode="solid", labels=[label])
        else:
            archetype = rr.Boxes3D(half_sizes=[body.half_size], colors=[color],
                                   fill_mode="solid", labels=[label])
        self.rec.log(path, archetype, rr.AnyValues(kind=kind), static=static)

    def _send_blueprint(self, poses: Mapping[str, Pose]) -> None:
        """The layout, with the views plugins add; an item that is not a rerun view or
        container is left out and named in the event log (a WARN), never fatal."""
        self._blueprint_sent = True
        points = [np.asarray(p.position, dtype=float) for p in poses.values()]
        extra = []
        for view in self._views:
            if isinstance(view, rrb.View | rrb.Container):
                extra.append(view)
            else:
                self.rec.log("events/actions", rr.TextLog(
                    f"msrr_timeline_views: left out a {type(view).__name__} (not a "
                    f"rerun.blueprint view or container)", level="WARN"))
        self.rec.send_blueprint(build_blueprint(
            self.run, eye=camera_eye(points) if points else None, planar=self._planar,
            shape=self._vectors, extra=extra))

    # -- events -----------------------------------------------------------------------

    def _time(self, tick: int, sim_time: float) -> None:
        self.rec.set_time("tick", sequence=tick)
        self.rec.set_time("sim_time", duration=sim_time)

    def _place(self, config: Configuration) -> None:
        """Give a vertex the plan never named (a free strut end the recognizer named) a
        fixed place beside its neighbour, kept for the rest of the run."""
        for e in config.edges():
            for v, w in ((e.source, e.target), (e.target, e.source)):
                if v not in self._layout:
                    x, y = self._layout.get(w, (0.0, 0.0))
                    self._layout[v] = (x + 30.0, y - 30.0)
        for v in config.vertices():
            self._layout.setdefault(v, (0.0, 0.0))

    def _log_graph(self, path: str, config: Configuration) -> None:
        """Nodes at their layout positions, one label node mid-edge (ports or edge id)."""
        self._place(config)
        ids, positions, labels, colors, radii = [], [], [], [], []
        for v in config.vertices():
            ids.append(v)
            positions.append(self._layout[v])
            virtual = config.is_virtual(v)
            labels.append("" if virtual else v)
            colors.append(_LABEL_COLOR if virtual else self._colors.get(v, _LABEL_COLOR))
            radii.append(3.0 if virtual else 9.0)
        edges = []
        for e in config.edges():
            node = label_node(e.id)
            (xa, ya), (xb, yb) = self._layout[e.source], self._layout[e.target]
            ids.append(node)
            positions.append(((xa + xb) / 2, (ya + yb) / 2))
            labels.append("-".join(e.ports) if e.ports else (e.id if e.kind else ""))
            colors.append(self._colors.get(e.id, _LABEL_COLOR))
            radii.append(2.0)
            edges += [(e.source, node), (node, e.target)]
        self.rec.log(path, rr.GraphNodes(node_ids=ids, positions=positions, labels=labels,
                                         colors=colors, radii=radii, show_labels=True),
                     rr.GraphEdges(edges=edges, graph_type="undirected"))

    def _log_topology(self, config: Configuration) -> None:
        """The graph and the docked count, when the physical links change."""
        found = Counter(key for key, _ in links(config))
        if found != self._links:
            self._links = found
            self._topology = config
            self._log_graph("topology/current", config)
            self.rec.log("topology/connections", rr.Scalars(float(found.total())))

    def tick(self, tick: Tick) -> None:
        self._time(tick.index, tick.time)
        # the simulator's own poses (the witness) where it has them, else a pose sensor's
        poses = tick.witness.poses if tick.witness is not None else tick.observation.tracked
        if not self._blueprint_sent:
            self._send_blueprint(poses)
        moved = False
        for module, pose in poses.items():
            state = np.concatenate([pose.position, pose.orientation])
            last = self._poses.get(module)
            if last is not None and float(np.max(np.abs(state - last))) < 1e-4:
                continue  # unchanged: latest-at keeps the previous transform
            moved = True
            self._poses[module] = state
            self._pose_rows.setdefault(module, []).append((tick.index, tick.time, state))
        topology_before = self._topology
        self._log_topology(tick.configuration)
        self._log_connectors(tick)
        if self._planar and (moved or self._topology is not topology_before):
            self._top_rows.append((tick.index, tick.time, *self._top(poses, tick.configuration)))
        self._log_scalars(tick)
        self._last = (tick.index, tick.time, poses)
        if not tick.action.goals:  # with goals, the planner's poses are the target
            fresh = self._ghost_action != tick.action_index
            if fresh or tick.action.behavior is not None:
                self._show_target(tick.action_index, tick.action.target, poses, fresh)
        if self._vectors:
            rms, angles, _ = skeletal_errors(tick.configuration, tick.action.target)
            if len(angles):
                self._scalar("shape/angle", (tick.index, tick.time), math.degrees(rms))

    def _log_scalars(self, tick: Tick) -> None:
        """Commands and errors; a series idle this tick gets one NaN (the viewer's plots,
        like matplotlib's, break a line at a NaN rather than bridge the idle ticks)."""
        at = (tick.index, tick.time)
        for module, command in tick.commands.items():
            names = {name.replace(".", "/"): value
                     for name, value in {**command.wheels, **command.joints}.items()}
            for name, value in names.items():
                self._scalar(f"commands/{module}/{name}", at, float(value))
            for name in self._commanded.get(module, set()) - set(names):
                self._scalar(f"commands/{module}/{name}", at, math.nan)
            self._commanded[module] = set(names)
        for module in [m for m in self._commanded if m not in tick.commands]:
            for name in self._commanded.pop(module):
                self._scalar(f"commands/{module}/{name}", at, math.nan)
        for module, error in tick.errors.items():
            self._scalar(f"errors/{module}", at, float(error))
        for module in self._erroring - set(tick.errors):
            self._scalar(f"errors/{module}", at, math.nan)
        self._erroring = set(tick.errors)

    def _scalar(self, path: str, at: tuple[int, float], value: float) -> None:
        """Buffer one scalar at ``(tick, sim_time)``; sent as a column at the end."""
        self._scalar_rows.setdefault(path, []).append((*at, value))

    def _log_connectors(self, tick: Tick) -> None:
        """Each end of an edge module: docked (per the recognized configuration),
        extending or releasing (per this tick's dock/undock command), else free."""
        config = tick.configuration
        edges = {e.id: e for e in config.edges() if e.kind is not None}
        for module, body in self._bodies.items():
            if body.shape != "capsule":
                continue
            ports = [p.name for p in self._kinds[module].ports] or ["a", "b"]
            edge = edges.get(module)
            command = tick.commands.get(module)
            states = []
            for port, vertex in zip(ports, (edge.source, edge.target) if edge else ("", ""),
                                    strict=False):
                if command is not None and port in command.undock:
                    states.append(("releasing", vertex))
                elif vertex and not config.is_virtual(vertex):
                    states.append(("docked", vertex))
                elif command is not None and port in command.dock:
                    states.append(("extending", ""))
                else:
                    states.append(("free", ""))
            if self._connectors.get(module) == repr(states):
                continue
            self._connectors[module] = repr(states)
            a, b = body.ends(self._inset)
            labels = [f"{p}: {s}" + (f" to {v}" if v else "")
                      for p, (s, v) in zip(ports, states, strict=False)]
            self.rec.log(f"world/modules/{module}/connectors", rr.Points3D(
                [a, b][:len(states)], radii=body.radius * 1.4, labels=labels,
                show_labels=False, colors=[CONNECTOR_COLORS[s] for s, _ in states]))

    def _top(self, poses: Mapping[str, Pose], config: Configuration
             ) -> tuple[np.ndarray, np.ndarray]:
        """Top-down outlines, shape (n, 5, 2), and docked-connection bars, (m, 2, 2), with
        y negated (the 2-D view's y axis points down)."""
        if self._top_ids is None:
            self._top_ids = [m for m in poses if m in self._bodies]
        ids = [m for m in self._top_ids if m in poses]
        xy = np.array([poses[m].position[:2] for m in ids], dtype=float).reshape(-1, 2)
        yaw = np.array([poses[m].yaw for m in ids], dtype=float)
        local = _RECTANGLE[None] * np.array([self._bodies[m].half_size[:2] for m in ids]
                                            ).reshape(-1, 1, 2)
        c, s = np.cos(yaw)[:, None], np.sin(yaw)[:, None]
        x = xy[:, :1] + c * local[..., 0] - s * local[..., 1]
        y = xy[:, 1:] + s * local[..., 0] + c * local[..., 1]
        bars = [[poses[e.source].position[:2], poses[e.target].position[:2]]
                for e in config.edges() if e.source in poses and e.target in poses]
        return (np.stack([x, -y], axis=-1),
                np.array(bars, dtype=float).reshape(-1, 2, 2) * (1.0, -1.0))

    def _send_buffered(self) -> None:
        """Module poses, scalars and the top view, buffered per tick, sent as columns (one
        call per entity instead of one per tick: the recorder's main cost on long runs)."""
        for module, rows in self._pose_rows.items():
            states = np.array([state for _, _, state in rows])
            self.rec.send_columns(
                f"world/modules/{module}", indexes=self._index(rows),
                columns=rr.Transform3D.columns(translation=states[:, :3],
                                               quaternion=states[:, 3:]))
        self._pose_rows = {}
        for path, rows in self._scalar_rows.items():
            self.rec.send_columns(path, indexes=self._index(rows),
                                  columns=rr.Scalars.columns(scalars=[r[2] for r in rows]))
        self._scalar_rows = {}
        rows = self._top_rows
        if rows and self._top_ids is not None:
            colors = [self._colors.get(m, _LABEL_COLOR) for m in self._top_ids]
            self.rec.log("top/modules", rr.LineStrips2D.from_fields(
                colors=colors, labels=self._top_ids, radii=0.006), static=True)
            self.rec.log("top/modules/fronts", rr.LineStrips2D.from_fields(
                colors=colors, radii=0.015), static=True)
            self.rec.log("top/connections", rr.LineStrips2D.from_fields(
                colors=[(0, 0, 0)], radii=0.012), static=True)
            for path, strips in (("top/modules", [r[2] for r in rows]),
                                 ("top/modules/fronts", [r[2][:, 3:5] for r in rows]),
                                 ("top/connections", [r[3] for r in rows])):
                flat = [strip for row in strips for strip in row]
                self.rec.send_columns(path, indexes=self._index(rows), columns=(
                    rr.LineStrips2D.columns(strips=flat).partition([len(s) for s in strips])))
        self._top_rows = []

    @staticmethod
    def _index(rows: list[tuple]) -> list[rr.TimeColumn]:
        return [rr.TimeColumn("tick", sequence=[r[0] for r in rows]),
                rr.TimeColumn("sim_time", duration=[r[1] for r in rows])]

    def _show_target(self, index: int, target: Configuration, poses: Mapping[str, Pose],
                     fresh: bool) -> None:
        """``target`` at the robot's scale, fitted onto ``poses``; laid out again when
        ``fresh`` (a new action), else re-fitted and logged only if it moved."""
        if fresh:
            self._ghost_action = index
            self._ghost_layout = shape_layout(target, self._kind_names)
        placed = fit_layout(target, self._ghost_layout,
                            {m: BodyPose(np.asarray(p.position, dtype=float), p.yaw)
                             for m, p in poses.items()}, tolerance=self._fit_tolerance,
                            oriented=self._oriented)
        if not fresh and placed.keys() == self._ghost_placed.keys() and all(
                float(np.max(np.abs(placed[v].position - was.position))) < _REFIT
                and abs(math.remainder(placed[v].yaw - was.yaw, 2 * math.pi)) < _REFIT
                for v, was in self._ghost_placed.items()):
            return
        self._ghost_placed = placed
        self._log_ghost(target, placed)

    def _log_ghost(self, target: Configuration, placed: Mapping[str, BodyPose]) -> None:
        """``target``'s modules at ``placed``: spheres translucent, boxes as wireframes,
        edge modules as translucent capsules between their ends (hover: the module id)."""
        logged: dict[str, object] = {}
        real = [v for v in target.vertices(virtual=False) if v in placed]
        bodies = {v: self._bodies.get(v) or body_of(self._kind_names.get(
            target.kind_of(v), _DEFAULT_KIND)) for v in real}
        spheres = [v for v in real if bodies[v].shape == "sphere"]
        boxes = [v for v in real if bodies[v].shape != "sphere"]
        if spheres:
            logged["world/ghost/nodes"] = rr.Ellipsoids3D(
                centers=[placed[v].position for v in spheres],
                half_sizes=[bodies[v].half_size for v in spheres],
                colors=[(*self._colors.get(v, _LABEL_COLOR), GHOST_ALPHA) for v in spheres],
                labels=spheres, show_labels=False, fill_mode="solid")
        if boxes:
            logged["world/ghost/boxes"] = rr.Boxes3D(
                centers=[placed[v].position for v in boxes],
                half_sizes=[bodies[v].half_size for v in boxes],
                quaternions=[_yaw_quaternion(placed[v].yaw) for v in boxes],
                colors=[self._colors.get(v, _LABEL_COLOR) for v in boxes],
                labels=boxes, show_labels=False, fill_mode="majorwireframe")
        struts = self._ghost_struts(target, placed)
        if struts is not None:
            logged["world/ghost/struts"] = struts
        for path in _GHOST_PATHS:
            if path in logged:
                self.rec.log(path, logged[path])
            elif path in self._ghost_logged:
                self.rec.log(path, rr.Clear(recursive=False))
        self._ghost_logged = set(logged)

    def _ghost_struts(self, target: Configuration, placed: Mapping[str, BodyPose]
                      ) -> rr.Capsules3D | None:
        translations, quaternions, lengths, radii, colors, labels = [], [], [], [], [], []
        for e in target.edges():
            if e.kind is None or e.source not in placed or e.target not in placed:
                continue
            a, b = placed[e.source].position, placed[e.target].position
            axis = (b - a) / max(float(np.linalg.norm(b - a)), 1e-9)
            body = self._bodies.get(e.id)
            inset_a = 0.0 if target.is_virtual(e.source) else self._inset
            inset_b = 0.0 if target.is_virtual(e.target) else self._inset
            t, q, length = capsule_between(a + inset_a * axis, b - inset_b * axis)
            translations.append(t)
            quaternions.append(rr.Quaternion(xyzw=q))
            lengths.append(length)
            radii.append(body.radius if body else 0.01)
            colors.append((*self._colors.get(e.id, _LABEL_COLOR), GHOST_ALPHA))
            labels.append(e.id)
        if not lengths:
            return None
        return rr.Capsules3D(lengths=lengths, radii=radii, translations=translations,
                             quaternions=quaternions, colors=colors, labels=labels,
                             show_labels=False, fill_mode="solid")

    def action(self, action: Action, status: ActionStatus) -> None:
        rec = self.rec
        index = next((i for i, a in enumerate(self.run.plan.actions) if a is action), -1)
        total = len(self.run.plan.actions)
        text = f"**{index + 1}/{total}: {action.label}** -- {status}"
        if action.note:
            text += f"\n\n{action.note}"
        if action.retrieved:   # the library configuration (and mapping) it comes from
            text += f"\n\nretrieved: {action.retrieved}"
        rec.log("action", rr.TextDocument(text, media_type="text/markdown"))
        level = {ActionStatus.FAILED: "ERROR", ActionStatus.RETRYING: "WARN",
                 ActionStatus.REDOCKING: "WARN"}.get(status, "INFO")
        rec.log("events/actions", rr.TextLog(f"action {index + 1}: {action.label} {status}",
                                             level=level))
        if status == ActionStatus.STARTED:
            self._log_graph("topology/target", action.target)
            self._log_goals(action)
        elif status == ActionStatus.SUCCEEDED:
            rec.log("world/targets", rr.Clear(recursive=True))
            self._clear_ghost()
            if self._planar:
                rec.log("top/targets", rr.Clear(recursive=True))

    def _clear_ghost(self) -> None:
        if self._ghost_logged:
            self.rec.log("world/ghost", rr.Clear(recursive=True))
        self._ghost_action, self._ghost_placed, self._ghost_logged = None, {}, set()

    def _log_goals(self, action: Action) -> None:
        if not action.goals:
            return
        ids = list(action.goals)
        half = [self._bodies[m].half_size if m in self._bodies else (DEFAULT_HALF_SIZE,) * 3
                for m in ids]
        centers = [[action.goals[m][0], action.goals[m][1], h[2]] for m, h in zip(ids, half,
                                                                                 strict=True)]
        quats = [rr.Quaternion(xyzw=[0, 0, np.sin(action.goals[m][2] / 2),
                                     np.cos(action.goals[m][2] / 2)]) for m in ids]
        colors = [self._colors.get(m, (200, 200, 200)) for m in ids]
        self.rec.log("world/targets", rr.Boxes3D(
            centers=centers, half_sizes=half, quaternions=quats, colors=colors,
            fill_mode="majorwireframe", labels=[f"goal {m}" for m in ids]))
        if self._planar:
            strips = []
            for m, h in zip(ids, half, strict=True):
                x, y, yaw = action.goals[m][:3]
                c, s = math.cos(yaw), math.sin(yaw)
                strips.append([(x + c * dx - s * dy, -(y + s * dx + c * dy))
                               for dx, dy in ((h[0], h[1]), (-h[0], h[1]), (-h[0], -h[1]),
                                              (h[0], -h[1]), (h[0], h[1]))])
            self.rec.log("top/targets", rr.LineStrips2D(strips, colors=colors, radii=0.003,
                                                        labels=[f"goal {m}" for m in ids]))

    def topology_change(self, event: TopologyEvent) -> None:
        self._time(event.tick, event.time)
        path = "events/docks" if event.kind == "dock" else "events/undocks"
        level = "INFO" if event.expected else "WARN"
        self.rec.log(path, rr.TextLog(f"{event_name(event)} at t={event.time:.1f} s",
                                      level=level))
        actions = self.run.plan.actions
        action = actions[event.action_index] if 0 <= event.action_index < len(actions) else None
        if (event.kind == "dock" and event.expected and action is not None
                and action.type is ActionType.FLOW):
            self._log_flow(action, event)

    def _log_flow(self, action: Action, event: TopologyEvent) -> None:
        """A flow's handover: its new connection docked (the old one let go in the same
        action). A text line and a mark on the docked-connections plot."""
        broken = ", ".join(c.label for c in action.broken()) or "?"
        self.rec.log("events/flows", rr.TextLog(
            f"flow {broken} -> {event.change.label} at t={event.time:.1f} s"))
        docked = float(self._links.total()) if self._links is not None else math.nan
        self.rec.log("topology/flows", rr.Scalars(docked))

    def fault(self, event: FaultEvent) -> None:
        self.rec.set_time("sim_time", duration=event.time)
        self.rec.log("events/faults", rr.TextLog(str(event),
                                                 level="WARN" if event.recovered else "ERROR"))

    def finish(self, result: RunResult) -> Path:
        """Log the summary, close the file and move it to its final name."""
        if not self._blueprint_sent:
            self._send_blueprint({})
        self._send_buffered()
        if self._last is not None:  # the run's goal, fitted onto the final poses
            index, time, poses = self._last
            self._time(index, time)
            self._clear_ghost()
            self._show_target(-1, self.run.plan.goal, poses, fresh=True)
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
