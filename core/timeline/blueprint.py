"""The default viewer layout of a run recording."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import rerun.blueprint as rrb

from ..events import Run

__all__ = ["build_blueprint", "camera_eye"]


def camera_eye(points: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """``(eye position, look target)`` [m] that frame ``points`` (module positions,
    each shape (3,)): the centre of their bounding box seen from the front right,
    above (43 deg down), 1.8 box diagonals away."""
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    low, high = p.min(axis=0), p.max(axis=0)
    centre = (low + high) / 2
    size = max(float(np.linalg.norm(high - low)), 0.3)
    direction = np.array([0.7, -1.2, 1.3]) / np.linalg.norm([0.7, -1.2, 1.3])
    return centre + 1.8 * size * direction, centre


def _graph(name: str, origin: str) -> rrb.GraphView:
    """A graph view that draws the logged node positions as they are (no forces)."""
    off = {"enabled": False}
    return rrb.GraphView(
        name=name, origin=origin,
        force_link=rrb.archetypes.ForceLink(**off),
        force_many_body=rrb.archetypes.ForceManyBody(**off),
        force_position=rrb.archetypes.ForcePosition(**off),
        force_collision_radius=rrb.archetypes.ForceCollisionRadius(**off),
        force_center=rrb.archetypes.ForceCenter(**off))


def build_blueprint(run: Run | None = None, *,
                    eye: tuple[np.ndarray, np.ndarray] | None = None, planar: bool = False,
                    shape: bool = False, extra: Sequence[object] = ()) -> rrb.Blueprint:
    """3-D world (and, for a planar robot, a top-down 2-D view) and the topology graphs
    on top; action, events and plots below.

    Args:
        run: the run (its robot and scenario name the world view).
        eye: ``(position, look target)`` [m] of the 3-D camera (:func:`camera_eye`).
        planar: add the top-down 2-D view (``top/...``).
        shape: add the plot of ``shape/angle`` (robots with connection vectors).
        extra: views plugins add (``msrr_timeline_views``), put among the plot tabs.
    """
    title = f"{run.robot}: {run.scenario}" if run is not None else "World"
    controls = None
    if eye is not None:
        controls = rrb.archetypes.EyeControls3D(position=eye[0], look_target=eye[1],
                                                eye_up=(0.0, 0.0, 1.0))
    world = rrb.Spatial3DView(name=title, origin="world", eye_controls=controls)
    scene = (rrb.Horizontal(world, rrb.Spatial2DView(name="Top view (y up)", origin="top"))
             if planar else world)
    plots: list[object] = [
        rrb.TimeSeriesView(name="Commands", origin="commands"),
        rrb.TimeSeriesView(name="Controller errors", origin="errors"),
        rrb.TimeSeriesView(name="Docked connections", origin="topology",  # flows: diamonds
                           contents=["$origin/connections", "$origin/flows"]),
    ]
    if shape:
        plots.insert(0, rrb.TimeSeriesView(name="Angle to target [deg]", origin="shape"))
    plots += list(extra)
    plots += [rrb.TextDocumentView(name="Plan", origin="plan"),
              rrb.TextDocumentView(name="Mapping", origin="mapping")]
    return rrb.Blueprint(
        rrb.Vertical(
            rrb.Horizontal(
                scene,
                rrb.Vertical(_graph("Current topology", "topology/current"),
                             _graph("Target topology", "topology/target")),
                column_shares=[4 if planar else 3, 2],
            ),
            rrb.Horizontal(
                rrb.Vertical(
                    rrb.TextDocumentView(name="Action", origin="action"),
                    rrb.TextLogView(name="Events", origin="events"),
                    row_shares=[1, 2],
                ),
                rrb.Tabs(*plots),
                column_shares=[2, 3],
            ),
            row_shares=[3, 2],
        ),
        collapse_panels=True,
    )
