"""Pure geometry of the FreeSN world: placing a configuration, horizontal frames.

Conventions: a strut's body frame has its ``z`` axis from end ``a`` (the source of its
connection) to end ``b`` (the target), so a configuration's ``z`` of the strut is the
body ``z`` axis in the root horizontal frame. A docked end holds the point at
``-L/2`` (end ``a``) or ``+L/2`` (end ``b``) of the strut axis on the node's centre:
the strut end touches the node surface and points radially (FreeSN paper, section
3.1). The horizontal frame ``H_i`` of a node (section 2.1) has its ``z`` axis up and
the node's heading (the twist of its orientation about the vertical).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from msrr.core.alignment import rot_z
from msrr.core.configuration import Configuration
from msrr.core.errors import ConfigurationError
from msrr.core.freeform.mujoco import heading
from msrr.core.kinematics.rotations import canonical_perpendicular

__all__ = [
    "END_SIGN",
    "Placement",
    "frame_from",
    "place",
]

END_SIGN = {"a": 1.0, "b": -1.0}
"""Direction from a docked end's node centre into the strut, as a multiple of body ``z``."""


def frame_from(z: np.ndarray, x: np.ndarray | None) -> np.ndarray:
    """Rotation (3, 3) whose ``z`` column is ``z`` and ``x`` column ``x`` made perpendicular.

    ``x`` missing or parallel to ``z`` gives :func:`canonical_perpendicular` of ``z``.
    """
    z = np.asarray(z, dtype=np.float64)
    z = z / np.linalg.norm(z)
    if x is not None:
        x = np.asarray(x, dtype=np.float64) - np.dot(x, z) * z
    if x is None or np.linalg.norm(x) < 1e-6:
        x = canonical_perpendicular(z)
    x = x / np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


@dataclass(frozen=True)
class Placement:
    """World poses of a configuration's bodies, resting above the ground.

    Attributes:
        nodes: node id -> centre [m], shape (3,).
        struts: strut id -> ``(centre [m] (3,), rotation (3, 3))``.
        ends: strut id -> ``(node at end a or None, node at end b or None)``.
        mismatch: largest angle [rad] between a strut as placed and its ``z`` (non-zero
            only where the configuration's loops do not close with equal strut lengths).
    """

    nodes: dict[str, np.ndarray]
    struts: dict[str, tuple[np.ndarray, np.ndarray]]
    ends: dict[str, tuple[str | None, str | None]]
    mismatch: float = 0.0


def place(config: Configuration, length: float, node_radius: float, strut_radius: float,
          *, clearance: float = 0.0005) -> Placement:
    """Place ``config``'s bodies from its ``z`` vectors (skeletal FK from the first node).

    Node centres follow a breadth-first spanning tree (``p_target = p_source + L z``,
    the skeletal FK of FreeSN Alg. 1 with every joint at zero). Where the topology has
    loops, the centres are then fitted by :func:`close_loops` so every strut between
    two nodes has length ``L`` (a rigid strut cannot do otherwise) while staying as
    near its ``z`` as possible, and no two spheres overlap. A strut whose both ends are
    nodes is laid between their centres, a strut with a free end along its ``z`` from
    its docked node. The whole is lifted so its lowest point is ``clearance`` [m]
    above the ground plane ``z = 0``.

    Raises:
        ConfigurationError: an edge has no ``z`` or no kind ``strut``, or a strut has
            no docked end in a configuration with nodes.
    """
    nodes = [v for v in config.vertices() if not config.is_virtual(v)]
    positions: dict[str, np.ndarray] = {}
    graph = config.undirected()
    for start in nodes:  # every connected component, from its first node
        if start in positions:
            continue
        positions[start] = np.zeros(3) if not positions else \
            np.array([2.0 * length * len(positions), 0.0, 0.0])
        queue = deque([start])
        while queue:
            u = queue.popleft()
            for _, v, key in graph.edges(u, keys=True):
                edge = config.edge(key)
                if edge.z is None:
                    raise ConfigurationError(f"connection {key!r} has no z vector")
                if config.is_virtual(v) or v in positions:
                    continue
                sign = 1.0 if edge.source == u else -1.0
                positions[v] = positions[u] + sign * length * edge.z
                queue.append(v)
    links = [(e.source, e.target, e.z) for e in config.edges()
             if not config.is_virtual(e.source) and not config.is_virtual(e.target)]
    if len(links) >= len(positions):  # a loop among the nodes
        positions = close_loops(positions, links, length, node_radius)
    struts: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    ends: dict[str, tuple[str | None, str | None]] = {}
    mismatch = 0.0
    for edge in config.edges():
        if edge.kind != "strut" or edge.z is None:
            raise ConfigurationError(f"connection {edge.id!r} must be a strut with a z vector")
        a = None if config.is_virtual(edge.source) else edge.source
        b = None if config.is_virtual(edge.target) else edge.target
        z = edge.z
        if a is not None and b is not None:
            span = positions[b] - positions[a]
            centre = positions[a] + 0.5 * span
            if np.linalg.norm(span) > 1e-9:
                z = span / np.linalg.norm(span)
                mismatch = max(mismatch, float(np.arccos(np.clip(z @ edge.z, -1.0, 1.0))))
        elif a is not None:
            centre = positions[a] + 0.5 * length * z
        elif b is not None:
            centre = positions[b] - 0.5 * length * z
        else:
            centre = np.zeros(3)
        struts[edge.id] = (centre, frame_from(z, edge.x))
        ends[edge.id] = (a, b)
    lowest = min([p[2] - node_radius for p in positions.values()]
                 + [_strut_lowest(c, r, length, node_radius, strut_radius)
                    for c, r in struts.values()], default=0.0)
    lift = np.array([0.0, 0.0, clearance - lowest])
    return Placement({n: p + lift for n, p in positions.items()},
                     {s: (c + lift, r) for s, (c, r) in struts.items()}, ends, mismatch)


