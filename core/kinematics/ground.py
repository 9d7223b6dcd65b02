"""Three-point ground contact for floating bases (FreeSN paper, section 3.4, "Ground Model").

The forward kinematics rotates a configuration about its root; a robot standing on
the ground then tips until it rests on three contact points with its centre of mass
above the support triangle. :class:`GroundOp` finds that pose: vertex positions
follow from the vectors and the module lengths along a spanning tree of the
topology, the support face is the face of their convex hull whose centre-of-mass
projection falls inside it and whose outward normal is closest to straight down,
and the minimal rotation that turns the face's normal to ``-z`` is applied to
every vector. Its derivative (for a fixed face) flows back to the vectors, so the
inverse kinematics keeps an analytic gradient.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import networkx as nx
import numpy as np
from scipy.spatial import ConvexHull, QhullError

from ..configuration import Configuration
from ..robot import RobotSpec
from .rotations import ANTIPARALLEL_TOLERANCE, cross, rotation_between
from .tree import KinematicTree

__all__ = ["GroundContact", "GroundModel", "GroundOp", "ground_op"]

_DOWN = np.array([0.0, 0.0, -1.0])
try:   # scipy's qhull wrapper, which ConvexHull drives (see hull_facets)
    from scipy.spatial._qhull import _Qhull as _QHULL
except ImportError:  # pragma: no cover - another scipy layout
    _QHULL = None


@dataclass(frozen=True)
class GroundModel:
    """Lengths and masses the ground model needs.

    Attributes:
        lengths: centre-to-centre length [m] of each edge, by id; ``default_length``
            for edges not listed.
        masses: mass [kg] of each module (vertex or edge) by id; ``default_vertex_mass``
            and ``default_edge_mass`` for modules not listed. An edge module's mass
            sits at its midpoint; virtual vertices weigh nothing.
    """

    lengths: Mapping[str, float] = field(default_factory=dict)
    masses: Mapping[str, float] = field(default_factory=dict)
    default_length: float = 1.0
    default_vertex_mass: float = 1.0
    default_edge_mass: float = 0.0

    @classmethod
    def for_configuration(cls, config: Configuration, spec: RobotSpec) -> GroundModel:
        """Lengths and masses of ``config``'s modules from ``spec``'s module kinds
        (``geometry`` entries ``length`` [m] and ``mass`` [kg]); the defaults where a
        kind gives none."""
        geometry = {k.name: k.geometry for k in spec.module_kinds}
        lengths, masses = {}, {}
        for e in config.edges():
            geo = geometry.get(e.kind or "", {})
            if "length" in geo:
                lengths[e.id] = float(geo["length"])
            if "mass" in geo:
                masses[e.id] = float(geo["mass"])
        for v in config.vertices(virtual=False):
            geo = geometry.get(config.kind_of(v), {})
            if "mass" in geo:
                masses[v] = float(geo["mass"])
        return cls(lengths, masses)


@dataclass(frozen=True)
class GroundContact:
    """The resting pose found by the ground model.

    Attributes:
        rotation: rotation applied to every vector, shape (3, 3).
        contacts: the three contact vertices (empty when no support face exists).
        normal: outward normal of the support face before the rotation, shape (3,).
        com: centre of mass before the rotation [m], shape (3,).
        stable: whether the centre of mass projects inside the support triangle.
    """

    rotation: np.ndarray
    contacts: tuple[str, ...]
    normal: np.ndarray
    com: np.ndarray
    stable: bool


@dataclass
class _Cache:
    rotation: np.ndarray
    points: np.ndarray | None = None   # positions (n_vertices, 3)
    face: tuple[int, int, int] | None = None
    edges: tuple[np.ndarray, np.ndarray] | None = None   # b - a, c - a
    norm: float = 1.0   # |(b - a) x (c - a)|
    normal: np.ndarray | None = None   # (b - a) x (c - a) / norm
    source: np.ndarray | None = None   # the vectors given to contact()
    grounded: np.ndarray | None = None   # source @ rotation.T


class GroundOp:
    """The ground model compiled for one tree: positions and centre of mass as matrices.

    Args:
        tree: the kinematic tree (its configuration gives the topology).
        model: lengths and masses.
    """

    def __init__(self, tree: KinematicTree, model: GroundModel):
        config = tree.configuration
        self.vertices = config.vertices()
        index = {v: i for i, v in enumerate(self.vertices)}
        n = len(tree.edges)
        column = {e: j for j, e in enumerate(tree.edges)}
        graph = nx.Graph()
        graph.add_nodes_from(self.vertices)
        for e in config.edges():
            if not graph.has_edge(e.source, e.target):
                graph.add_edge(e.source, e.target, id=e.id)
        start = tree.root.vertices[0] if tree.root.vertices else self.vertices[0]
        # positions = paths @ Z_rows: sum of +-length * z along the spanning tree
        paths = np.zeros((len(self.vertices), n))
        for parent, child in nx.bfs_edges(graph, start):
            edge = config.edge(graph.edges[parent, child]["id"])
            sign = 1.0 if edge.source == parent else -1.0
            paths[index[child]] = paths[index[parent]]
            paths[index[child], column[edge.id]] += sign * model.lengths.get(
                edge.id, model.default_length)
        self.paths = paths
        masses = np.array([0.0 if config.is_virtual(v) else model.masses.get(
            v, model.default_vertex_mass) for v in self.vertices])
        com = masses @ paths
        total = masses.sum()
        for e in config.edges():
            m = model.masses.get(e.id, model.default_edge_mass)
            com = com + m * 0.5 * (paths[index[e.source]] + paths[index[e.target]])
            total += m
        self.com_weights = com / total if total > 0 else np.full(n, 0.0)

    def contact(self, z: np.ndarray) -> tuple[GroundContact, _Cache]:
        """The resting pose for world-frame vectors ``z`` (rows, (n, 3)); the cache holds
        the grounded vectors ``z R^T`` (``cache.grounded``) and what :meth:`backward` needs."""
        points = self.paths @ z
        com = self.com_weights @ z
        face = self._support(points, com)
        if face is None:
            eye = np.eye(3)
            return GroundContact(eye, (), _DOWN.copy(), com, False), _Cache(eye, source=z)
        (a, b, c), stable = face
        u, v = points[b] - points[a], points[c] - points[a]
        raw = _cross3(u, v)
        norm = math.sqrt(raw.dot(raw))   # np.linalg.norm's own arithmetic for a vector
        normal = raw / norm
        rot = turn_down(normal)
        contact = GroundContact(rot, tuple(self.vertices[i] for i in (a, b, c)), normal, com,
                                stable)
        return contact, _Cache(rot, points, (a, b, c), (u, v), norm, normal, z, z @ rot.T)

    def backward(self, cache: _Cache, z: np.ndarray, grad_z: np.ndarray,
                 x: np.ndarray | None = None, grad_x: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray | None]:
        """Pull gradients on the grounded vectors ``R z`` back to ``z`` (rows (n, 3)).

        Args:
            cache: from :meth:`contact`.
            z: the vectors before grounding (rows).
            grad_z: ``dL/d(R z)`` (rows).
            x, grad_x: the same for forward vectors, optional.
        """
        rot = cache.rotation
        gz = grad_z @ rot
        gx = None if grad_x is None else grad_x @ rot
        if cache.face is None:
            return gz, gx
        assert cache.points is not None and cache.edges is not None \
            and cache.normal is not None
        # torque of the gradients on the grounded vectors (those contact() made, if of z)
        grounded = cache.grounded if z is cache.source else z @ rot.T
        tau = np.add.reduce(cross(grounded, grad_z), axis=0)
        if x is not None and grad_x is not None:
            tau += np.add.reduce(cross(x @ rot.T, grad_x), axis=0)
        norm, normal = cache.norm, cache.normal
        # R = Q^T with Q = rotation_between(down, n); dR = hat(-R omega_Q) R
        omega_q = turn_down_omega(normal, norm)      # (3, 3): d omega_Q / d raw
        g_raw = -(omega_q.T @ (rot.T @ tau))
        a, b, c = cache.face
        pts = cache.points
        u, v = cache.edges
        g_u = _cross3(v, g_raw)
        g_v = _cross3(g_raw, u)
        g_points = np.zeros_like(pts)
        g_points[b] += g_u
        g_points[c] += g_v
        g_points[a] -= g_u + g_v
        return gz + self.paths.T @ g_points, gx

    def _support(self, points: np.ndarray, com: np.ndarray
                 ) -> tuple[tuple[int, int, int], bool] | None:
        """Support triangle (vertex indices, outward normal order) and its stability."""
        if len(points) < 3:
            return None
        try:
            faces, equations = hull_facets(points)
            normals = equations[:, :3]
        except (QhullError, ValueError):
            return self._planar_support(points, com)
        # the most downward normal first (ties: the first face); the first stable one wins
        order = np.argsort(normals[:, 2], kind="stable").tolist()
        pts, ns, tri, centre = points.tolist(), normals.tolist(), faces.tolist(), com.tolist()
        for i in order:
            face = _outward(pts, tri[i], ns[i])
            if _inside_face(pts, face, centre, ns[i]):
                return face, True
        return _outward(pts, tri[order[0]], ns[order[0]]), False

    def _planar_support(self, points: np.ndarray, com: np.ndarray
                        ) -> tuple[tuple[int, int, int], bool] | None:
        """All points in one plane: the fan triangle of its outline under the centre of mass."""
        centred = points - points.mean(axis=0)
        _, sv, vt = np.linalg.svd(centred)
        if sv[1] < 1e-9 * max(sv[0], 1e-300):
            return None  # collinear: no support plane
        normal = vt[2] if vt[2][2] <= 0 else -vt[2]
        flat = centred @ vt[:2].T
        try:
            outline = [int(i) for i in ConvexHull(flat).vertices]
        except (QhullError, ValueError):
            return None
        fans = []
        for i in range(1, len(outline) - 1):
            a, b, c = outline[0], outline[i], outline[i + 1]
            if np.dot(cross(points[b] - points[a], points[c] - points[a]), normal) < 0:
                b, c = c, b
            fans.append((a, b, c))
        for a, b, c in fans:
            if _inside(points[a], points[b], points[c], com, normal):
                return (a, b, c), True
        return (fans[0], False) if fans else None


def ground_op(tree: KinematicTree, model: GroundModel) -> GroundOp:
    """The :class:`GroundOp` of ``tree`` and ``model``, built once per tree and model and
    kept on the tree (like its forward-kinematics layout): a tracking IK builds a new
    problem every control tick on the same tree."""
    cached = getattr(tree, "_ground", None)
    if cached is None or cached[0] != model:
        cached = tree._ground = (model, GroundOp(tree, model))
    return cached[1]


def hull_facets(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``ConvexHull(points)``'s ``simplices`` and ``equations``: the same qhull run (options
    ``Qt``), without the volume, area and bounds ``ConvexHull`` also computes (40 % of its
    time on a support face's ~20 points). Falls back to ``ConvexHull`` where scipy's qhull
    wrapper is not the one this was written for.

    Raises:
        QhullError, ValueError: as ``ConvexHull`` (degenerate or invalid points).
    """
    if _QHULL is None:
        hull = ConvexHull(points)
        return hull.simplices, hull.equations
    qhull = _QHULL(b"i", np.ascontiguousarray(points, dtype=np.float64), b"",
                   required_options=b"Qt")
    try:
        qhull.triangulate()
        simplices, _, equations, _, _ = qhull.get_simplex_facet_array()
    finally:
        qhull.close()
    return simplices, equations


