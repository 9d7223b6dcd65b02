"""Rigid-body geometry of the generic runtime: module bodies, port frames, placements.

The kinematic driver and the latch controller share these pure functions. A module is
a rigid body with a planar pose: a position ``p`` [m], shape (3,), and a heading
``yaw`` [rad] about the world z axis (modules never roll or pitch in the generic
runtime). Its size comes from its :class:`~msrr.core.robot.ModuleKind`'s ``geometry``:

* a body: ``length``/``width``/``height`` (a box) or ``radius`` (a ball), read by
  :func:`msrr.core.robot.body_half_size` (default: a cube of half edge 0.05 m);
* a port sits where its kind's :class:`~msrr.core.robot.Body` puts it
  (:func:`msrr.core.bodies.port_frame`: its ``position``, else on the body along its
  normal); without a body, on the body's surface along its ``normal`` (a box face, or
  the ball's surface); with ``geometry["pitch"]`` the port sits ``pitch / 2`` from the
  centre instead, so two docked modules' centres are ``pitch`` apart (MMRP's
  latch protrudes from the body);
* a port without a normal, or a connection without ports (freeform connectors,
  FreeBOT, SnailBot), joins two bodies that touch: the target's centre is the
  source's plus ``z * (reach_source + reach_target)``, ``reach`` the distance from
  a centre to its surface along ``z``; such a contact can *slide*: the moving body
  stays on the other's surface while its direction from the other's centre turns
  (:func:`slide_toward`), which is how a flow's leaf reaches a neighbour of its
  parent (:func:`touching_direction`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import bodies
from ..errors import ExecutionError
from ..robot import ModuleKind, body_half_size

__all__ = [
    "BodyPose",
    "contact_distance",
    "contact_reach",
    "inscribed_radius",
    "place_for_contact",
    "place_for_ports",
    "port_frame",
    "rotate_z",
    "slide_toward",
    "touching_direction",
    "wrap_angle",
]


@dataclass(frozen=True)
class BodyPose:
    """A planar rigid pose: ``position`` [m], shape (3,), heading ``yaw`` [rad]."""

    position: np.ndarray
    yaw: float = 0.0


def wrap_angle(angle: float) -> float:
    """``angle`` [rad] wrapped into (-pi, pi]."""
    wrapped = math.remainder(angle, 2 * math.pi)
    return math.pi if wrapped == -math.pi else wrapped


def rotate_z(vector: np.ndarray, yaw: float) -> np.ndarray:
    """``vector``, shape (3,), turned by ``yaw`` [rad] about the world z axis."""
    c, s = math.cos(yaw), math.sin(yaw)
    x, y, z = (float(v) for v in vector)
    return np.array([c * x - s * y, s * x + c * y, z])


def contact_reach(kind: ModuleKind, direction: np.ndarray) -> float:
    """Distance [m] from the centre of ``kind``'s body to its surface along the unit
    ``direction`` (in the body frame): a ball's radius, or where the ray leaves the box."""
    g = kind.geometry
    if "radius" in g and not ("length" in g or "width" in g or "height" in g):
        return float(g["radius"])
    half = np.array(body_half_size(kind))
    d = np.abs(np.asarray(direction, dtype=float))
    return float(1.0 / max(d[i] / half[i] for i in range(3) if half[i] > 0))


def inscribed_radius(kind: ModuleKind) -> float:
    """Radius [m] of the largest ball inside ``kind``'s body (the collision check's)."""
    return float(min(body_half_size(kind)))


def _port_offset(kind: ModuleKind, port: str) -> tuple[np.ndarray, np.ndarray] | None:
    """Port position and outward normal in the body frame, or ``None`` (no normal)."""
    spec = kind.port(port)
    if spec.normal is None:
        return None
    if kind.body is not None:  # a described body: the port's own pose (msrr.core.bodies)
        rotation, position = bodies.port_frame(kind, port)
        return position, rotation[:, 0]
    normal = np.asarray(spec.normal, dtype=float)
    normal = normal / np.linalg.norm(normal)
    if "pitch" in kind.geometry:
        return normal * float(kind.geometry["pitch"]) / 2, normal
    return normal * contact_reach(kind, normal), normal


def port_frame(kind: ModuleKind, port: str, pose: BodyPose
               ) -> tuple[np.ndarray, np.ndarray] | None:
    """World position [m] and outward unit normal of ``port`` of a body at ``pose``;
    ``None`` when the port has no normal (it docks by contact)."""
    local = _port_offset(kind, port)
    if local is None:
        return None
    offset, normal = local
    return pose.position + rotate_z(offset, pose.yaw), rotate_z(normal, pose.yaw)


