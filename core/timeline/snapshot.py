"""Draw a still image of a run from its recording (no display needed).

:func:`load_track` reads the module bodies and poses, the recognized topology, the
connector states of edge modules, the action text, the dock/undock events, the docked
connections and the per-module errors back from a ``run.rrd``
(:func:`msrr.core.timeline.readback.read_rows`); :func:`render_snapshot` draws them
with matplotlib (Agg): top-down footprints at the start, two intermediate ticks and
the end (boxes as rectangles, spheres as circles, capsules as thick bars with their
connectors), plus connections and errors over time, under a title naming the robot and
the scenario.

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

__all__ = ["Track", "load_track", "render_snapshot", "write_snapshot"]

_MODULE = re.compile(r"^/world/modules/([^/]+)$")
_LABEL = "edge:"  # graph label nodes (msrr.core.timeline.geometry.label_node)


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


def _latest(rows: list[Row], tick: int) -> Row | None:
    timed = [(r.tick, r) for r in rows if r.tick is not None]
    i = bisect_right([t for t, _ in timed], tick)
    return timed[i - 1][1] if i else None


@dataclass
class Track:
    """What a snapshot needs from one recording.

    ``shapes``: per module ``"box"``, ``"sphere"`` or ``"capsule"``; ``half``: a box's
    half extents or a sphere's radius twice [m]; ``capsules``: a capsule's ``(z of its
    first end, z of its second end, radius)`` in its body frame [m]; ``connectors``: the
    connector rows of edge modules; ``connections``: docked-connection count rows;
    ``title``: robot and scenario, as the recording names itself; ``angle``: RMS strut
    angle to the running action's target [deg] (robots with connection vectors).
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

    @property
    def last_tick(self) -> int:
        return max(self.times) if self.times else 0

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
        if row is None:
            return []
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
        row = _latest(self.connections, tick)
        if row is not None and "Scalars:scalars" in row.values:
            return round(row.values["Scalars:scalars"][0])
        return len(self.edges(tick))

    def action_text(self, tick: int) -> str:
        row = _latest(self.action, tick)
        if row is None or "TextDocument:text" not in row.values:
            return ""
        return row.values["TextDocument:text"][0].split("\n")[0].replace("**", "").strip()


def load_track(path: str | Path) -> Track:
    """Read what :func:`render_snapshot` draws from the recording at ``path``.

    Raises:
        MsrrError: missing or unreadable file, or no module poses in it.
    """
    rows = read_rows(path)
    modules, half, colors, faces, poses = [], {}, {}, {}, {}
    shapes, capsules = {}, {}
    for entity, entity_rows in rows.items():
        match = _MODULE.match(entity)
        if not match:
            continue
        module = match.group(1)
        static = next((r for r in entity_rows if r.tick is None), None)
        timed = [r for r in entity_rows if "Transform3D:translation" in r.values]
        if not timed:
            continue
        modules.append(module)
        poses[module] = timed
        body = static.values if static else {}
        color = next((body[k][0] for k in ("Boxes3D:colors", "Ellipsoids3D:colors",
                                           "Capsules3D:colors") if k in body), None)
        colors[module] = _rgb(color) if color is not None else (.5,) * 3
        if "Capsules3D:lengths" in body:
            shapes[module] = "capsule"
            z0 = (body.get("Capsules3D:translations") or [[0.0, 0.0, 0.0]])[0][2]
            radius = body["Capsules3D:radii"][0]
            capsules[module] = (z0, z0 + body["Capsules3D:lengths"][0], radius)
            half[module] = (radius, radius)
            continue
        if "Ellipsoids3D:half_sizes" in body:
            shapes[module] = "sphere"
            hx, hy, _ = body["Ellipsoids3D:half_sizes"][0]
        else:
            shapes[module] = "box"
            hx, hy, _ = (body.get("Boxes3D:half_sizes") or [[0.1, 0.1, 0.05]])[0]
        half[module] = (hx, hy)
        face = next((r.values for r in rows.get(f"{entity}/faces", [])), {})
        positions, face_colors = face.get("Points3D:positions", []), face.get("Points3D:colors", [])
        faces[module] = [(p[0], p[1], _rgb(c))
                         for p, c in zip(positions, face_colors, strict=False)]
    if not modules:
        raise MsrrError(f"{path}: no module poses (world/modules/<id>) in this recording")
    modules.sort(key=lambda m: (len(m), m))
    times: dict[int, float] = {}
    for entity_rows in rows.values():
        for r in entity_rows:
            if r.tick is not None and r.sim_time is not None:
                times.setdefault(r.tick, r.sim_time)
    events = [(r.tick, r.sim_time or 0.0, r.values["TextLog:text"][0])
              for name in ("/events/docks", "/events/undocks") for r in rows.get(name, [])
              if r.tick is not None and "TextLog:text" in r.values]
    errors = {m: [r for r in rows.get(f"/errors/{m}", []) if r.tick is not None]
              for m in modules}
    errors = {m: e for m, e in errors.items() if any("Scalars:scalars" in r.values for r in e)}
    angle = [r for r in rows.get("/shape/angle", []) if r.tick is not None]
    connectors = {m: rows[f"/world/modules/{m}/connectors"] for m in modules
                  if f"/world/modules/{m}/connectors" in rows}
    name = next((r.values["RecordingInfo:name"][0] for r in rows.get("/__properties", [])
                 if "RecordingInfo:name" in r.values), "")
    ghost = {k: rows.get(f"/world/ghost/{k}", []) + rows.get("/world/ghost", [])
             for k in ("nodes", "struts")}
    for k in ghost:
        ghost[k].sort(key=lambda r: -1 if r.tick is None else r.tick)
    return Track(modules, half, colors, faces, poses, rows.get("/topology/current", []),
                 rows.get("/action", []), rows.get("/world/targets", []), errors,
                 sorted(events), times, shapes, capsules, connectors,
                 rows.get("/topology/connections", []), ghost, name, angle)