def turn_down(n: np.ndarray) -> np.ndarray:
    """``rotation_between(n, (0, 0, -1))`` for one unit vector ``n`` (3,): the minimal rotation
    that turns a support face's normal straight down (eq. 2), shape (3, 3).

    The same IEEE operations as :func:`~.rotations.rotation_between` on plain floats (its ~20
    numpy calls on 3-vectors cost more than the arithmetic), its einsum's sums with their +0
    start, so the result is the same to the bit, zeros' signs included (exact runs have exact
    zeros); an antiparallel ``n`` (straight up) takes the general path.
    """
    n0, n1, n2 = n.tolist()
    # w = n x down (rotations.cross); c = n . down and hat(w) as einsum sums them, from +0
    # (so a zero is +0, whatever the signs of the zeros summed)
    w0, w1, w2 = n1 * -1.0 - n2 * 0.0, n2 * 0.0 - n0 * -1.0, n0 * 0.0 - n1 * 0.0
    c = (n0 * 0.0 + n1 * 0.0 + n2 * -1.0) + 0.0
    d = 1.0 + c
    if d < ANTIPARALLEL_TOLERANCE:
        return rotation_between(n, _DOWN)
    e, z = c * 1.0 + 0.0, c * 0.0   # c I + hat(w) on and off the diagonal
    p0, p1, p2 = w0 + 0.0, w1 + 0.0, w2 + 0.0
    m0, m1, m2 = 0.0 - w0, 0.0 - w1, 0.0 - w2
    # c I + hat(w) + w w^T / (1 + c)
    return np.array(((e + w0 * w0 / d, (z + m2) + w0 * w1 / d, (z + p1) + w0 * w2 / d),
                     ((z + p2) + w1 * w0 / d, e + w1 * w1 / d, (z + m0) + w1 * w2 / d),
                     ((z + m1) + w2 * w0 / d, (z + p0) + w2 * w1 / d, e + w2 * w2 / d)))


