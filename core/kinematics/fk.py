"""Skeletal forward kinematics (FreeSN paper, Alg. 1), vectorised, with reverse-mode gradients.

:func:`forward` is the public entry: a kinematic tree, a configuration (the zero
point of the joint space) and ``sigma`` give the transformed configuration. The
work is done by an :class:`Evaluator`, which binds a tree to initial vectors once
and then evaluates many ``sigma`` cheaply -- the inverse kinematics calls it in its
inner loop:

* node types are evaluated in batches (one call per node type, not per node);
  nodes of dimension 0 (fixed nodes) are evaluated once, at construction;
* ``rotFromRoot`` of every port is cached level by level of the tree
  (``G[port] = G[input port of its node] @ portRot(port)``, Alg. 1 lines 10-15);
* :meth:`Evaluator.gradient` pulls a gradient on the world-frame vectors back to
  ``sigma`` in one sweep: each port's rotation receives the summed "torque"
  ``tau = sum z_rot x g`` of every vector it carries (a subtree sum, one matrix
  product), so the cost is linear in the tree size.

Vectors are rows ``(n, 3)`` inside the evaluator and columns ``(3, n)`` outside.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from ..configuration import Configuration
from ..errors import ConfigurationError
from .node import NodeBatch
from .rotations import canonical_perpendicular, cross, einsum
from .tree import KinematicTree

__all__ = ["Evaluator", "FKResult", "FKState", "forward", "tree_vectors"]

_EYE = np.eye(3)


def tree_vectors(tree: KinematicTree, config: Configuration
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``Z``, ``X`` (each (3, n), tree layout) and which edges really have ``x``, shape (n,).

    An edge without ``x`` gets :func:`~.rotations.canonical_perpendicular` of its ``z``
    (the skeletal view has no forward vectors; the joint modes still need one).

    Raises:
        ConfigurationError: an edge of the tree is missing or has no ``z``.
    """
    n = len(tree.edges)
    z = np.empty((n, 3))
    x = np.empty((n, 3))
    has_x = np.zeros(n, dtype=bool)
    for j, edge_id in enumerate(tree.edges):
        edge = config.edge(edge_id)
        if edge.z is None:
            raise ConfigurationError(f"connection {edge_id!r} has no z vector")
        z[j] = edge.z
        if edge.x is not None:
            x[j] = edge.x
            has_x[j] = True
    if not has_x.all():
        x[~has_x] = canonical_perpendicular(z[~has_x])
    return z.T, x.T, has_x


@dataclass
class _Group:
    """Nodes of one type and shape, evaluated in one batch."""

    cls: Any
    params: dict[str, float]
    n_ports: int
    dim: int
    nodes: np.ndarray   # (N,) node indices
    cols: np.ndarray    # (N, m) columns of Z
    sig: np.ndarray     # (N, d) indices into sigma
    ports: np.ndarray   # (N, P) port indices
    slots: np.ndarray   # (N,) input slot of each node