def _pick_ticks(track: Track) -> list[int]:
    """Start, one and two thirds of the run, and the end."""
    last = track.last_tick
    start = min(track.times) if track.times else 0
    return sorted({start, start + (last - start) // 3, start + 2 * (last - start) // 3, last})


def _footprint(ax: Any, track: Track, tick: int) -> None:
    from matplotlib.patches import Circle, Polygon

    centers = {m: p for m in track.modules if (p := track.pose(m, tick)) is not None}
    target = _latest(track.targets, tick)
    if target is not None and "Boxes3D:centers" in target.values:
        hs = target.values.get("Boxes3D:half_sizes") or [[0.1, 0.1, 0.05]]
        for i, c in enumerate(target.values["Boxes3D:centers"]):
            q = target.values.get("Boxes3D:quaternions", [[0, 0, 0, 1]] * (i + 1))[i]
            h = hs[min(i, len(hs) - 1)]
            ax.add_patch(Polygon(_corners(c[0], c[1], _yaw(q), h[0], h[1]), closed=True,
                                 fill=False, ls="--", lw=1.0, ec="0.45", zorder=1))
    _ghost(ax, track, tick)
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
            _capsule(ax, track, m, tick)
            continue
        hx, hy = track.half[m]
        if shape == "sphere":
            ax.add_patch(Circle((x, y), hx, fc=track.colors[m], ec="black", lw=0.8,
                                alpha=0.75, zorder=2))
            ax.text(x, y, m, ha="center", va="center", fontsize=8, fontweight="bold", zorder=7)
            continue
        ax.add_patch(Polygon(_corners(x, y, yaw, hx, hy), closed=True, fc=track.colors[m],
                             ec="black", lw=0.8, alpha=0.6, zorder=2))
        c, s = math.cos(yaw), math.sin(yaw)
        for fx, fy, color in track.faces.get(m, []):
            ax.plot(x + c * fx * 0.9 - s * fy * 0.9, y + s * fx * 0.9 + c * fy * 0.9, "o",
                    ms=3, color=color, zorder=3)
        front = _corners(x, y, yaw, hx, hy)[3], _corners(x, y, yaw, hx, hy)[0]
        ax.plot([front[0][0], front[1][0]], [front[0][1], front[1][1]], color="0.1", lw=2.5,
                zorder=3, solid_capstyle="butt")  # heading: the front (+x) edge
        ax.text(x, y, m, ha="center", va="center", fontsize=8, fontweight="bold", zorder=6)
    text = track.action_text(tick)
    title = f"tick {tick}, t = {track.sim_time(tick):.1f} s"
    ax.set_title(title + (f"\n{_wrap(text)}" if text else ""), fontsize=8)
    ax.set_aspect("equal")
    ax.grid(True, lw=0.3, alpha=0.5)
    ax.tick_params(labelsize=7)


def _capsule(ax: Any, track: Track, module: str, tick: int) -> None:
    """An edge module from above: a bar of its diameter with round ends, its connectors
    as dots coloured by state, its id at the middle."""
    from matplotlib.patches import Circle, Polygon

    ends = track.capsule_ends(module, tick)
    if ends is None:
        return
    (xa, ya), (xb, yb) = ends
    r = track.capsules[module][2]
    d = math.hypot(xb - xa, yb - ya) or 1e-9
    nx_, ny_ = -(yb - ya) / d * r, (xb - xa) / d * r
    color = track.colors[module]
    ax.add_patch(Polygon([(xa + nx_, ya + ny_), (xb + nx_, yb + ny_), (xb - nx_, yb - ny_),
                          (xa - nx_, ya - ny_)], closed=True, fc=color, ec="black", lw=0.6,
                         alpha=0.85, zorder=4))
    states = track.connector_states(module, tick)
    for i, (x, y) in enumerate(ends):
        fc = states[i][1] if i < len(states) else color
        ax.add_patch(Circle((x, y), r * 0.9, fc=fc, ec="black", lw=0.4, zorder=5))
    ax.text((xa + xb) / 2, (ya + yb) / 2, module, ha="center", va="center", fontsize=6,
            zorder=7, bbox={"boxstyle": "round,pad=0.1", "fc": "white", "ec": "none",
                            "alpha": 0.7})


def _ghost(ax: Any, track: Track, tick: int) -> None:
    """The running action's target laid out on the robot (``world/ghost``), dashed."""
    from matplotlib.patches import Circle

    nodes = _latest(track.ghost.get("nodes", []), tick)
    if nodes is not None and "Ellipsoids3D:centers" in nodes.values:
        for c, h in zip(nodes.values["Ellipsoids3D:centers"],
                        nodes.values.get("Ellipsoids3D:half_sizes", []), strict=False):
            ax.add_patch(Circle((c[0], c[1]), h[0], fill=False, ls="--", lw=0.9, ec="0.4",
                                zorder=1))
    struts = _latest(track.ghost.get("struts", []), tick)
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


def render_snapshot(track: Track, title: str = "") -> Any:
    """A matplotlib figure of ``track`` (Agg; the caller saves or closes it)."""
    from matplotlib.figure import Figure

    ticks = _pick_ticks(track)
    fig = Figure(figsize=(3.2 * len(ticks), 6.4), dpi=110, layout="constrained")
    grid = fig.add_gridspec(2, len(ticks), height_ratios=[2.1, 1])
    axes = [fig.add_subplot(grid[0, i]) for i in range(len(ticks))]
    for ax, tick in zip(axes, ticks, strict=True):
        _footprint(ax, track, tick)
    xs, ys = [], []  # one shared, padded extent so the panels compare
    for m in track.modules:
        for r in track.poses[m]:
            x, y, _ = r.values["Transform3D:translation"][0]
            xs.append(x)
            ys.append(y)
    pad = 0.25
    for ax in axes:
        ax.set_xlim(min(xs) - pad, max(xs) + pad)
        ax.set_ylim(min(ys) - pad, max(ys) + pad)
    axes[0].set_ylabel("y [m]", fontsize=8)
    for ax in axes:
        ax.set_xlabel("x [m]", fontsize=8)
    half = len(ticks) // 2
    conn = fig.add_subplot(grid[1, :half])
    changes = [r for r in (track.connections or track.topology) if r.tick is not None]
    times = [r.sim_time or 0.0 for r in changes]
    counts = [track.docked(r.tick) for r in changes if r.tick is not None]
    if times:
        times.append(track.sim_time(track.last_tick))
        counts.append(counts[-1])
        conn.step(times, counts, where="post", color="black", lw=1.5)
    for _, t, text in track.events:
        dock = text.startswith("dock")
        conn.axvline(t, color="tab:green" if dock else "tab:red", lw=0.8, ls=":")
    for tick in ticks:
        conn.axvline(track.sim_time(tick), color="0.6", lw=0.6)
    conn.set_title("connections (green: dock, red: undock, grey: panels above)", fontsize=8)
    conn.set_xlabel("sim time [s]", fontsize=8)
    conn.set_ylabel("docked connections", fontsize=8)
    conn.yaxis.get_major_locator().set_params(integer=True)
    err = fig.add_subplot(grid[1, half:])
    if track.angle:
        err.plot([r.sim_time for r in track.angle],
                 [r.values.get("Scalars:scalars", [math.nan])[0] for r in track.angle],
                 lw=1.2, color="black")
        err.set_title("RMS connection angle to the running action's target [deg] (eq. 8)",
                      fontsize=8)
    else:
        for m, rows in track.errors.items():  # a cleared row (module idle) breaks the line
            err.plot([r.sim_time for r in rows],
                     [r.values["Scalars:scalars"][0] if "Scalars:scalars" in r.values
                      else math.nan for r in rows], lw=1, color=track.colors[m], label=m)
        err.set_title("distance of each moving module to its goal [m]", fontsize=8)
        if track.errors:
            err.legend(fontsize=7, ncols=2, title="module", title_fontsize=7)
    for tick in ticks:
        err.axvline(track.sim_time(tick), color="0.6", lw=0.6)
    err.set_xlabel("sim time [s]", fontsize=8)
    for ax in (conn, err):
        ax.tick_params(labelsize=7)
        ax.grid(True, lw=0.3, alpha=0.5)
    if track.capsules:
        key = ("circle: node, bar: strut (its id at the middle), connector dot: green docked, "
               "orange extending, purple releasing, grey free; dashed: the running action's "
               "target")
    else:
        key = ("bold edge: heading (front), black bar: docked connection, red/blue dot: "
               "active/passive face, dashed: goal of the running action")
    title = title or track.title
    fig.suptitle(f"{title}\n{key}" if title else key, fontsize=9)
    return fig


def write_snapshot(recording: str | Path, image: str | Path, title: str = "") -> Path:
    """Render ``recording`` to the PNG ``image``, written atomically.

    Raises:
        MsrrError: unreadable recording, or matplotlib is not installed.
    """
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise MsrrError("platform snapshot needs matplotlib: pip install 'msrr-platform[plot]'"
                        ) from None
    track = load_track(recording)
    fig = render_snapshot(track, title or track.title or Path(recording).name)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png")
    return atomic_write_bytes(image, buffer.getvalue())