@dataclass(frozen=True)
class _LoopFit:
    """The least-squares problem of :func:`close_loops` over the centres after the first.

    Attributes:
        first: the fixed first centre [m], shape (3,).
        src, dst: node index of each link's ends, shape (links,).
        zs: each link's ``z``, shape (links, 3).
        pairs: every node pair ``(i, j)``, ``i < j``, shape (pairs, 2).
        length: strut length ``L`` [m].
        gap: least distance of two node centres, ``2 r + spacing`` [m].
    """

    first: np.ndarray
    src: np.ndarray
    dst: np.ndarray
    zs: np.ndarray
    pairs: np.ndarray
    length: float
    gap: float

    def residual(self, flat: np.ndarray, weight: float) -> np.ndarray:
        """``|p_t - p_s| - L`` per link, ``w (p_t - p_s - L z)`` per link, then the overlap
        ``max(0, 2 r + spacing - |p_i - p_j|)`` per node pair."""
        p = np.vstack([self.first, flat.reshape(-1, 3)])
        span = p[self.dst] - p[self.src]
        gaps = np.linalg.norm(p[self.pairs[:, 1]] - p[self.pairs[:, 0]], axis=1)
        return np.concatenate([
            np.linalg.norm(span, axis=1) - self.length,
            (weight * (span - self.length * self.zs)).ravel(),
            np.maximum(0.0, self.gap - gaps),
        ])

    def jacobian(self, flat: np.ndarray, weight: float) -> np.ndarray:
        """The residual's analytic Jacobian with respect to ``flat``."""
        src, dst, pairs = self.src, self.dst, self.pairs
        n_links, n_pairs, n_nodes = len(src), len(pairs), len(flat) // 3 + 1
        p = np.vstack([self.first, flat.reshape(-1, 3)])
        span = p[dst] - p[src]
        unit = span / np.maximum(np.linalg.norm(span, axis=1), 1e-12)[:, None]
        gap = p[pairs[:, 1]] - p[pairs[:, 0]]
        dist = np.linalg.norm(gap, axis=1)
        active = (self.gap - dist > 0)[:, None]
        push = -(active * gap) / np.maximum(dist, 1e-12)[:, None]
        jac = np.zeros((n_links * 4 + n_pairs, 3 * n_nodes))
        rows = np.arange(n_links)
        for node, sign in ((dst, 1.0), (src, -1.0)):
            for a in range(3):
                jac[rows, 3 * node + a] += sign * unit[:, a]
                jac[n_links + 3 * rows + a, 3 * node + a] += sign * weight
        prow = 4 * n_links + np.arange(n_pairs)
        for node, sign in ((pairs[:, 1], 1.0), (pairs[:, 0], -1.0)):
            for a in range(3):
                jac[prow, 3 * node + a] += sign * push[:, a]
        return jac[:, 3:]

    def fit(self, x: np.ndarray, weight: float) -> np.ndarray:
        return least_squares(self.residual, x, jac=self.jacobian, args=(weight,), xtol=1e-12,
                             ftol=1e-12).x

    def exact(self, x: np.ndarray) -> bool:
        """Lengths exact and no sphere overlaps."""
        return bool(np.max(np.abs(self.residual(x, 0.0))) < 1e-6 * self.length)