class _Layout:
    """Index arrays of a tree, computed once per tree (``tree._engine``)."""

    def __init__(self, tree: KinematicTree):
        self.n = len(tree.edges)
        ports: list[tuple[int, str]] = [(k, v) for k, node in enumerate(tree.nodes)
                                        for v in node.vertices]
        self.n_ports = len(ports)
        port_of = {v: q for q, (_, v) in enumerate(ports)}
        root_slot = self.n_ports  # G[root_slot] = I
        node_slot = np.array([root_slot if p is None else port_of[p] for p in tree.input_ports],
                             dtype=np.intp)
        self.node_slot = node_slot
        col_node = np.array([k for k, node in enumerate(tree.nodes) for _ in node.edges],
                            dtype=np.intp)
        self.col_slot = node_slot[col_node] if self.n else np.zeros(0, dtype=np.intp)
        port_node = np.array([k for k, _ in ports], dtype=np.intp)
        self.port_slot = node_slot[port_node] if self.n_ports else np.zeros(0, dtype=np.intp)
        # levels of the port composition: node depth
        depth = [0] * len(tree.nodes)
        for k in range(1, len(tree.nodes)):
            depth[k] = depth[tree.parents[k]] + 1
        self.levels: list[tuple[np.ndarray, np.ndarray]] = []
        for level in range(max(depth) + 1 if depth else 0):
            qs = np.array([q for q, (k, _) in enumerate(ports) if depth[k] == level],
                          dtype=np.intp)
            if len(qs):
                self.levels.append((qs, self.port_slot[qs]))
        # chain[q, j] = 1 when port q's rotation carries column j (q is on the path from
        # the root to the input port of column j's node)
        chain = np.zeros((self.n_ports, self.n))
        for j, slot in enumerate(self.col_slot):
            q = int(slot)
            while q != root_slot:
                chain[q, j] = 1.0
                q = int(self.port_slot[q])
        self.chain = chain
        # batches of equal node types
        col_start = np.cumsum([0] + [len(n.edges) for n in tree.nodes])
        port_start = np.cumsum([0] + [len(n.vertices) for n in tree.nodes])
        by_key: dict[tuple, list[int]] = {}
        for k, node in enumerate(tree.nodes):
            by_key.setdefault(node.group_key(), []).append(k)
        self.static: list[_Group] = []
        self.moving: list[_Group] = []
        for ks in by_key.values():
            first = tree.nodes[ks[0]]
            m, p, d = len(first.edges), len(first.vertices), first.dim
            group = _Group(
                cls=type(first), params=dict(first.params), n_ports=p, dim=d,
                nodes=np.array(ks, dtype=np.intp),
                cols=np.array([np.arange(col_start[k], col_start[k] + m) for k in ks],
                              dtype=np.intp).reshape(len(ks), m),
                sig=np.array([np.arange(tree.slices[k].start, tree.slices[k].stop) for k in ks],
                             dtype=np.intp).reshape(len(ks), d),
                ports=np.array([np.arange(port_start[k], port_start[k] + p) for k in ks],
                               dtype=np.intp).reshape(len(ks), p),
                slots=node_slot[ks])
            (self.moving if d else self.static).append(group)


def _layout(tree: KinematicTree) -> _Layout:
    if tree._engine is None:
        tree._engine = _Layout(tree)
    return tree._engine


@dataclass
class FKState:
    """Everything one evaluation computed, kept for :meth:`Evaluator.gradient`.

    Attributes:
        z_joint, x_joint: node outputs ``Z^joint``, ``X^joint`` as rows, (n, 3).
        z, x: ``Z^rot``, ``X^rot`` as rows, (n, 3): the vectors in the root frame.
        cost: motion cost per column, (n,).
        port_rotations: ``rotFromRoot`` of every port, (n_ports + 1, 3, 3); the last
            entry is the identity of the root's input.
        sigma: the joint values, (dim,).
    """

    z_joint: np.ndarray
    x_joint: np.ndarray
    z: np.ndarray
    x: np.ndarray
    cost: np.ndarray
    port_rotations: np.ndarray
    sigma: np.ndarray
    batches: list[NodeBatch] = field(default_factory=list)


