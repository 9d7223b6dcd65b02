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

import numpy as np

from .alignment import align_yaw, angles_between, rot_z
from .configuration import Configuration
from .driver import Pose
from .errors import ConfigurationError
from .events import ShapeErrors
from .robot import ShapeTolerance

__all__ = ["fit_planar", "pose_errors", "skeletal_error", "skeletal_errors"]


def _wrap(angle: np.ndarray) -> np.ndarray:
    return (angle + np.pi) % (2 * np.pi) - np.pi


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
                 tolerance: ShapeTolerance) -> ShapeErrors:
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
    heading = np.abs(_wrap(yaw + theta - goal_yaw))
    return ShapeErrors(max_position=float(distance.max(initial=0.0)),
                       rms_position=float(np.sqrt(np.mean(distance ** 2))) if ids else 0.0,
                       max_heading=float(heading.max(initial=0.0)),
                       tolerance_position=tolerance.position,
                       tolerance_heading=tolerance.heading)


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