def _exact_fits(problem: _LoopFit, x0: np.ndarray, direction_weight: float, restarts: int
                ) -> list[tuple[float, np.ndarray]]:
    """Exact fits and their squared distance to the ``z`` vectors: by continuation from
    ``x0`` (only that one if it succeeds), else from seeded random shapes, up to three."""
    rng = np.random.default_rng(0)
    length = problem.length
    found: list[tuple[float, np.ndarray]] = []
    for attempt in range(restarts + 1):
        if attempt == 0:  # continuation: agree with z, then make the lengths exact
            x, weights = x0, (1.0, 0.3, 0.1, 0.03, direction_weight, 0.0)
        else:  # a random exact shape, turned (or mirrored) onto z, then polished
            x = problem.fit(x0 + rng.normal(0.0, length, x0.shape), 0.0)
            x = _turn_onto(x, problem.first, problem.src, problem.dst, length * problem.zs)
            weights = (direction_weight, 0.0)
        for weight in weights:
            x = problem.fit(x, weight)
        if problem.exact(x):
            found.append((float(np.sum(problem.residual(x, 1.0) ** 2)), x))
            if attempt == 0 or len(found) == 3:
                break
    return found


def close_loops(positions: dict[str, np.ndarray], links: list[tuple[str, str, np.ndarray]],
                length: float, node_radius: float, *, direction_weight: float = 0.01,
                spacing: float = 0.01, restarts: int = 8) -> dict[str, np.ndarray]:
    """Node centres where every linked pair is ``length`` apart, nearest the ``z`` vectors.

    Least squares over the centres (the first node fixed) of the residuals
    ``|p_t - p_s| - L`` per link, ``w (p_t - p_s - L z)`` per link with ``w =
    direction_weight`` (small: the lengths are what a rigid strut cannot violate), and
    ``max(0, 2 r + spacing - |p_i - p_j|)`` per node pair, from
    the breadth-first placement, with the direction weight lowered in steps from 1
    (continuation: first agree with the ``z`` vectors, then make the lengths exact). A
    configuration whose loops close already is a zero of the residual and comes back
    unchanged. When that ends in a tangle (a length off or spheres overlapping), seeded
    random restarts fit the lengths alone and then turn toward the ``z`` vectors; the
    best of up to three exact fits (by their distance to the ``z`` vectors) is kept.

    Raises:
        ConfigurationError: no exact fit after ``restarts`` restarts.

    Args:
        positions: initial centres [m] by node id.
        links: ``(source, target, z)`` of every strut between two nodes.
        length: strut length ``L`` [m]. node_radius: ``r`` [m].
    """
    names = list(positions)
    index = {n: i for i, n in enumerate(names)}
    problem = _LoopFit(
        first=positions[names[0]],
        src=np.array([index[s] for s, _, _ in links]),
        dst=np.array([index[t] for _, t, _ in links]),
        zs=np.array([z for _, _, z in links]),
        pairs=np.array([(i, j) for i in range(len(names)) for j in range(i + 1, len(names))],
                       dtype=int).reshape(-1, 2),
        length=length, gap=2.0 * node_radius + spacing)
    x0 = np.array([positions[n] for n in names[1:]]).ravel()
    if not len(x0) or problem.exact(x0):
        return dict(positions)  # closes already (to the precision of the stored vectors)
    found = _exact_fits(problem, x0, direction_weight, restarts)
    if not found:
        raise ConfigurationError(
            f"the loops of the configuration cannot be closed with struts of length {length} m "
            f"and spheres of radius {node_radius} m that do not overlap")
    x = min(found, key=lambda item: item[0])[1]
    p = np.vstack([problem.first, x.reshape(-1, 3)])
    return {n: p[i] for i, n in enumerate(names)}


def _turn_onto(flat: np.ndarray, first: np.ndarray, src: np.ndarray, dst: np.ndarray,
               want: np.ndarray) -> np.ndarray:
    """Rotate (or rotate and mirror) centres about ``first`` so link spans best match ``want``.

    Orthogonal Procrustes (Kabsch) on the spans; both handednesses are tried.
    """
    p = np.vstack([first, flat.reshape(-1, 3)]) - first
    span = p[dst] - p[src]
    u, _, vt = np.linalg.svd(want.T @ span)
    best, best_cost = p, np.inf
    for flip in (1.0, -1.0):
        rot = u @ np.diag([1.0, 1.0, flip * np.linalg.det(u @ vt)]) @ vt
        if flip < 0:  # a mirror image is as valid a shape
            rot = u @ vt if np.linalg.det(u @ vt) < 0 else u @ np.diag([1.0, 1.0, -1.0]) @ vt
        cost = float(np.sum((span @ rot.T - want) ** 2))
        if cost < best_cost:
            best, best_cost = p @ rot.T, cost
    return (best[1:] + first).ravel()


def _strut_lowest(centre: np.ndarray, rotation: np.ndarray, length: float, node_radius: float,
                  radius: float) -> float:
    half = 0.5 * length - node_radius
    return float(centre[2] - abs(rotation[2, 2]) * half - radius)


def horizontal(quat: np.ndarray) -> np.ndarray:
    """Rotation (3, 3) of the horizontal frame of a body with orientation ``quat`` (w, x, y, z)."""
    return rot_z(float(heading(quat)))
