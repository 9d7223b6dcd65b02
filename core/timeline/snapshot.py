"""Draw a still image of a run from its recording (no display needed).

:func:`load_track` reads the module bodies (with their kinds) and poses, the recognized
topology, the connector states of edge modules, the action text, the dock, undock and
flow events, the running action's target (goal poses, or its shape laid out on the
robot), the docked connections and the per-module errors back from a ``run.rrd``
(:func:`msrr.core.timeline.readback.read_rows`); :func:`render_snapshot` draws them
with matplotlib (Agg): top-down footprints at the start, two intermediate ticks and
the end -- or at one chosen :class:`Moment` (:func:`pick_moment`: a simulated time, or
the end of an action) -- (boxes as rectangles, spheres as circles, capsules as thick
bars with their connectors), plus connections (flows marked) and errors over time,
under a title naming the robot and the scenario and a legend of what this recording
draws (:func:`legend_entries`).

Labels that would cover one another are moved along or beside their strut with a leader
line, or left out when no place is free (:func:`_declutter`).

matplotlib is imported inside the drawing functions: it is an optional dependency
(the ``plot`` extra), and a missing one is reported as one line by
:func:`write_snapshot`.
"""

from __future__ import annotations

import io
import math
import re
import textwrap
from bisect import bisect_right
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import MsrrError
from ..files import atomic_write_bytes
from .readback import Row, read_rows

__all__ = ["Moment", "Track", "legend_entries", "load_track", "pick_moment", "render_snapshot",
           "write_snapshot"]

_MODULE = re.compile(r"^/world/modules/([^/]+)$")
_ACTION = re.compile(r"^action (\d+): .* (succeeded|failed)$")
_NUMBERED = re.compile(r"^\**(\d+)/(\d+):")
_LABEL = "edge:"  # graph label nodes (msrr.core.timeline.geometry.label_node)
_END = b"\xff" * 16  # after every row id: "at the end of a tick"
_FLOW = (150 / 255, 60 / 255, 200 / 255)  # msrr.core.timeline.recorder.FLOW_COLOR
_GHOST = ("nodes", "boxes", "struts")


def _rgb(packed: int) -> tuple[float, float, float]:
    return ((packed >> 24) & 255) / 255, ((packed >> 16) & 255) / 255, ((packed >> 8) & 255) / 255


def _yaw(q: list[float]) -> float:
    x, y, z, w = q
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def _rotate(q: list[float], v: tuple[float, float, float]) -> tuple[float, float, float]:
    """``v`` rotated by the unit quaternion ``q`` (x, y, z, w)."""
    x, y, z, w = q
    vx, vy, vz = v
    tx, ty, tz = 2 * (y * vz - z * vy), 2 * (z * vx - x * vz), 2 * (x * vy - y * vx)
    return (vx + w * tx + y * tz - z * ty, vy + w * ty + z * tx - x * tz,
            vz + w * tz + x * ty - y * tx)


def _latest(rows: list[Row], at: int | tuple[int, bytes]) -> Row | None:
    """The last of ``rows`` (in logging order, :attr:`Row.order`) logged at or before
    ``at``: a tick (its end), or ``(tick, row id)``."""
    key = (at, _END) if isinstance(at, int) else at
    timed = [r for r in rows if r.tick is not None]
    i = bisect_right([r.order for r in timed], key)
    return timed[i - 1] if i else None


@dataclass(frozen=True)
class Moment:
    """One moment of a recording a panel draws.

    Attributes:
        tick: the module poses of the end of this tick.
        at: ``(tick, row id)``: targets, action text and connectors as logged up to this
            row (the end of an action: its target before it was cleared).
        label: how the panel names it (``"end of action 5"``), or ``""``.
    """

    tick: int
    at: tuple[int, bytes]
    label: str = ""

    @classmethod
    def of_tick(cls, tick: int, label: str = "") -> Moment:
        return cls(tick, (tick, _END), label)


