"""Judging a shape: module poses against the goal layout, or skeletal vectors against
the goal's (the FreeSN paper's eq. 8 alignment).

:func:`skeletal_errors` compares the connection vectors ``z`` of two configurations
after the yaw that aligns them best: the measure of the executor's reaching test, the
library check and the freeform robots' runs.

A run reaches the goal *shape* when, after the planar rigid motion (rotation about z and
translation) that best fits the final module positions onto the goal layout, every
module is within the robot's shape tolerance in position and heading. The robot
declares the tolerance in its spec defaults, as a typed
:class:`~msrr.core.robot.ShapeTolerance` (validated when the plugin loads: each bound a
finite number > 0)::

    defaults=RobotDefaults(shape_tolerance=ShapeTolerance(position=0.03, heading=0.1))

``position`` is the largest position error of a module [m] and ``heading`` its largest
heading error about z [rad]; a robot without one (``shape_tolerance=None``, the
default) is judged on its topology alone.

The goal layout is where the robot's own driver places the goal configuration at
``reset`` (``platform run`` builds a second driver for it), so the comparison uses the
simulator's geometry (MMRP: the 0.30 m docking pitch), not a guess of it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Literal

import numpy as np

from .alignment import align_yaw, angles_between, rot_z, wrap_angle
from .configuration import Configuration
from .driver import Pose
from .errors import ConfigurationError
from .robot import ShapeTolerance

__all__ = ["ShapeVerdict", "fit_planar", "pose_errors", "skeletal_error", "skeletal_errors",
           "skeletal_verdict"]


@dataclass(frozen=True)
class ShapeVerdict:
    """How far a shape is from its goal: the one shape figure of a judged goal.

    Attributes:
        metric: ``"poses"`` (module poses against the goal layout, after the planar
            fit) or ``"skeletal"`` (connection vectors, eq. 8).
        error: the largest module position error [m] (poses) or the RMS angle [rad]
            between connection vectors after yaw alignment (skeletal).
        tolerance: the bound ``error`` must be within, same unit.
        heading: the largest module heading error [rad] (poses only).
        heading_tolerance: its bound [rad] (poses only).
        rms: the RMS of the module position errors [m] (poses only; a detail of the
            same figure, for sweeps' statistics).
    """

    metric: Literal["poses", "skeletal"]
    error: float
    tolerance: float
    heading: float | None = None
    heading_tolerance: float | None = None
    rms: float | None = None

    @property
    def within(self) -> bool:
        """Within every bound."""
        return self.error <= self.tolerance and (
            self.heading is None or self.heading_tolerance is None
            or self.heading <= self.heading_tolerance)

    def __str__(self) -> str:
        if self.metric == "skeletal":
            return (f"{math.degrees(self.error):.2f} deg RMS between connection vectors "
                    f"(tolerance {math.degrees(self.tolerance):g} deg)")
        return (f"position error up to {self.error:.3g} m (tolerance {self.tolerance:g}), "
                f"heading error up to {self.heading or 0.0:.3g} rad (tolerance "
                f"{self.heading_tolerance:g})")

    def summary(self) -> dict[str, object]:
        """JSON-ready (``summary.json``)."""
        if self.metric == "skeletal":
            return {"metric": "skeletal", "error_deg": round(math.degrees(self.error), 3),
                    "tolerance_deg": round(math.degrees(self.tolerance), 3),
                    "within": self.within}
        return {"metric": "poses", "max_position_error_m": round(self.error, 4),
                "rms_position_error_m": round(self.rms or 0.0, 4),
                "position_tolerance_m": self.tolerance,
                "max_heading_error_rad": round(self.heading or 0.0, 4),
                "heading_tolerance_rad": self.heading_tolerance, "within": self.within}


def fit_planar(points: np.ndarray, goal: np.ndarray, headings: np.ndarray | None = None,
               goal_headings: np.ndarray | None = None) -> tuple[float, np.ndarray]:
    """The rotation about z and translation that best map ``points`` onto ``goal``.

    Least squares in the plane (2-D Kabsch/Procrustes): with centred points ``p_i`` and
    ``q_i``, ``theta = atan2(sum p_i x q_i, sum p_i . q_i)`` and ``t = mean(q) - R mean(p)``.
    When the points carry no direction (one module, or all at one place) the circular
    mean of the heading differences fixes ``theta``.

    Args:
        points: final positions, shape (n, 2) [m].
        goal: goal positions, shape (n, 2) [m].
        headings: final headings, shape (n,) [rad] (only for the degenerate case).
        goal_headings: goal headings, shape (n,) [rad].

    Returns:
        ``(theta [rad], t [m] shape (2,))`` with ``goal ~ R(theta) points + t``.
    """
    p = points - points.mean(axis=0)
    q = goal - goal.mean(axis=0)
    cross = float(np.sum(p[:, 0] * q[:, 1] - p[:, 1] * q[:, 0]))
    dot = float(np.sum(p * q))
    if math.hypot(cross, dot) > 1e-12:
        theta = math.atan2(cross, dot)
    elif headings is not None and goal_headings is not None and len(headings):
        diff = goal_headings - headings
        theta = math.atan2(float(np.mean(np.sin(diff))), float(np.mean(np.cos(diff))))
    else:
        theta = 0.0
    c, s = math.cos(theta), math.sin(theta)
    rotation = np.array([[c, -s], [s, c]])
    return theta, goal.mean(axis=0) - rotation @ points.mean(axis=0)


def pose_errors(final: Mapping[str, Pose], goal: Mapping[str, Pose],
                 tolerance: ShapeTolerance) -> ShapeVerdict:
    """Per-module position and heading errors of ``final`` against ``goal`` after
    :func:`fit_planar` (planar: x, y and heading about z).

    Args:
        final: final pose of every module.
        goal: goal layout, same module ids.
        tolerance: the bounds ``within`` compares with (position [m], heading [rad]).

    Raises:
        ConfigurationError: the two name different modules.
    """
    if set(final) != set(goal):
        raise ConfigurationError(f"final modules {sorted(final)} differ from the goal "
                                 f"layout's {sorted(goal)}")
    ids = sorted(final)
    p = np.array([final[m].position[:2] for m in ids], dtype=float).reshape(-1, 2)
    q = np.array([goal[m].position[:2] for m in ids], dtype=float).reshape(-1, 2)
    yaw = np.array([final[m].yaw for m in ids])
    goal_yaw = np.array([goal[m].yaw for m in ids])
    theta, t = fit_planar(p, q, yaw, goal_yaw)
    c, s = math.cos(theta), math.sin(theta)
    moved = p @ np.array([[c, -s], [s, c]]).T + t
    distance = np.linalg.norm(moved - q, axis=1)
    heading = np.abs(wrap_angle(yaw + theta - goal_yaw))
    return ShapeVerdict("poses", float(distance.max(initial=0.0)), tolerance.position,
                        float(heading.max(initial=0.0)), tolerance.heading,
                        float(np.sqrt(np.mean(distance ** 2))) if ids else 0.0)


def skeletal_errors(current: Configuration, goal: Configuration
                 ) -> tuple[float, np.ndarray, float]:
    """The angles [rad] between the ``z`` of the edges both have, after yaw alignment
    (eq. 8): ``(rms, per-edge angles (n,) in the goal's edge order, yaw)``, ``yaw`` [rad]
    the turn of ``goal`` onto ``current``; ``(0, [], 0)`` when they share no edge with a
    vector (robots without connection vectors)."""
    have = {e.id for e in current.edges() if e.z is not None}
    ids = [e.id for e in goal.edges() if e.id in have and e.z is not None]
    if not ids:
        return 0.0, np.zeros(0), 0.0
    z, z_goal = current.vectors(ids), goal.vectors(ids)
    yaw = align_yaw(z, z_goal).theta
    angles = angles_between(z, rot_z(yaw) @ z_goal)
    return float(np.sqrt(np.mean(angles**2))), angles, float(yaw)


def skeletal_error(current: Configuration, goal: Configuration) -> float:
    """RMS angle [rad] between the ``z`` of the edges both have, after yaw alignment (eq. 8);
    0 when they share no edge with a vector (see :func:`skeletal_errors`)."""
    return skeletal_errors(current, goal)[0]


def skeletal_verdict(current: Configuration, goal: Configuration,
                     tolerance: float) -> ShapeVerdict | None:
    """:func:`skeletal_error` against ``tolerance`` [rad], or ``None`` when there is nothing
    to compare: ``goal`` has no connection vector, or ``current`` none on an edge both have
    (a driver that reports no vectors measures no shape; it is never called 0)."""
    have = {e.id for e in current.edges() if e.z is not None}
    if not any(e.z is not None and e.id in have for e in goal.edges()):
        return None
    return ShapeVerdict("skeletal", skeletal_error(current, goal), tolerance)
