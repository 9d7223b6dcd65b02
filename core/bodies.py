"""Rigid geometry of described modules: port frames, docked poses, vectors and checks.

A module kind with a :class:`~msrr.core.robot.Body` is a rigid body in its own frame
(x forward, z up); each port has a frame on it: origin at the port's ``position``,
axes ``(normal, up x normal, up)`` (:func:`port_frame`). Two docked ports coincide
with their normals opposite and their ``up`` vectors equal: the second module's frame
is the first's port frame turned by pi about ``up`` (:func:`docked_pose`). A port with
a :class:`~msrr.core.robot.Hinge` adds a turn by the joint angle about the hinge axis
through the port.

From these the core lays out a configuration (:func:`layout`), derives the connection
vectors ``z`` (unit, from the source module's centre to the target's) and ``x`` (the
source port's ``up``, made perpendicular to ``z``) that a lattice robot never writes
(:func:`with_port_vectors`; loops through hinges folded shut by :func:`close_loops`,
from small positive angles), and checks that a configuration of rigid ports is
consistent (:func:`geometry_problems`: every loop closes, no two bodies overlap).

Pure functions on numpy; module kinds and configurations are read by attribute only.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .configuration import Configuration
    from .robot import Body, ModuleKind, PortSpec, RobotSpec

__all__ = ["Frame", "body_reach", "close_loops", "connection_hinge", "docked_pose", "frame_of",
           "even_bend", "has_bodies", "hinge_angle", "hinge_edges", "port_mismatch", "vector_angles",
           "geometry_problems", "inscribed", "layout", "port_frame", "rotation_about",
           "with_port_vectors"]

Frame = tuple[np.ndarray, np.ndarray]
"""A rigid pose: rotation (3, 3) and translation [m] (3,)."""

FLIP = np.diag([-1.0, -1.0, 1.0])
"""A port frame turned by pi about its ``up`` axis: the frame of the port docked to it."""

UNBENT = 0.1
"""The hinge angle [rad] a loop starts folding from (the positive way) when nothing
says which way it folds."""

LOOP_TOLERANCE = 1e-3
"""Largest gap [m] (and angle [rad]) of a closed loop of rigid ports that still closes."""


def rotation_about(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation matrix (3, 3) by ``angle`` [rad] about the unit ``axis`` (Rodrigues)."""
    a = np.asarray(axis, dtype=float)
    k = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)


def has_bodies(spec: RobotSpec) -> bool:
    """Whether every vertex kind of ``spec`` declares a body (physics from description)."""
    kinds = [k for k in spec.module_kinds if k.role == "vertex"]
    return bool(kinds) and all(k.body is not None for k in kinds)


def _sdf(body: Body, point: np.ndarray) -> float:
    """Signed distance [m] of ``point`` (module frame) to ``body``'s surface."""
    if body.shape == "box":
        q = np.abs(point) - np.asarray(body.size) / 2
        return float(np.linalg.norm(np.maximum(q, 0.0)) + min(max(q[0], q[1], q[2]), 0.0))
    r = body.size[0]
    if body.shape == "sphere":
        return float(np.linalg.norm(point)) - r
    half = body.size[1] / 2
    if body.shape == "capsule":
        along = min(max(float(point[0]), -half), half)
        return float(np.linalg.norm(point - np.array([along, 0.0, 0.0]))) - r
    d = np.array([float(np.hypot(point[1], point[2])) - r, abs(float(point[0])) - half])
    return float(np.linalg.norm(np.maximum(d, 0.0)) + min(max(d[0], d[1]), 0.0))


def body_reach(kind: ModuleKind, direction: np.ndarray) -> float:
    """Distance [m] from the centre of ``kind``'s body to its surface along the unit
    ``direction`` (module frame), by bisection on the body's signed distance."""
    return _reach(kind.body, direction)


def _reach(body: Body | None, direction: np.ndarray) -> float:
    if body is None:
        raise ValueError("a port without a position needs the module kind's body")
    d = np.asarray(direction, dtype=float)
    low, high = 0.0, 2.0 * float(np.linalg.norm(body.half_extents)) + 1e-9
    for _ in range(60):
        mid = 0.5 * (low + high)
        if _sdf(body, mid * d) < 0:
            low = mid
        else:
            high = mid
    return high


def inscribed(kind: ModuleKind) -> float:
    """Radius [m] of the largest ball about the centre inside ``kind``'s body."""
    body = kind.body
    if body is None:
        return 0.0
    return float(min(body.half_extents))