@dataclass
class Track:
    """What a snapshot needs from one recording.

    ``shapes``: per module ``"box"``, ``"sphere"`` or ``"capsule"``; ``kinds``: its
    kind's name; ``half``: a box's half extents or a sphere's radius twice [m];
    ``capsules``: a capsule's ``(z of its first end, z of its second end, radius)`` in its
    body frame [m]; ``connectors``: the connector rows of edge modules; ``connections``:
    docked-connection count rows; ``ghost``: rows of the running action's target shape
    (``nodes``, ``boxes``, ``struts``, with the clears of ``world/ghost``); ``flows``:
    ``(tick, time, text)`` of each flow's handover; ``actions``: the ``events/actions``
    rows; ``title``: robot and scenario, as the recording names itself; ``angle``: RMS
    strut angle to the running action's target [deg] (robots with connection vectors);
    ``times``: each tick's simulated time [s]; ``start_time``: where the recording starts
    (its initial state, before the first tick) [s].
    """

    modules: list[str]
    half: dict[str, tuple[float, float]]
    colors: dict[str, tuple[float, float, float]]
    faces: dict[str, list[tuple[float, float, tuple[float, float, float]]]]
    poses: dict[str, list[Row]]
    topology: list[Row]
    action: list[Row]
    targets: list[Row]
    errors: dict[str, list[Row]]
    events: list[tuple[int, float, str]]
    times: dict[int, float] = field(default_factory=dict)
    shapes: dict[str, str] = field(default_factory=dict)
    capsules: dict[str, tuple[float, float, float]] = field(default_factory=dict)
    connectors: dict[str, list[Row]] = field(default_factory=dict)
    connections: list[Row] = field(default_factory=list)
    ghost: dict[str, list[Row]] = field(default_factory=dict)
    title: str = ""
    angle: list[Row] = field(default_factory=list)
    kinds: dict[str, str] = field(default_factory=dict)
    flows: list[tuple[int, float, str]] = field(default_factory=list)
    actions: list[Row] = field(default_factory=list)
    start_time: float = 0.0

    @property
    def last_tick(self) -> int:
        return max(self.times) if self.times else 0

    @property
    def first_tick(self) -> int:
        return min(self.times) if self.times else 0

    def sim_time(self, tick: int) -> float:
        ticks = sorted(t for t in self.times if t <= tick)
        return self.times[ticks[-1]] if ticks else 0.0

    def _pose_row(self, module: str, tick: int) -> Row | None:
        rows = self.poses.get(module, [])
        return _latest(rows, tick) or next((r for r in rows if r.tick is not None), None)

    def pose(self, module: str, tick: int) -> tuple[float, float, float] | None:
        """``(x [m], y [m], yaw [rad])`` of ``module`` at ``tick``."""
        row = self._pose_row(module, tick)
        if row is None:
            return None
        x, y, _ = row.values["Transform3D:translation"][0]
        return x, y, _yaw(row.values["Transform3D:quaternion"][0])

    def capsule_ends(self, module: str, tick: int
                     ) -> tuple[tuple[float, float], tuple[float, float]] | None:
        """Top-down ``(x, y)`` [m] of a capsule module's first and second end at ``tick``."""
        row = self._pose_row(module, tick)
        if row is None or module not in self.capsules:
            return None
        p = row.values["Transform3D:translation"][0]
        q = row.values["Transform3D:quaternion"][0]
        za, zb, _ = self.capsules[module]
        ends = []
        for z in (za, zb):
            d = _rotate(q, (0.0, 0.0, z))
            ends.append((p[0] + d[0], p[1] + d[1]))
        return ends[0], ends[1]

    def edges_with_ids(self, tick: int) -> list[tuple[str, str, str | None]]:
        """``(source, target, edge id or None)`` of the recognized topology at ``tick``;
        the graph's label nodes (one mid-edge, named by the edge) are folded back."""
        row = _latest(self.topology, tick)
        return [] if row is None else _graph_edges(row)

    def edges(self, tick: int) -> list[tuple[str, str]]:
        """``(source, target)`` of every connection of the recognized topology at ``tick``."""
        return [(a, b) for a, b, _ in self.edges_with_ids(tick)]

    def connector_states(self, module: str, tick: int) -> list[tuple[str, tuple[float, ...]]]:
        """``(label, colour)`` of each connector of edge module ``module`` at ``tick``."""
        row = _latest(self.connectors.get(module, []), tick)
        if row is None:
            return []
        return [(label, _rgb(c)) for label, c in zip(row.values.get("Points3D:labels", []),
                                                    row.values.get("Points3D:colors", []),
                                                    strict=False)]

    def docked(self, tick: int) -> int:
        """Docked connections at ``tick`` (each docked end of an edge module counts)."""
        row = _latest([r for r in self.connections if "Scalars:scalars" in r.values], tick)
        if row is not None:
            return round(row.values["Scalars:scalars"][0])
        return len(self.edges(tick))

    def action_text(self, at: int | tuple[int, bytes]) -> str:
        row = _latest(self.action, at)
        if row is None or "TextDocument:text" not in row.values:
            return ""
        return row.values["TextDocument:text"][0].split("\n")[0].replace("**", "").strip()

    def action_count(self) -> int:
        """Actions in the plan, as the action panel numbers them (``"3/16: ..."``)."""
        for row in self.action:
            found = _NUMBERED.match(row.values.get("TextDocument:text", [""])[0])
            if found:
                return int(found.group(2))
        return 0

    def action_end(self, number: int) -> Row | None:
        """The ``events/actions`` row where action ``number`` (from 1) last ended."""
        ends = [r for r in self.actions if r.tick is not None and (found := _ACTION.match(
            r.values.get("TextLog:text", [""])[0])) and int(found.group(1)) == number]
        return ends[-1] if ends else None