class Evaluator:
    """Skeletal FK of one tree from fixed initial vectors, for many ``sigma``.

    Args:
        tree: the kinematic tree.
        z_init: ``Z^init``, shape (3, n), tree layout.
        x_init: ``X^init``, shape (3, n), tree layout.
    """

    def __init__(self, tree: KinematicTree, z_init: np.ndarray, x_init: np.ndarray):
        self.tree = tree
        self.layout = layout = _layout(tree)
        z0 = np.ascontiguousarray(np.asarray(z_init, dtype=np.float64).reshape(3, -1).T)
        x0 = np.ascontiguousarray(np.asarray(x_init, dtype=np.float64).reshape(3, -1).T)
        if len(z0) != layout.n or len(x0) != layout.n:
            raise ConfigurationError(f"expected {layout.n} vectors in tree layout, got "
                                     f"{len(z0)} z and {len(x0)} x")
        self.z0, self.x0 = z0, x0
        self._z_joint = z0.copy()
        self._x_joint = x0.copy()
        self._cost = np.zeros(layout.n)
        self._rel = np.broadcast_to(_EYE, (layout.n_ports, 3, 3)).copy()
        for g in layout.static:
            gz, gx = z0[g.cols], x0[g.cols]
            out = g.cls.evaluate(gz, gx, np.zeros((len(g.nodes), 0)), g.params, g.n_ports, False,
                                 g.cls.prepare(gz, gx, g.params))
            self._z_joint[g.cols] = out.z
            self._x_joint[g.cols] = out.x
            self._cost[g.cols] = out.cost
            self._rel[g.ports] = out.rot
        self._inputs = [(g, z0[g.cols], x0[g.cols],
                         g.cls.prepare(z0[g.cols], x0[g.cols], g.params)) for g in layout.moving]
        # one batch covering every column in order: its outputs are the arrays themselves
        self._whole = (len(layout.moving) == 1 and layout.moving[0].cols.shape[1] == 1
                       and np.array_equal(layout.moving[0].cols[:, 0], np.arange(layout.n)))

    def evaluate(self, sigma: np.ndarray, derivatives: bool = False) -> FKState:
        """Alg. 1: the vectors in the root frame and the costs at ``sigma`` (dim,)."""
        layout = self.layout
        sigma = np.asarray(sigma, dtype=np.float64)
        rel = self._rel.copy()
        batches = []
        if self._whole:
            g, gz, gx, context = self._inputs[0]
            out = g.cls.evaluate(gz, gx, sigma[g.sig], g.params, g.n_ports, derivatives, context)
            z_joint, x_joint, cost = out.z[:, 0], out.x[:, 0], out.cost[:, 0]
            rel[g.ports] = out.rot
            batches.append(out)
        else:
            z_joint = self._z_joint.copy()
            x_joint = self._x_joint.copy()
            cost = self._cost.copy()
            for g, gz, gx, context in self._inputs:
                out = g.cls.evaluate(gz, gx, sigma[g.sig], g.params, g.n_ports, derivatives,
                                     context)
                z_joint[g.cols] = out.z
                x_joint[g.cols] = out.x
                cost[g.cols] = out.cost
                rel[g.ports] = out.rot
                batches.append(out)
        rot = np.empty((layout.n_ports + 1, 3, 3))
        rot[layout.n_ports] = _EYE
        for qs, slots in layout.levels:
            rot[qs] = rot[slots] @ rel[qs]
        carried = rot[layout.col_slot]
        z = einsum("nab,nb->na", carried, z_joint)
        x = einsum("nab,nb->na", carried, x_joint)
        return FKState(z_joint, x_joint, z, x, cost, rot, sigma, batches)

    def gradient(self, state: FKState, grad_z: np.ndarray, grad_x: np.ndarray | None,
                 grad_cost: np.ndarray | None) -> np.ndarray:
        """``dL/dsigma`` from ``dL/dz`` and ``dL/dx`` (rows (n, 3), root frame) and ``dL/dC``.

        ``state`` must come from :meth:`evaluate` with ``derivatives=True``.
        """
        layout = self.layout
        grad = np.zeros(self.tree.dim)
        if not layout.moving:
            return grad
        torque = cross(state.z, grad_z)
        if grad_x is not None:
            torque += cross(state.x, grad_x)
        tau = layout.chain @ torque                       # (n_ports, 3), root frame
        carried = state.port_rotations[layout.col_slot]
        gz_local = einsum("nba,nb->na", carried, grad_z)
        gx_local = None if grad_x is None else einsum("nba,nb->na", carried, grad_x)
        tau_local = einsum("qba,qb->qa", state.port_rotations[layout.port_slot], tau)
        for (g, _, _, _), out in zip(self._inputs, state.batches, strict=True):
            assert out.dz is not None and out.dcost is not None and out.omega is not None
            part = einsum("nmad,nma->nd", out.dz, gz_local[g.cols])
            if gx_local is not None:
                assert out.dx is not None
                part += einsum("nmad,nma->nd", out.dx, gx_local[g.cols])
            if grad_cost is not None:
                part += einsum("nmd,nm->nd", out.dcost, grad_cost[g.cols])
            if g.n_ports:
                part += einsum("npad,npa->nd", out.omega, tau_local[g.ports])
            grad[g.sig] = part
        return grad