def place_for_ports(fixed_kind: ModuleKind, fixed_port: str, fixed: BodyPose,
                    moving_kind: ModuleKind, moving_port: str, moving_yaw: float) -> BodyPose:
    """The pose of the moving body that puts its ``moving_port`` onto ``fixed_port``,
    normals opposite, turning only about z.

    Two horizontal normals fix the heading; two vertical ones (opposite) keep
    ``moving_yaw``.

    Raises:
        ExecutionError: a port has no normal, or no heading makes the normals opposite.
    """
    at = port_frame(fixed_kind, fixed_port, fixed)
    local = _port_offset(moving_kind, moving_port)
    if at is None or local is None:
        raise ExecutionError(f"ports {fixed_port!r} and {moving_port!r}: a port without a normal "
                             "docks by contact (see place_for_contact)")
    position, normal = at
    offset, moving_normal = local
    want = -normal
    horizontal = math.hypot(want[0], want[1])
    if horizontal > 1e-9 and math.hypot(moving_normal[0], moving_normal[1]) > 1e-9:
        yaw = wrap_angle(math.atan2(want[1], want[0])
                         - math.atan2(moving_normal[1], moving_normal[0]))
    else:
        yaw = moving_yaw
    if float(rotate_z(moving_normal, yaw) @ want) < 1 - 1e-6:
        raise ExecutionError(f"port {moving_port!r} of a {moving_kind.name} cannot face port "
                             f"{fixed_port!r} of a {fixed_kind.name} by turning about z")
    return BodyPose(position - rotate_z(offset, yaw), yaw)


def contact_distance(fixed_kind: ModuleKind, fixed_yaw: float, moving_kind: ModuleKind,
                     moving_yaw: float, direction: np.ndarray) -> float:
    """Distance [m] between the centres of two bodies that touch along the unit
    ``direction`` (world frame, from the fixed body's centre to the moving one's)."""
    return (contact_reach(fixed_kind, rotate_z(direction, -fixed_yaw))
            + contact_reach(moving_kind, rotate_z(-direction, -moving_yaw)))


def place_for_contact(fixed_kind: ModuleKind, fixed: BodyPose, moving_kind: ModuleKind,
                      moving_yaw: float, z: np.ndarray, fixed_is_source: bool) -> BodyPose:
    """The pose of the moving body that touches the fixed one along the connection
    vector ``z`` (unit, world frame, pointing from the source to the target)."""
    direction = np.asarray(z, dtype=float) / np.linalg.norm(z)
    toward_moving = direction if fixed_is_source else -direction
    distance = contact_distance(fixed_kind, fixed.yaw, moving_kind, moving_yaw, toward_moving)
    return BodyPose(fixed.position + toward_moving * distance, moving_yaw)


def slide_toward(direction: np.ndarray, goal: np.ndarray, max_angle: float) -> np.ndarray:
    """``direction`` (unit, shape (3,)) turned toward ``goal`` (unit) along their great
    circle by at most ``max_angle`` [rad]; exactly ``goal`` once within it. Opposite
    directions turn about a horizontal axis (over the top), or about y when vertical."""
    u = np.asarray(direction, dtype=float)
    g = np.asarray(goal, dtype=float)
    angle = math.acos(max(-1.0, min(1.0, float(u @ g))))
    if angle <= max_angle:
        return g.copy()
    axis = np.cross(u, g)
    if float(np.linalg.norm(axis)) < 1e-9:
        axis = np.cross(u, np.array([0.0, 0.0, 1.0]))
        if float(np.linalg.norm(axis)) < 1e-9:
            axis = np.array([0.0, 1.0, 0.0])
    axis = axis / np.linalg.norm(axis)
    c, s = math.cos(max_angle), math.sin(max_angle)
    turned = u * c + np.cross(axis, u) * s + axis * float(axis @ u) * (1 - c)
    return turned / np.linalg.norm(turned)


def touching_direction(parent_kind: ModuleKind, parent: BodyPose, leaf_kind: ModuleKind,
                       leaf_yaw: float, other_kind: ModuleKind, other: BodyPose,
                       side: np.ndarray) -> np.ndarray | None:
    """Where on ``parent`` a leaf touching it also touches ``other``: the unit direction
    ``d`` from the parent's centre, in the plane of ``e1`` (toward ``other``'s centre) and
    ``side`` (a unit vector normal to ``e1``), on ``side``'s half, with
    ``|p + d * contact_distance(d) - o| = contact_distance`` of leaf and other.

    Found by bisection on the angle from ``e1`` (the gap to ``other`` grows with it);
    ``None`` when the leaf cannot touch both (``other`` too far from ``parent``).
    """
    e1 = other.position - parent.position
    e1 = e1 / np.linalg.norm(e1)
    e2 = np.asarray(side, dtype=float)

    def gap(theta: float) -> float:
        d = math.cos(theta) * e1 + math.sin(theta) * e2
        leaf = parent.position + d * contact_distance(parent_kind, parent.yaw, leaf_kind,
                                                      leaf_yaw, d)
        between = leaf - other.position
        span = float(np.linalg.norm(between))
        if span < 1e-12:
            return -1.0
        return span - contact_distance(other_kind, other.yaw, leaf_kind, leaf_yaw,
                                       between / span)

    low, high = 0.0, math.pi
    if gap(low) > 0 or gap(high) < 0:
        return None
    for _ in range(60):
        mid = 0.5 * (low + high)
        if gap(mid) < 0:
            low = mid
        else:
            high = mid
    return math.cos(high) * e1 + math.sin(high) * e2