def _graph_edges(row: Row) -> list[tuple[str, str, str | None]]:
    pairs = [(e["first"], e["second"]) for e in row.values.get("GraphEdges:edges", [])]
    ends: dict[str, list[str]] = {}
    out: list[tuple[str, str, str | None]] = []
    for a, b in pairs:
        if b.startswith(_LABEL):
            ends.setdefault(b, []).insert(0, a)
        elif a.startswith(_LABEL):
            ends.setdefault(a, []).append(b)
        else:
            out.append((a, b, None))
    for node, (a, b) in ((n, v) for n, v in ends.items() if len(v) == 2):
        out.append((a, b, node[len(_LABEL):]))
    return out


def _bodies(rows: dict[str, list[Row]]) -> dict[str, dict[str, Any]]:
    """Per module with poses: its shape, half size, colour, kind, faces and capsule."""
    found: dict[str, dict[str, Any]] = {}
    for entity, entity_rows in rows.items():
        match = _MODULE.match(entity)
        timed = [r for r in entity_rows if "Transform3D:translation" in r.values]
        if not match or not timed:
            continue
        static = next((r for r in entity_rows if r.tick is None), None)
        body = static.values if static else {}
        color = next((body[k][0] for k in ("Boxes3D:colors", "Ellipsoids3D:colors",
                                           "Capsules3D:colors") if k in body), None)
        out: dict[str, Any] = {"poses": timed, "kind": (body.get("kind") or [""])[0],
                               "color": _rgb(color) if color is not None else (.5,) * 3}
        if "Capsules3D:lengths" in body:
            z0 = (body.get("Capsules3D:translations") or [[0.0, 0.0, 0.0]])[0][2]
            radius = body["Capsules3D:radii"][0]
            out.update(shape="capsule", half=(radius, radius),
                       capsule=(z0, z0 + body["Capsules3D:lengths"][0], radius))
        else:
            sphere = "Ellipsoids3D:half_sizes" in body
            hx, hy, _ = (body.get("Ellipsoids3D:half_sizes") or body.get("Boxes3D:half_sizes")
                         or [[0.1, 0.1, 0.05]])[0]
            face = next((r.values for r in rows.get(f"{entity}/faces", [])), {})
            out.update(shape="sphere" if sphere else "box", half=(hx, hy), faces=[
                (p[0], p[1], _rgb(c)) for p, c in zip(face.get("Points3D:positions", []),
                                                      face.get("Points3D:colors", []),
                                                      strict=False)])
        found[match.group(1)] = out
    return found


def load_track(path: str | Path) -> Track:
    """Read what :func:`render_snapshot` draws from the recording at ``path``.

    Raises:
        MsrrError: missing or unreadable file, or no module poses in it.
    """
    rows = read_rows(path)
    bodies = _bodies(rows)
    if not bodies:
        raise MsrrError(f"{path}: no module poses (world/modules/<id>) in this recording")
    modules = sorted(bodies, key=lambda m: (len(m), m))
    times: dict[int, float] = {}  # a tick's time: its latest (the initial state is at 0 s)
    start = math.inf
    for entity_rows in rows.values():
        for r in entity_rows:
            if r.tick is not None and r.sim_time is not None:
                times[r.tick] = max(times.get(r.tick, -math.inf), r.sim_time)
                start = min(start, r.sim_time)

    def texts(*names: str) -> list[tuple[int, float, str]]:
        return sorted((r.tick, r.sim_time or 0.0, r.values["TextLog:text"][0]) for name in names
                      for r in rows.get(name, []) if r.tick is not None and "TextLog:text"
                      in r.values)

    errors = {m: [r for r in rows.get(f"/errors/{m}", []) if r.tick is not None]
              for m in modules}
    errors = {m: e for m, e in errors.items() if any("Scalars:scalars" in r.values for r in e)}
    name = next((r.values["RecordingInfo:name"][0] for r in rows.get("/__properties", [])
                 if "RecordingInfo:name" in r.values), "")
    ghost = {k: sorted(rows.get(f"/world/ghost/{k}", []) + rows.get("/world/ghost", []),
                       key=lambda r: r.order) for k in _GHOST}
    return Track(
        modules, {m: bodies[m]["half"] for m in modules},
        {m: bodies[m]["color"] for m in modules},
        {m: bodies[m]["faces"] for m in modules if "faces" in bodies[m]},
        {m: bodies[m]["poses"] for m in modules}, rows.get("/topology/current", []),
        rows.get("/action", []), rows.get("/world/targets", []), errors,
        texts("/events/docks", "/events/undocks"), times,
        {m: bodies[m]["shape"] for m in modules},
        {m: bodies[m]["capsule"] for m in modules if "capsule" in bodies[m]},
        {m: rows[f"/world/modules/{m}/connectors"] for m in modules
         if f"/world/modules/{m}/connectors" in rows},
        rows.get("/topology/connections", []), ghost, name,
        [r for r in rows.get("/shape/angle", []) if r.tick is not None],
        {m: bodies[m]["kind"] for m in modules}, texts("/events/flows"),
        rows.get("/events/actions", []), start if math.isfinite(start) else 0.0)