def turn_down_omega(n: np.ndarray, norm: float) -> np.ndarray:
    """``rotation_between_omega(down, n, (I - n n^T) / norm)``: how the rotation from straight
    down onto the unit normal ``n`` (3,) turns when the unnormalised normal (length ``norm``)
    moves, shape (3, 3), column ``d`` per component of the unnormalised normal.

    Plain-float form of :func:`~.rotations.rotation_between_omega` with the same operations
    in the same order (the same floats); zero for antiparallel vectors as there.
    """
    n0, n1, n2 = n.tolist()
    d = 1.0 + ((0.0 * n0 + 0.0 * n1 + -1.0 * n2) + 0.0)   # einsum's sum, from +0
    if d < ANTIPARALLEL_TOLERANCE:
        return np.zeros((3, 3))
    # dv2 = (I - n n^T) / norm, column k
    nn = (n0, n1, n2)
    dv = [[((1.0 if i == k else 0.0) - nn[i] * nn[k]) / norm for k in range(3)] for i in range(3)]
    a0, a1, a2 = 0.0 * n2 - -1.0 * n1, -1.0 * n0 - 0.0 * n2, 0.0 * n1 - 0.0 * n0   # down x n
    rows: list[list[float]] = [[], [], []]
    for k in range(3):
        u0, u1, u2 = dv[0][k], dv[1][k], dv[2][k]
        twist = ((a0 * u0 + a1 * u1 + a2 * u2) + 0.0) / d   # einsum's sum, from +0
        rows[0].append((n1 * u2 - n2 * u1) - twist * n0)
        rows[1].append((n2 * u0 - n0 * u2) - twist * n1)
        rows[2].append((n0 * u1 - n1 * u0) - twist * n2)
    return np.array(rows)


