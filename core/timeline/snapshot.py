"""Draw a still image of a run from its recording (no display needed).

:func:`load_track` reads the module poses, the recognized topology, the action text,
the dock/undock events and the per-module errors back from a ``run.rrd``
(:func:`msrr.core.timeline.readback.read_rows`); :func:`render_snapshot` draws them
with matplotlib (Agg): top-down footprints at the start, two intermediate ticks and
the end, plus connections and errors over time.

matplotlib is imported inside the drawing functions: it is an optional dependency
(the ``dev`` extra), and a missing one is reported as one line by
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


def _rgb(packed: int) -> tuple[float, float, float]:
    return ((packed >> 24) & 255) / 255, ((packed >> 16) & 255) / 255, ((packed >> 8) & 255) / 255


def _yaw(q: list[float]) -> float:
    x, y, z, w = q
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def _latest(rows: list[Row], tick: int) -> Row | None:
    timed = [(r.tick, r) for r in rows if r.tick is not None]
    i = bisect_right([t for t, _ in timed], tick)
    return timed[i - 1][1] if i else None


@dataclass
class Track:
    """What a snapshot needs from one recording."""

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

    @property
    def last_tick(self) -> int:
        return max(self.times) if self.times else 0

    def sim_time(self, tick: int) -> float:
        ticks = sorted(t for t in self.times if t <= tick)
        return self.times[ticks[-1]] if ticks else 0.0

    def pose(self, module: str, tick: int) -> tuple[float, float, float] | None:
        rows = self.poses.get(module, [])
        row = _latest(rows, tick) or next((r for r in rows if r.tick is not None), None)
        if row is None:
            return None
        x, y, _ = row.values["Transform3D:translation"][0]
        return x, y, _yaw(row.values["Transform3D:quaternion"][0])

    def edges(self, tick: int) -> list[tuple[str, str]]:
        row = _latest(self.topology, tick)
        if row is None:
            return []
        return [(e["first"], e["second"]) for e in row.values.get("GraphEdges:edges", [])]

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
        box = static.values if static else {}
        hx, hy, _ = (box.get("Boxes3D:half_sizes") or [[0.1, 0.1, 0.05]])[0]
        half[module] = (hx, hy)
        colors[module] = _rgb(box["Boxes3D:colors"][0]) if "Boxes3D:colors" in box else (.5,) * 3
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
    errors = {m: [r for r in rows.get(f"/errors/{m}", []) if "Scalars:scalars" in r.values]
              for m in modules}
    return Track(modules, half, colors, faces, poses, rows.get("/topology/current", []),
                 rows.get("/action", []), rows.get("/world/targets", []),
                 {m: e for m, e in errors.items() if e}, sorted(events), times)


def _pick_ticks(track: Track) -> list[int]:
    """Start, one and two thirds of the run, and the end."""
    last = track.last_tick
    start = min(track.times) if track.times else 0
    return sorted({start, start + (last - start) // 3, start + 2 * (last - start) // 3, last})


def _footprint(ax: Any, track: Track, tick: int) -> None:
    from matplotlib.patches import Polygon

    centers = {m: p for m in track.modules if (p := track.pose(m, tick)) is not None}
    target = _latest(track.targets, tick)
    if target is not None and "Boxes3D:centers" in target.values:
        hs = target.values.get("Boxes3D:half_sizes") or [[0.1, 0.1, 0.05]]
        for i, c in enumerate(target.values["Boxes3D:centers"]):
            q = target.values.get("Boxes3D:quaternions", [[0, 0, 0, 1]] * (i + 1))[i]
            h = hs[min(i, len(hs) - 1)]
            ax.add_patch(Polygon(_corners(c[0], c[1], _yaw(q), h[0], h[1]), closed=True,
                                 fill=False, ls="--", lw=1.0, ec="0.45", zorder=1))
    for a, b in track.edges(tick):  # a bar across the gap between the two bodies
        if a in centers and b in centers:
            (xa, ya, _), (xb, yb, _) = centers[a], centers[b]
            d = math.hypot(xb - xa, yb - ya) or 1.0
            ux, uy = (xb - xa) / d, (yb - ya) / d
            ra, rb = track.half[a][0] * 0.8, track.half[b][0] * 0.8
            ax.plot([xa + ux * ra, xb - ux * rb], [ya + uy * ra, yb - uy * rb],
                    color="black", lw=3, zorder=4, solid_capstyle="butt")
    for m, (x, y, yaw) in centers.items():
        hx, hy = track.half[m]
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
    times = [r.sim_time or 0.0 for r in track.topology if r.tick is not None]
    counts = [len(r.values.get("GraphEdges:edges", [])) for r in track.topology
              if r.tick is not None]
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
    for m, rows in track.errors.items():
        err.plot([r.sim_time for r in rows], [r.values["Scalars:scalars"][0] for r in rows],
                 lw=1, color=track.colors[m], label=m)
    err.set_title("distance of each moving module to its goal [m]", fontsize=8)
    err.set_xlabel("sim time [s]", fontsize=8)
    if track.errors:
        err.legend(fontsize=7, ncols=2, title="module", title_fontsize=7)
    for ax in (conn, err):
        ax.tick_params(labelsize=7)
        ax.grid(True, lw=0.3, alpha=0.5)
    key = ("bold edge: heading (front), black bar: docked connection, red/blue dot: "
           "active/passive face, dashed: goal of the running action")
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
        raise MsrrError("install matplotlib: pip install msrr-platform[dev]") from None
    track = load_track(recording)
    fig = render_snapshot(track, title or Path(recording).name)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png")
    return atomic_write_bytes(image, buffer.getvalue())