def pick_moment(track: Track, at: float | None = None, action: int | None = None
                ) -> Moment | None:
    """The moment ``platform snapshot --at SECONDS`` or ``--action K`` draws, ``None``
    for neither: the last tick at or before simulated time ``at`` [s], or where action
    ``action`` (from 1, as the plan numbers it) ended, its target as it was then.

    Raises:
        MsrrError: both given, or a value outside the recording (one line naming the
            option and the range it takes).
    """
    if at is not None and action is not None:
        raise MsrrError("--at and --action cannot be combined: choose one moment")
    if at is not None:
        first, last = track.start_time, track.sim_time(track.last_tick)
        if not (math.isfinite(at) and first - 1e-9 <= at <= last + 1e-9):
            raise MsrrError(f"--at {at:g}: outside the recording (simulated time {first:.2f} "
                            f"to {last:.2f} s)")
        tick = max((t for t, time in track.times.items() if time <= at + 1e-9),
                   default=track.first_tick)
        return Moment.of_tick(tick, f"at t = {at:g} s")
    if action is not None:
        total = track.action_count()
        if not 1 <= action <= total:
            raise MsrrError(f"--action {action}: the plan has {total} actions "
                            f"(1 to {total})" if total else
                            f"--action {action}: this recording has no actions")
        end = track.action_end(action)
        if end is None:
            raise MsrrError(f"--action {action}: action {action} did not end in this "
                            "recording (the run stopped before it ended, or skipped it)")
        return Moment(end.tick, end.order, f"end of action {action}")
    return None