def _cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """:func:`~.rotations.cross` of two 3-vectors in plain floats: the same products and
    differences, so the same floats, without six numpy calls on 3 elements."""
    a0, a1, a2 = a.tolist()
    b0, b1, b2 = b.tolist()
    return np.array((a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0))


def _sub(u: list[float], v: list[float]) -> tuple[float, float, float]:
    return u[0] - v[0], u[1] - v[1], u[2] - v[2]


def _cross_dot(u: tuple[float, float, float], v: tuple[float, float, float],
               n: list[float]) -> float:
    """``(u x v) . n`` in plain floats (the same operations as ``cross`` and a dot)."""
    return ((u[1] * v[2] - u[2] * v[1]) * n[0] + (u[2] * v[0] - u[0] * v[2]) * n[1]) \
        + (u[0] * v[1] - u[1] * v[0]) * n[2]


def _outward(pts: list[list[float]], face: list[int], normal: list[float]
             ) -> tuple[int, int, int]:
    """``face``'s vertex indices ordered so that ``(b - a) x (c - a)`` is along ``normal``."""
    a, b, c = face
    if _cross_dot(_sub(pts[b], pts[a]), _sub(pts[c], pts[a]), normal) < 0:
        b, c = c, b
    return a, b, c


def _inside_face(pts: list[list[float]], face: tuple[int, int, int], p: list[float],
                 normal: list[float]) -> bool:
    """:func:`_inside` on point lists: ``p`` projected along ``normal`` falls in ``face``."""
    a, b, c = face
    return all(_cross_dot(_sub(pts[v], pts[u]), _sub(p, pts[u]), normal) >= -1e-12
               for u, v in ((a, b), (b, c), (c, a)))


def _inside(a: np.ndarray, b: np.ndarray, c: np.ndarray, p: np.ndarray,
            normal: np.ndarray) -> bool:
    """Whether ``p`` projected along ``normal`` falls inside triangle ``abc``."""
    return all(np.dot(cross(v - u, p - u), normal) >= -1e-12
               for u, v in ((a, b), (b, c), (c, a)))
