"""Planar geometry of MMRP modules: faces, latch alignment, track kinematics (pure)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from msrr.core.alignment import wrap_angle

from ..robot import FACES

__all__ = [
    "ACTIVE_FACES",
    "FACE_NORMALS",
    "OPPOSITE",
    "Alignment",
    "alignment",
    "group_twist",
    "neighbour_pose",
    "track_speeds",
]

FACE_NORMALS: dict[str, tuple[float, float]] = {f.name: (f.normal[0], f.normal[1]) for f in FACES}
"""Outward face normal in the module frame (x forward, y left)."""

ACTIVE_FACES = frozenset(f.name for f in FACES if f.role == "active")
OPPOSITE = {"T": "B", "B": "T", "L": "R", "R": "L"}
"""The face a face docks with (T-B and L-R only)."""

Pose2 = tuple[float, float, float]


def neighbour_pose(pose: Pose2, face: str, pitch: float) -> Pose2:
    """Pose of the module docked on ``face`` of a module at ``pose`` (same heading)."""
    x, y, yaw = pose
    nx, ny = FACE_NORMALS[face]
    c, s = math.cos(yaw), math.sin(yaw)
    return (x + pitch * (c * nx - s * ny), y + pitch * (s * nx + c * ny), yaw)


@dataclass(frozen=True)
class Alignment:
    """Misalignment of a face pair, measured in the first module's face frame.

    Attributes:
        gap: centre distance along the face normal minus the pitch [m].
        lateral: offset across the face normal [m].
        yaw: heading difference [rad].
    """

    gap: float
    lateral: float
    yaw: float

    def within(self, lateral_tolerance: float, gap_tolerance: float, yaw_tolerance: float
               ) -> bool:
        return (abs(self.gap) <= gap_tolerance and abs(self.lateral) <= lateral_tolerance
                and abs(self.yaw) <= yaw_tolerance)


def alignment(pose_a: Pose2, face_a: str, pose_b: Pose2, pitch: float) -> Alignment:
    """How far module b at ``pose_b`` is from docking position on ``face_a`` of module a."""
    xa, ya, yaw_a = pose_a
    nx, ny = FACE_NORMALS[face_a]
    c, s = math.cos(yaw_a), math.sin(yaw_a)
    normal = np.array([c * nx - s * ny, s * nx + c * ny])
    across = np.array([-normal[1], normal[0]])
    d = np.array([pose_b[0] - xa, pose_b[1] - ya])
    return Alignment(float(d @ normal) - pitch, float(d @ across), wrap_angle(pose_b[2] - yaw_a))


def track_speeds(v: float, omega: float, offset_left: float, width: float) -> tuple[float, float]:
    """Left and right track speeds [m/s] of a module in a group moving with ``(v, omega)``.

    Args:
        v: forward speed of the group reference point [m/s].
        omega: yaw rate [rad/s].
        offset_left: module centre's offset to the left of the reference point [m].
        width: track separation [m].
    """
    forward = v - omega * offset_left
    return forward - omega * width / 2.0, forward + omega * width / 2.0


def group_twist(positions: np.ndarray, headings: np.ndarray, tracks: np.ndarray, width: float
                ) -> tuple[np.ndarray, float]:
    """The rigid planar velocity of a docked group from its modules' track speeds.

    Each module contributes its forward speed along its heading and its yaw rate; the
    group's yaw rate is their mean and the centroid velocity their least-squares fit.
    Tracks cannot push sideways, so the centroid's lateral velocity is removed.

    Args:
        positions: module centres [m], shape (n, 2).
        headings: module headings [rad], shape (n,).
        tracks: ``(left, right)`` speeds [m/s], shape (n, 2).
        width: track separation [m].

    Returns:
        ``(centroid velocity (2,) [m/s], yaw rate [rad/s])``.
    """
    n = len(positions)
    forward = [(left + right) / 2.0 for left, right in tracks]
    omega = sum((right - left) / width for left, right in tracks) / n
    cx = sum(float(q[0]) for q in positions) / n
    cy = sum(float(q[1]) for q in positions) / n
    vx = vy = hx = hy = 0.0
    for (px, py), yaw, f in zip(positions, headings, forward, strict=True):
        c, s = math.cos(yaw), math.sin(yaw)
        vx += f * c + omega * (py - cy)
        vy += f * s - omega * (px - cx)
        hx, hy = hx + c, hy + s
    vx, vy = vx / n, vy / n
    norm = math.hypot(hx, hy)
    if norm > 1e-9:
        hx, hy = hx / norm, hy / norm
        along = vx * hx + vy * hy
        vx, vy = along * hx, along * hy
    return np.array([vx, vy]), float(omega)