def _pick_ticks(track: Track) -> list[int]:
    """Start, one and two thirds of the run, and the end."""
    last, start = track.last_tick, track.first_tick
    return sorted({start, start + (last - start) // 3, start + 2 * (last - start) // 3, last})


# -- one panel: the robot from above --------------------------------------------------------


@dataclass
class _Label:
    """A text in a panel: kept where it is (``fixed``), or tried at ``spots`` (data
    coordinates, first the natural place) with a leader line to ``anchor``."""

    text: Any
    fixed: bool
    spots: list[tuple[float, float]] = field(default_factory=list)
    anchor: tuple[float, float] = (0.0, 0.0)


def _footprint(ax: Any, track: Track, moment: Moment) -> list[_Label]:
    """One panel; returns its labels for :func:`_declutter`."""
    from matplotlib.patches import Circle

    tick = moment.tick
    labels: list[_Label] = []
    centers = {m: p for m in track.modules if (p := track.pose(m, tick)) is not None}
    _goals(ax, track, moment)
    _ghost(ax, track, moment)
    for a, b, edge_id in track.edges_with_ids(tick):  # a bar across the gap of two bodies
        if edge_id in track.capsules or a not in centers or b not in centers:
            continue  # an edge module is drawn as itself
        (xa, ya, _), (xb, yb, _) = centers[a], centers[b]
        d = math.hypot(xb - xa, yb - ya) or 1.0
        ux, uy = (xb - xa) / d, (yb - ya) / d
        ra, rb = track.half[a][0] * 0.8, track.half[b][0] * 0.8
        ax.plot([xa + ux * ra, xb - ux * rb], [ya + uy * ra, yb - uy * rb],
                color="black", lw=3, zorder=4, solid_capstyle="butt")
    for m, (x, y, yaw) in centers.items():
        shape = track.shapes.get(m, "box")
        if shape == "capsule":
            labels += _capsule(ax, track, m, tick)
            continue
        hx, hy = track.half[m]
        if shape == "sphere":
            ax.add_patch(Circle((x, y), hx, fc=track.colors[m], ec="black", lw=0.8,
                                alpha=0.75, zorder=2))
        else:
            _box(ax, track, m, (x, y, yaw))
        labels.append(_Label(ax.text(x, y, m, ha="center", va="center", fontsize=_font(ax),
                                     fontweight="bold", zorder=7), fixed=True))
    text = track.action_text(moment.at)
    title = f"tick {tick}, t = {track.sim_time(tick):.1f} s"
    title += f" ({moment.label})" if moment.label else ""
    ax.set_title(title + (f"\n{_wrap(text)}" if text else ""), fontsize=8)
    ax.set_aspect("equal")
    ax.grid(True, lw=0.3, alpha=0.5)
    ax.tick_params(labelsize=7)
    return labels


def _font(ax: Any) -> float:
    """Font size [pt] of a module id: 8, or 9 in a panel over 4 in wide (strut ids 1.5 less)."""
    inches = ax.get_position().width * ax.get_figure().get_figwidth()
    return 9.0 if inches > 4.0 else 8.0


def _box(ax: Any, track: Track, module: str, pose: tuple[float, float, float]) -> None:
    """A box module from above: its footprint, its ports as dots, its front edge bold."""
    from matplotlib.patches import Polygon

    x, y, yaw = pose
    hx, hy = track.half[module]
    corners = _corners(x, y, yaw, hx, hy)
    ax.add_patch(Polygon(corners, closed=True, fc=track.colors[module], ec="black", lw=0.8,
                         alpha=0.6, zorder=2))
    c, s = math.cos(yaw), math.sin(yaw)
    for fx, fy, color in track.faces.get(module, []):
        ax.plot(x + c * fx * 0.9 - s * fy * 0.9, y + s * fx * 0.9 + c * fy * 0.9, "o",
                ms=3, color=color, zorder=3)
    ax.plot([corners[3][0], corners[0][0]], [corners[3][1], corners[0][1]], color="0.1",
            lw=2.5, zorder=3, solid_capstyle="butt")  # heading: the front (+x) edge


def _capsule(ax: Any, track: Track, module: str, tick: int) -> list[_Label]:
    """An edge module from above: a bar of its diameter with round ends, its connectors
    as dots coloured by state, its id at the middle (or, if crowded, along or beside it)."""
    from matplotlib.patches import Circle, Polygon

    ends = track.capsule_ends(module, tick)
    if ends is None:
        return []
    (xa, ya), (xb, yb) = ends
    r = track.capsules[module][2]
    d = math.hypot(xb - xa, yb - ya) or 1e-9
    nx_, ny_ = -(yb - ya) / d, (xb - xa) / d
    color = track.colors[module]
    ax.add_patch(Polygon([(xa + nx_ * r, ya + ny_ * r), (xb + nx_ * r, yb + ny_ * r),
                          (xb - nx_ * r, yb - ny_ * r), (xa - nx_ * r, ya - ny_ * r)],
                         closed=True, fc=color, ec="black", lw=0.6, alpha=0.85, zorder=4))
    states = track.connector_states(module, tick)
    for i, (x, y) in enumerate(ends):
        fc = states[i][1] if i < len(states) else color
        ax.add_patch(Circle((x, y), r * 0.9, fc=fc, ec="black", lw=0.4, zorder=5))
    mx, my = (xa + xb) / 2, (ya + yb) / 2
    spots = [(mx, my), *((xa + f * (xb - xa), ya + f * (yb - ya)) for f in (0.3, 0.7))]
    spots += [(mx + side * k * r * nx_, my + side * k * r * ny_) for k in (3.5, 6.0)
              for side in (1, -1)]
    text = ax.text(mx, my, module, ha="center", va="center", fontsize=_font(ax) - 1.5, zorder=7,
                   bbox={"boxstyle": "round,pad=0.1", "fc": "white", "ec": "none",
                         "alpha": 0.8})
    return [_Label(text, fixed=False, spots=spots, anchor=(mx, my))]


def _goals(ax: Any, track: Track, moment: Moment) -> None:
    """Goal poses the planner gave the moving modules (``world/targets``), dashed in
    each module's colour."""
    from matplotlib.patches import Polygon

    target = _latest(track.targets, moment.at)
    if target is None or "Boxes3D:centers" not in target.values:
        return
    v = target.values
    hs = v.get("Boxes3D:half_sizes") or [[0.1, 0.1, 0.05]]
    colors = v.get("Boxes3D:colors") or []
    for i, c in enumerate(v["Boxes3D:centers"]):
        q = (v.get("Boxes3D:quaternions") or [[0, 0, 0, 1]] * (i + 1))[i]
        h = hs[min(i, len(hs) - 1)]
        ec = _rgb(colors[min(i, len(colors) - 1)]) if colors else "0.45"
        ax.add_patch(Polygon(_corners(c[0], c[1], _yaw(q), h[0], h[1]), closed=True,
                             fill=False, ls="--", lw=1.1, ec=ec, zorder=1))


def _ghost(ax: Any, track: Track, moment: Moment) -> None:
    """The running action's target laid out on the robot (``world/ghost``), dashed grey."""
    from matplotlib.patches import Circle, Polygon

    nodes = _latest(track.ghost.get("nodes", []), moment.at)
    if nodes is not None and "Ellipsoids3D:centers" in nodes.values:
        for c, h in zip(nodes.values["Ellipsoids3D:centers"],
                        nodes.values.get("Ellipsoids3D:half_sizes", []), strict=False):
            ax.add_patch(Circle((c[0], c[1]), h[0], fill=False, ls="--", lw=0.9, ec="0.4",
                                zorder=1))
    boxes = _latest(track.ghost.get("boxes", []), moment.at)
    if boxes is not None and "Boxes3D:centers" in boxes.values:
        v = boxes.values
        quats = v.get("Boxes3D:quaternions") or [[0, 0, 0, 1]] * len(v["Boxes3D:centers"])
        for c, h, q in zip(v["Boxes3D:centers"], v.get("Boxes3D:half_sizes", []), quats,
                           strict=False):
            ax.add_patch(Polygon(_corners(c[0], c[1], _yaw(q), h[0], h[1]), closed=True,
                                 fill=False, ls="--", lw=0.9, ec="0.4", zorder=1))
    struts = _latest(track.ghost.get("struts", []), moment.at)
    if struts is not None and "Capsules3D:lengths" in struts.values:
        v = struts.values
        for t, q, length in zip(v.get("Capsules3D:translations", []),
                                v.get("Capsules3D:quaternions", []), v["Capsules3D:lengths"],
                                strict=False):
            dx, dy, _ = _rotate(q, (0.0, 0.0, length))
            ax.plot([t[0], t[0] + dx], [t[1], t[1] + dy], ls="--", lw=1.2, color="0.4",
                    zorder=1)


def _wrap(text: str, width: int = 38) -> str:
    return "\n".join(textwrap.wrap(text, width)[:2])


def _corners(x: float, y: float, yaw: float, hx: float, hy: float) -> list[tuple[float, float]]:
    c, s = math.cos(yaw), math.sin(yaw)
    return [(x + c * dx - s * dy, y + s * dx + c * dy)
            for dx, dy in ((hx, hy), (-hx, hy), (-hx, -hy), (hx, -hy))]


def _overlaps(box: Any, others: list[Any]) -> bool:
    return any(box.overlaps(other) for other in others)


def _declutter(fig: Any, panels: list[tuple[Any, list[_Label]]]) -> int:
    """Move each movable label that covers an earlier one (or leaves its panel) to the
    first free spot, with a thin leader line back to its strut; hide it when no spot is
    free. Fixed labels (module ids on their bodies) stay. Returns how many were hidden."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig)
    fig.draw_without_rendering()  # lays the figure out: text extents in display units
    renderer = fig.canvas.get_renderer()
    hidden = 0
    for ax, labels in panels:
        frame = ax.get_window_extent(renderer)
        taken = [lab.text.get_window_extent(renderer).expanded(1.05, 1.1)
                 for lab in labels if lab.fixed]
        for label in (lab for lab in labels if not lab.fixed):
            for spot in label.spots:
                label.text.set_position(spot)
                box = label.text.get_window_extent(renderer).expanded(1.05, 1.1)
                inside = (frame.x0 <= box.x0 and box.x1 <= frame.x1 and frame.y0 <= box.y0
                          and box.y1 <= frame.y1)
                if inside and not _overlaps(box, taken):
                    taken.append(box)
                    if spot != label.spots[0]:
                        ax.plot([label.anchor[0], spot[0]], [label.anchor[1], spot[1]],
                                color="0.35", lw=0.5, zorder=6)
                    break
            else:
                label.text.set_visible(False)
                hidden += 1
    return hidden


# -- the figure ----------------------------------------------------------------------------


def legend_entries(track: Track) -> list[str]:
    """What this recording's panels draw, one entry per kind of mark it uses (a robot of
    spheres gets no face or heading entry, a robot without struts no connector colours)."""
    shapes = set(track.shapes.values())

    def kinds(shape: str) -> str:
        names = sorted({track.kinds.get(m) or "module" for m, s in track.shapes.items()
                        if s == shape})
        return ", ".join(names)

    entries = []
    if "box" in shapes:
        entries.append(f"box: {kinds('box')} (id, bold edge: front)")
    if any(track.faces.values()):
        entries.append("red/blue dot: active/passive port")
    if "sphere" in shapes:
        entries.append(f"circle: {kinds('sphere')} (id)")
    if "capsule" in shapes:
        entries.append(f"bar: {kinds('capsule')} (id at its middle), end dot green docked, "
                       "orange extending, purple releasing, grey free")
    ticks = sorted({r.tick for r in track.topology if r.tick is not None})
    if any(e not in track.capsules for t in ticks for _, _, e in track.edges_with_ids(t)):
        entries.append("black bar: docked connection")
    if any("Boxes3D:centers" in r.values for r in track.targets):
        entries.append("dashed, module's colour: goal pose of a moving module")
    if any(any(k in r.values for k in ("Ellipsoids3D:centers", "Boxes3D:centers",
                                       "Capsules3D:lengths"))
           for rows in track.ghost.values() for r in rows):
        entries.append("dashed grey: target shape of the running action (at the end: the "
                       "run's goal), fitted onto the modules")
    return entries


def _legend(track: Track, title: str) -> str:
    lines, line = [], ""
    for entry in legend_entries(track):
        if line and len(line) + len(entry) + 2 > 150:
            lines.append(line)
            line = ""
        line = f"{line}; {entry}" if line else entry
    lines += [line] if line else []
    return "\n".join([title, *lines] if title else lines)


def _flow_sides(text: str) -> list[str]:
    """``["F1-F2", "F1-F3"]`` of ``"flow F1-F2 -> F1-F3 at t=4.4 s"`` (broken, made)."""
    return text.removeprefix("flow ").split(" at t=")[0].split(" -> ")


def _connections(ax: Any, track: Track, marks: list[int]) -> None:
    """Docked connections over time; docks green, undocks red, each flow's handover a
    purple diamond on the line with its two connections."""
    from matplotlib.ticker import MaxNLocator

    changes = [r for r in (track.connections or track.topology)
               if r.tick is not None and ("Scalars:scalars" in r.values or not track.connections)]
    times = [r.sim_time or 0.0 for r in changes]
    counts = [track.docked(r.tick) for r in changes if r.tick is not None]
    if times:
        times.append(track.sim_time(track.last_tick))
        counts.append(counts[-1])
        ax.step(times, counts, where="post", color="black", lw=1.5)
        ax.set_ylim(max(min(counts) - 1.3, -0.3), max(counts) + 1.3)  # two whole numbers
    handed = {(round(t, 6), part.strip()) for _, t, text in track.flows
              for side in _flow_sides(text) for part in side.split(",")}
    for _, t, text in track.events:
        kind, _, rest = text.partition(" ")
        if (round(t, 6), rest.split(" at ")[0]) in handed:
            continue  # drawn as the flow
        ax.axvline(t, color="tab:green" if kind == "dock" else "tab:red", lw=0.8, ls=":")
    span = max(times[-1] - times[0], 1e-9) if times else 1.0
    shown = {0.03: -math.inf, 0.97: -math.inf}  # last label at the bottom, at the top
    for tick, t, text in track.flows:
        ax.axvline(t, color=_FLOW, lw=0.8, ls=":")
        ax.plot([t], [track.docked(tick)], "D", color=_FLOW, ms=5, zorder=5)
        free = [y for y, last in shown.items() if t - last > 0.03 * span]
        if free:  # a label closer than that to the last one on its side would cover it
            shown[free[0]] = t
            ax.text(t, free[0], "→".join(_flow_sides(text)), rotation=90, fontsize=6,
                    color=_FLOW, ha="right", va="bottom" if free[0] < 0.5 else "top",
                    transform=ax.get_xaxis_transform(), clip_on=True)
    for tick in marks:
        ax.axvline(track.sim_time(tick), color="0.6", lw=0.6)
    ax.set_title("connections (green: dock, red: undock, "
                 + ("purple: flow, " if track.flows else "")
                 + ("grey: panels above)" if len(marks) > 1 else "grey: the moment above)"),
                 fontsize=8)
    ax.set_xlabel("sim time [s]", fontsize=8)
    ax.set_ylabel("docked connections", fontsize=8)
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))


def _errors(ax: Any, track: Track, marks: list[int]) -> None:
    """The RMS connection angle to the target, or each moving module's distance to its goal."""
    if track.angle:
        ax.plot([r.sim_time for r in track.angle],
                [r.values.get("Scalars:scalars", [math.nan])[0] for r in track.angle],
                lw=1.2, color="black")
        ax.set_title("RMS connection angle to the running action's target [deg] (eq. 8)",
                     fontsize=8)
    else:
        for m, rows in track.errors.items():  # a cleared row (module idle) breaks the line
            ax.plot([r.sim_time for r in rows],
                    [r.values["Scalars:scalars"][0] if "Scalars:scalars" in r.values
                     else math.nan for r in rows], lw=1, color=track.colors[m], label=m)
        ax.set_title("distance of each moving module to its goal [m]", fontsize=8)
        if track.errors:
            ax.legend(fontsize=7, ncols=2, title="module", title_fontsize=7)
    for tick in marks:
        ax.axvline(track.sim_time(tick), color="0.6", lw=0.6)
    ax.set_xlabel("sim time [s]", fontsize=8)


Extent = tuple[float, float, float, float]
"""``(x0, x1, y0, y1)`` [m] a panel shows."""
_PAD = 0.25  # [m] around the modules


def _bounds(points: list[tuple[float, float]]) -> Extent:
    xs, ys = [p[0] for p in points], [p[1] for p in points]
    return min(xs) - _PAD, max(xs) + _PAD, min(ys) - _PAD, max(ys) + _PAD


def _extents(track: Track, ticks: list[int]) -> list[Extent]:
    """What each panel shows: every module position of the run, padded, the same in
    every panel so they compare; or, for a robot that travels (the run's extent over
    1.5 times the largest of the moments'), a window of one size centred on the robot at
    each moment (same scale, its own place: the axes say where)."""
    run = _bounds([tuple(r.values["Transform3D:translation"][0][:2])
                   for m in track.modules for r in track.poses[m]])
    here = [_bounds([p[:2] for m in track.modules if (p := track.pose(m, t)) is not None])
            for t in ticks]
    wide = max(e[1] - e[0] for e in here)
    tall = max(e[3] - e[2] for e in here)
    if max(run[1] - run[0], run[3] - run[2]) <= 1.5 * max(wide, tall):
        return [run] * len(ticks)
    return [((e[0] + e[1] - wide) / 2, (e[0] + e[1] + wide) / 2,
             (e[2] + e[3] - tall) / 2, (e[2] + e[3] + tall) / 2) for e in here]


def _panel_width(track: Track, extent: Extent) -> float:
    """Width [in] of a footprint panel: 3.2, wider (up to 6) when the smallest body would
    be drawn under 0.32 in across (many small modules: their ids need room)."""
    smallest = min((min(h) * 2 for m, h in track.half.items()
                    if track.shapes.get(m) != "capsule"), default=0.1)
    span = max(extent[1] - extent[0], 1e-3)
    return min(6.0, max(3.2, 0.32 * span / max(smallest, 1e-3)))


def _panels(track: Track, extent: Extent, top: float, count: int
            ) -> tuple[Any, list[Any], Any, Any]:
    """The figure of ``count`` moments (up to four): one row of panels (3.2 to 3.6 in
    wide), or, when the robot has more than 12 modules, rows of two panels at least 4.8
    in wide (the ids of many small modules need the room)."""
    from matplotlib.figure import Figure

    aspect = (extent[3] - extent[2]) / max(extent[1] - extent[0], 1e-3)
    width = _panel_width(track, extent)
    columns = count if len(track.modules) <= 12 else 2
    width = min(width, 3.6) if columns == count else max(width, 4.8)
    panel = min((width - 0.7) * aspect, 1.6 * width) + 1.0  # [in]: axes, ticks, titles
    rows = math.ceil(count / columns)
    fig = Figure(figsize=(width * max(columns, 2), top + rows * panel + 2.4), dpi=110,
                 layout="constrained")
    grid = fig.add_gridspec(rows + 1, 2 * columns, height_ratios=[panel] * rows + [2.4])
    axes = [fig.add_subplot(grid[i // columns, 2 * (i % columns):2 * (i % columns) + 2])
            for i in range(count)]
    return fig, axes, fig.add_subplot(grid[rows, :columns]), fig.add_subplot(grid[rows, columns:])


def render_snapshot(track: Track, title: str = "", moment: Moment | None = None) -> Any:
    """A matplotlib figure of ``track`` (Agg; the caller saves or closes it): four
    moments of the run, or the one ``moment`` drawn large, over the two time plots."""
    from matplotlib.figure import Figure

    moments = [moment] if moment else [Moment.of_tick(t) for t in _pick_ticks(track)]
    extents = _extents(track, [m.tick for m in moments])
    extent = extents[0]
    legend = _legend(track, title or track.title)
    aspect = (extent[3] - extent[2]) / max(extent[1] - extent[0], 1e-3)
    top = 1.1 + 0.16 * legend.count("\n")  # [in]: the title and legend lines
    if moment is None:
        fig, axes, conn, err = _panels(track, extent, top, len(moments))
    else:
        panel = min(8.3 * aspect, 8.0) + 1.0
        fig = Figure(figsize=(9.0, top + panel + 2.6), dpi=110, layout="constrained")
        grid = fig.add_gridspec(2, 2, height_ratios=[panel, 2.6])
        axes = [fig.add_subplot(grid[0, :])]
        conn, err = fig.add_subplot(grid[1, 0]), fig.add_subplot(grid[1, 1])
    panels = [(ax, _footprint(ax, track, m)) for ax, m in zip(axes, moments, strict=True)]
    for ax, (x0, x1, y0, y1) in zip(axes, extents, strict=True):
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
        ax.set_xlabel("x [m]", fontsize=8)
    axes[0].set_ylabel("y [m]", fontsize=8)
    marks = [m.tick for m in moments]
    _connections(conn, track, marks)
    _errors(err, track, marks)
    for ax in (conn, err):
        ax.tick_params(labelsize=7)
        ax.grid(True, lw=0.3, alpha=0.5)
    fig.suptitle(legend, fontsize=9)
    _declutter(fig, panels)
    return fig


def write_snapshot(recording: str | Path, image: str | Path, title: str = "", *,
                   at: float | None = None, action: int | None = None) -> Path:
    """Render ``recording`` to the PNG ``image``, written atomically: four moments, or the
    one :func:`pick_moment` chooses for ``at`` [s of simulated time] or ``action`` (from 1).

    Raises:
        MsrrError: unreadable recording, a moment outside it, or matplotlib is not installed.
    """
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise MsrrError("platform snapshot needs matplotlib: pip install 'msrr-platform[plot]'"
                        ) from None
    track = load_track(recording)
    moment = pick_moment(track, at, action)
    fig = render_snapshot(track, title or track.title or Path(recording).name, moment)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png")
    return atomic_write_bytes(image, buffer.getvalue())