def port_frame(kind: ModuleKind, port: str) -> Frame:
    """The frame of ``port`` in ``kind``'s module frame: rotation (3, 3) with columns
    ``(normal, up x normal, up)``, and the port's position [m] (3,), both read-only.

    A port without ``position`` sits where its normal leaves the body; one without
    ``up`` takes the module's z (else x) made perpendicular to its normal."""
    return _port_frame(kind.port(port), kind.body)


@lru_cache(maxsize=4096)
def _port_frame(spec: PortSpec, body: Body | None) -> Frame:
    """:func:`port_frame` of one port on one body: computed once (a servo reads it at
    every period), the arrays read-only since they are shared."""
    n = np.asarray(spec.normal, dtype=float)
    if spec.up is not None:
        up = np.asarray(spec.up, dtype=float)
    else:
        base = np.array([0.0, 0.0, 1.0]) if abs(n[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
        up = base - float(base @ n) * n
        up /= np.linalg.norm(up)
    position = (np.asarray(spec.position, dtype=float) if spec.position is not None
                else n * _reach(body, n))
    rotation = np.column_stack([n, np.cross(up, n), up])
    rotation.flags.writeable = position.flags.writeable = False
    return rotation, position


def connection_hinge(kinds: tuple[ModuleKind, ModuleKind], ports: tuple[str, str]
                     ) -> np.ndarray | None:
    """The hinge axis of a connection from ``ports[0]`` of ``kinds[0]`` to ``ports[1]`` of
    ``kinds[1]``, unit, in the frame of ``ports[0]``; ``None`` when it is rigid."""
    (ka, kb), (pa, pb) = kinds, ports
    if ka.hinge is not None and ka.hinge.port == pa:
        return port_frame(ka, pa)[0].T @ np.asarray(ka.hinge.axis)
    if kb.hinge is not None and kb.hinge.port == pb:
        return FLIP @ port_frame(kb, pb)[0].T @ np.asarray(kb.hinge.axis)
    return None


def docked_pose(kinds: tuple[ModuleKind, ModuleKind], ports: tuple[str, str],
                angle: float = 0.0) -> Frame:
    """The pose of the second module in the first's frame when their ports are docked;
    a hinge connection turned by ``angle`` [rad] about its axis."""
    (ra, pa), (rb, pb) = port_frame(kinds[0], ports[0]), port_frame(kinds[1], ports[1])
    axis = connection_hinge(kinds, ports)
    turn = np.eye(3) if axis is None or not angle else rotation_about(axis, angle)
    rotation = ra @ turn @ FLIP @ rb.T
    return rotation, pa - rotation @ pb


def hinge_angle(relative: np.ndarray, kinds: tuple[ModuleKind, ModuleKind],
                ports: tuple[str, str]) -> float:
    """The angle [rad] of a hinge connection whose target body is turned by ``relative``
    (3, 3) in its source's frame: the turn about the hinge axis that
    :func:`docked_pose` would need."""
    ra, rb = port_frame(kinds[0], ports[0])[0], port_frame(kinds[1], ports[1])[0]
    axis = connection_hinge(kinds, ports)
    turn = ra.T @ relative @ rb @ FLIP.T
    sine = 0.5 * np.array([turn[2, 1] - turn[1, 2], turn[0, 2] - turn[2, 0],
                           turn[1, 0] - turn[0, 1]])
    return math.atan2(float(sine @ axis), (float(np.trace(turn)) - 1.0) / 2.0)


def frame_of(parent: Frame, relative: Frame) -> Frame:
    """``relative`` (in ``parent``'s frame) in the world."""
    return parent[0] @ relative[0], parent[0] @ relative[1] + parent[1]


def _kinds(config: Configuration, spec: RobotSpec, edge: object) -> tuple:
    return spec.kind(config.kind_of(edge.source)), spec.kind(config.kind_of(edge.target))


def layout(config: Configuration, spec: RobotSpec, angles: Mapping[str, float] | None = None,
           *, roots: Mapping[str, Frame] | None = None) -> tuple[dict[str, Frame], list[str]]:
    """Module poses from docked ports: each connected group from its first module, at the
    origin (or ``roots[module]``), along a breadth-first tree of its connections.

    Args:
        config: vertex modules joined by connections with ports (others are skipped).
        spec: the robot; every kind involved has a body.
        angles: hinge angle [rad] by connection id (missing: 0).
        roots: the pose of a group's first module.

    Returns:
        The pose of every module reached, and the ids of connections not in the trees
        (they close loops).
    """
    angles = angles or {}
    roots = roots or {}
    poses: dict[str, Frame] = {}
    closing: list[str] = []
    tree: set[str] = set()
    adjacent: dict[str, list] = {v: [] for v in config.vertices(virtual=False)}
    for edge in config.edges():
        if edge.ports is not None and edge.source in adjacent and edge.target in adjacent:
            adjacent[edge.source].append(edge)
            adjacent[edge.target].append(edge)
    for start in adjacent:
        if start in poses:
            continue
        poses[start] = roots.get(start, (np.eye(3), np.zeros(3)))
        queue = [start]
        while queue:
            here = queue.pop(0)
            for edge in adjacent[here]:
                if edge.id in tree:
                    continue
                other = edge.target if edge.source == here else edge.source
                if other in poses:
                    if edge.id not in closing:
                        closing.append(edge.id)
                    continue
                rel = docked_pose(_kinds(config, spec, edge), edge.ports,
                                  float(angles.get(edge.id, 0.0)))
                if edge.source != here:
                    rel = (rel[0].T, -rel[0].T @ rel[1])
                poses[other] = frame_of(poses[here], rel)
                tree.add(edge.id)
                queue.append(other)
    return poses, closing


def with_port_vectors(config: Configuration, spec: RobotSpec) -> Configuration:
    """``config`` with ``z`` and ``x`` derived from port poses (hinges at 0) on every
    connection with ports that has no ``z`` (see the module docstring); itself when the
    robot declares no bodies or nothing is missing."""
    if not has_bodies(spec) or all(e.z is not None or e.ports is None for e in config.edges()):
        return config
    poses, closing = layout(config, spec)
    if closing and hinge_edges(config, spec):  # hinges close the loops: fold them shut
        edges = [config.edge(e) for e in closing]
        pairs = [(e.source, e.ports[0], e.target, e.ports[1]) for e in edges]
        angles, _ = close_loops(config, spec, pairs, even_bend(config, spec, pairs))
        poses, _ = layout(config, spec, angles)
    z: dict[str, np.ndarray | None] = {}
    x: dict[str, np.ndarray | None] = {}
    for edge in config.edges():
        z[edge.id], x[edge.id] = edge.z, edge.x
        if edge.z is not None or edge.source not in poses or edge.target not in poses:
            continue
        between = poses[edge.target][1] - poses[edge.source][1]
        zz = between / np.linalg.norm(between)
        rotation, _ = port_frame(spec.kind(config.kind_of(edge.source)), edge.ports[0])
        up = poses[edge.source][0] @ rotation[:, 2]
        xx = up - float(up @ zz) * zz
        z[edge.id] = zz
        x[edge.id] = xx / np.linalg.norm(xx) if np.linalg.norm(xx) > 1e-9 else None
    return config.derive(z=z, x=x)


def geometry_problems(config: Configuration, spec: RobotSpec) -> list[tuple[str, str]]:
    """Where a configuration of described bodies is not geometrically consistent, as
    ``(where, message)`` pairs (:class:`~msrr.core.robot.Violation` fields): a loop
    of rigid ports that does not close (the closing ports more than
    :data:`LOOP_TOLERANCE` apart or turned), or two bodies that overlap (their inscribed
    balls intersect). Loops through a hinge are not checked (their angles close them).
    Empty when the robot declares no bodies."""
    if not has_bodies(spec):
        return []
    poses, closing = layout(config, spec)
    found = []
    edges = {e.id: e for e in config.edges()}
    hinged = any(connection_hinge(_kinds(config, spec, e), e.ports) is not None
                 for e in edges.values() if e.ports is not None)
    for edge_id in [] if hinged else closing:
        edge = edges[edge_id]
        kinds = _kinds(config, spec, edge)
        want = frame_of(poses[edge.source], docked_pose(kinds, edge.ports))
        have = poses[edge.target]
        gap = float(np.linalg.norm(want[1] - have[1]))
        turn = math.acos(max(-1.0, min(1.0, (float(np.trace(want[0].T @ have[0])) - 1) / 2)))
        if gap > LOOP_TOLERANCE or turn > LOOP_TOLERANCE:
            found.append((f"connection {edge_id}", f"the loop does not close: its ports are "
                          f"{gap:.3g} m apart and turned {math.degrees(turn):.1f} deg from docked"))
    modules = sorted(poses)
    for i, a in enumerate(modules):
        for b in modules[i + 1:]:
            limit = inscribed(spec.kind(config.kind_of(a))) + inscribed(
                spec.kind(config.kind_of(b)))
            if float(np.linalg.norm(poses[a][1] - poses[b][1])) < limit - 1e-9:
                found.append((f"module {a}", f"overlaps module {b} where the ports place them"))
    return found


def hinge_edges(config: Configuration, spec: RobotSpec) -> list[str]:
    """Ids of the connections of ``config`` that are hinges (see :func:`connection_hinge`)."""
    if not has_bodies(spec):
        return []
    return [e.id for e in config.edges() if e.ports is not None
            and connection_hinge(_kinds(config, spec, e), e.ports) is not None]


def vector_angles(config: Configuration, spec: RobotSpec) -> dict[str, float]:
    """The hinge angles [rad] that lay ``config`` out with its connections' ``z`` vectors
    (least squares over the angles and a yaw, each hinge within its limit); empty when
    it has no hinge or no vector."""
    from scipy.optimize import least_squares  # only where hinges are laid out

    hinges = hinge_edges(config, spec)
    given = [e for e in config.edges() if e.z is not None and e.ports is not None]
    if not hinges or not given:
        return {}
    limits = []
    for edge_id in hinges:
        edge = config.edge(edge_id)
        ka, kb = _kinds(config, spec, edge)
        hinge = ka.hinge if ka.hinge is not None and ka.hinge.port == edge.ports[0] else kb.hinge
        limits.append(hinge.limit)
    want = np.array([e.z for e in given], dtype=float)

    def residual(values: np.ndarray) -> np.ndarray:
        poses, _ = layout(config, spec, dict(zip(hinges, values[1:], strict=True)))
        turn = rotation_about(np.array([0.0, 0.0, 1.0]), float(values[0]))
        out = []
        for edge, z in zip(given, want, strict=True):
            between = poses[edge.target][1] - poses[edge.source][1]
            out.append(turn @ (between / np.linalg.norm(between)) - z)
        return np.concatenate(out)

    bound = np.array([math.pi * 4, *limits])
    fit = least_squares(residual, np.zeros(len(hinges) + 1), bounds=(-bound, bound))
    angles = dict(zip(hinges, (float(v) for v in fit.x[1:]), strict=True))
    poses, closing = layout(config, spec, angles)
    for edge_id in set(closing) & set(hinges):  # a loop's last hinge: as the layout has it
        edge = config.edge(edge_id)
        angles[edge_id] = hinge_angle(poses[edge.source][0].T @ poses[edge.target][0],
                                      _kinds(config, spec, edge), edge.ports)
    return angles


def port_mismatch(source: Frame, target: Frame, kinds: tuple[ModuleKind, ModuleKind],
                  ports: tuple[str, str]) -> tuple[np.ndarray, np.ndarray]:
    """How far two modules at ``source`` and ``target`` (world poses) are from docking
    their ``ports``: the gap between the port positions [m] (3,), and the rotation
    mismatch: of the hinge axes for a hinge (3,), of the whole docked pose for rigid
    ports (9,)."""
    ra, pa = port_frame(kinds[0], ports[0])
    rb, pb = port_frame(kinds[1], ports[1])
    gap = (target[0] @ pb + target[1]) - (source[0] @ pa + source[1])
    axis = connection_hinge(kinds, ports)
    if axis is None:
        want = source[0] @ docked_pose(kinds, ports)[0]
        return gap, (target[0] - want).ravel()
    return gap, target[0] @ rb @ FLIP.T @ axis - source[0] @ ra @ axis


Closing = tuple[str, str, str, str]
"""A port pair to bring together: source module, its port, target module, its port."""


def _hinge_limit(config: Configuration, spec: RobotSpec, edge_id: str) -> float:
    edge = config.edge(edge_id)
    ka, kb = _kinds(config, spec, edge)
    hinge = ka.hinge if ka.hinge is not None and ka.hinge.port == edge.ports[0] else kb.hinge
    return hinge.limit


def even_bend(config: Configuration, spec: RobotSpec, closing: list[Closing],
              steps: int = 64) -> dict[str, float]:
    """One angle [rad] for every hinge of ``config`` -- of ``steps`` from :data:`UNBENT`
    to the smallest hinge limit, the positive way -- whose layout brings the ports of
    ``closing`` closest: where :func:`close_loops` starts folding a loop, so that a ring
    of like hinges folds evenly (a regular polygon) rather than at whichever hinge least
    squares reaches first."""
    hinges = hinge_edges(config, spec)
    if not hinges:
        return {}
    pairs = [((spec.kind(config.kind_of(s)), spec.kind(config.kind_of(t))), (sp, tp), s, t)
             for s, sp, t, tp in closing]
    top = min(_hinge_limit(config, spec, e) for e in hinges)

    def gap(angle: float) -> float:
        poses, _ = layout(config, spec, dict.fromkeys(hinges, angle))
        return max((float(np.linalg.norm(port_mismatch(poses[s], poses[t], kinds, ports)[0]))
                    for kinds, ports, s, t in pairs), default=0.0)

    from scipy.optimize import minimize_scalar  # only where hinges close loops

    grid = np.linspace(UNBENT, max(UNBENT, top), steps)
    gaps = [gap(a) for a in grid]
    step = float(grid[1] - grid[0]) if steps > 1 else 0.0
    found = []  # each local minimum of the grid refined, the least bend first: more would
    for i, g in enumerate(gaps):  # wind the loop round twice
        if (i == 0 or g <= gaps[i - 1]) and (i + 1 == steps or g <= gaps[i + 1]):
            fit = minimize_scalar(gap, bounds=(max(UNBENT, grid[i] - step),
                                               min(top, grid[i] + step)), method="bounded")
            found.append((float(fit.fun), float(fit.x)))
            if fit.fun < LOOP_TOLERANCE:
                break
    first = next((a for g, a in found if g < LOOP_TOLERANCE), min(found)[1] if found
                 else UNBENT)
    return dict.fromkeys(hinges, float(first))


def close_loops(config: Configuration, spec: RobotSpec, closing: list[Closing],
                start: Mapping[str, float], *, seed: int = 0) -> tuple[dict[str, float], float]:
    """Hinge angles [rad] of ``config`` near ``start`` that bring each port pair of
    ``closing`` together (ports of modules already joined through ``config``), no two
    bodies overlapping; and the largest gap [m] left. Least squares within the hinges'
    limits, from ``start`` and then from seeded random starts while a gap is left."""
    from scipy.optimize import least_squares  # only where hinges close loops

    hinges = hinge_edges(config, spec)
    if not hinges or not closing:
        return {}, math.inf if closing else 0.0
    limits = np.array([_hinge_limit(config, spec, e) for e in hinges])
    first = np.clip([start.get(e, 0.0) for e in hinges], -limits, limits)
    modules = config.vertices(virtual=False)
    radius = np.array([inscribed(spec.kind(config.kind_of(m))) for m in modules])
    pairs = [((spec.kind(config.kind_of(s)), spec.kind(config.kind_of(t))), (sp, tp), s, t)
             for s, sp, t, tp in closing]

    def gaps(values: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict]:
        poses, _ = layout(config, spec, dict(zip(hinges, values, strict=True)))
        parts = [port_mismatch(poses[s], poses[t], kinds, ports) for kinds, ports, s, t in pairs]
        return np.concatenate([g for g, _ in parts]), np.concatenate([r for _, r in parts]), poses

    def residual(values: np.ndarray) -> np.ndarray:
        gap, turn, poses = gaps(values)
        centres = np.array([poses[m][1] for m in modules])
        apart = np.linalg.norm(centres[:, None] - centres[None, :], axis=2)
        overlap = np.triu(np.maximum(0.0, radius[:, None] + radius[None, :] - apart), 1)
        return np.concatenate([gap, 0.05 * turn, overlap.ravel(), 0.002 * (values - first)])

    rng = np.random.default_rng(seed)
    best: tuple[np.ndarray, float] | None = None
    for attempt in range(8):
        guess = first if attempt == 0 else rng.uniform(-limits, limits)
        fit = least_squares(residual, guess, bounds=(-limits, limits))
        gap = float(np.max(np.linalg.norm(gaps(fit.x)[0].reshape(-1, 3), axis=1)))
        if best is None or gap < best[1]:
            best = (fit.x, gap)
        if gap < 1e-4:
            break
    assert best is not None
    return dict(zip(hinges, (float(v) for v in best[0]), strict=True)), best[1]