@dataclass(frozen=True)
class FKResult:
    """Result of :func:`forward`.

    Attributes:
        tree: the kinematic tree.
        Z: ``Z^rot``, the transformed connection vectors, shape (3, n), tree layout.
        X: ``X^rot``, the transformed forward vectors, shape (3, n).
        Z_joint: ``Z^joint`` (node frames), shape (3, n).
        X_joint: ``X^joint``, shape (3, n).
        cost: motion cost per module (edge), shape (n,), tree layout.
        port_rotations: ``rotFromRoot`` of every port vertex, ``{vertex: (3, 3)}``.
        sigma: the joint values, shape (dim,).
        source: the input configuration.
        has_x: which edges had a forward vector in the input, shape (n,).
    """

    tree: KinematicTree
    Z: np.ndarray
    X: np.ndarray
    Z_joint: np.ndarray
    X_joint: np.ndarray
    cost: np.ndarray
    port_rotations: dict[str, np.ndarray]
    sigma: np.ndarray
    source: Configuration
    has_x: np.ndarray

    @property
    def z(self) -> dict[str, np.ndarray]:
        """``{edge id: z}``, each shape (3,)."""
        return {e: self.Z[:, j].copy() for j, e in enumerate(self.tree.edges)}

    @property
    def x(self) -> dict[str, np.ndarray]:
        """``{edge id: x}`` for the edges whose input had a forward vector."""
        return {e: self.X[:, j].copy() for j, e in enumerate(self.tree.edges) if self.has_x[j]}

    @property
    def costs(self) -> dict[str, float]:
        """``{edge id: motion cost}``."""
        return {e: float(c) for e, c in zip(self.tree.edges, self.cost, strict=True)}

    @property
    def motion_cost(self) -> float:
        """Sum of the per-module motion costs."""
        return float(self.cost.sum())

    @cached_property
    def configuration(self) -> Configuration:
        """The input configuration with the transformed vectors (same ids)."""
        return transformed_configuration(self.source, self.tree, self.Z, self.X, self.has_x)


def transformed_configuration(source: Configuration, tree: KinematicTree, z: np.ndarray,
                              x: np.ndarray, has_x: np.ndarray) -> Configuration:
    """``source`` with columns of ``z`` and ``x`` (3, n) as its vectors."""
    return source.with_vectors(
        z={e: z[:, j] for j, e in enumerate(tree.edges)},
        x={e: x[:, j] for j, e in enumerate(tree.edges) if has_x[j]})


def forward(tree: KinematicTree, config: Configuration,
            sigma: np.ndarray | None = None) -> FKResult:
    """Skeletal forward kinematics (Alg. 1) of ``config`` at joint values ``sigma``.

    Args:
        tree: the kinematic tree (its ids are the configuration's).
        config: the zero point of the joint space: ``Z^init`` and ``X^init``.
        sigma: joint values in the tree's layout, shape (tree.dim,); zeros if None.

    Returns:
        The transformed vectors, costs and port rotations. With ``sigma = 0`` the
        vectors are exactly those of ``config``.

    Raises:
        ConfigurationError: ``sigma`` has the wrong shape or a non-finite value.
    """
    z0, x0, has_x = tree_vectors(tree, config)
    sigma = np.zeros(tree.dim) if sigma is None else np.asarray(sigma, dtype=np.float64)
    if sigma.shape != (tree.dim,):
        raise ConfigurationError(f"sigma must have shape ({tree.dim},), got {sigma.shape}")
    if not np.isfinite(sigma).all():
        bad = int(np.flatnonzero(~np.isfinite(sigma))[0])
        raise ConfigurationError(f"joint value {sigma[bad]} is not finite", field=f"sigma[{bad}]")
    state = Evaluator(tree, z0, x0).evaluate(sigma)
    ports = {v: state.port_rotations[q] for q, v in
             enumerate(v for node in tree.nodes for v in node.vertices)}
    return FKResult(tree, state.z.T.copy(), state.x.T.copy(), state.z_joint.T.copy(),
                    state.x_joint.T.copy(), state.cost, ports, sigma, config, has_x)
