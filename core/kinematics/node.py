"""Kinematic nodes: one or more modules moved together by a joint space (paper section 3.2).

A kinematic node ``k`` owns an ordered set of *edges* (the modules that carry
connection vectors: a FreeSN strut, a FreeBOT connection) whose vectors form
``Z_k`` and ``X_k``, and an ordered set of *vertices* (the modules it moves, which
are also its output *ports*: children attach there). Its parent attaches through
the ends of its edges that it does not own. Given ``Z_k^init``, ``X_k^init`` and the
joint values ``sigma_k`` it returns the transformed vectors ``Z_k^joint``,
``X_k^joint``, the motion costs ``C_k`` (one per edge) and the rotation from its
input port to each of its ports (``portRot``), together with their analytic
derivatives with respect to ``sigma_k``.

Three families (``family``):

* ``"fixed"`` -- :class:`FixedNode`: joint dimension 0, identity port rotations; any
  sub-graph, cycles allowed (the root of every tree is one).
* ``"module_joint"`` -- :class:`ModuleJointNode`: one edge and the vertex it reaches.
* ``"parallel"`` -- :class:`ParallelNode`: a sub-graph that closes cycles through
  its parent's ports (FreeSN parallel strut, Fig. 7).

Robot plugins register concrete node *types* (classes) through
``msrr_kinematic_nodes(robot, register)``; the class attribute ``name`` is the joint
mode's name. A type implements :meth:`KinematicNode.evaluate`, vectorised over
``N`` nodes of that type at once, which the forward kinematics calls once per type.
Vectors inside ``evaluate`` are rows: ``(N, m, 3)``.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Literal, Self

import numpy as np

from ..errors import ConfigurationError
from .rotations import skew

if TYPE_CHECKING:
    from ..configuration import Edge

__all__ = [
    "FAMILIES",
    "FixedNode",
    "KinematicNode",
    "KinematicTreeError",
    "ModuleJointNode",
    "NodeBatch",
    "NodeForward",
    "NodeJacobian",
    "ParallelNode",
]

Family = Literal["fixed", "module_joint", "parallel"]
FAMILIES: tuple[str, ...] = ("fixed", "module_joint", "parallel")


class KinematicTreeError(ConfigurationError):
    """A kinematic node or tree is malformed or does not fit its configuration."""


@dataclass
class NodeBatch:
    """What :meth:`KinematicNode.evaluate` returns for ``N`` nodes of one type.

    Attributes:
        z: transformed connection vectors ``Z^joint``, shape (N, m, 3).
        x: transformed forward vectors ``X^joint``, shape (N, m, 3).
        cost: motion cost per edge ``C``, shape (N, m).
        rot: rotation from the input port to each port, shape (N, P, 3, 3).
        dz: ``d z / d sigma``, shape (N, m, 3, d), when derivatives were asked for.
        dx: ``d x / d sigma``, shape (N, m, 3, d).
        dcost: ``d C / d sigma``, shape (N, m, d).
        omega: port angular velocities, shape (N, P, 3, d): ``d rot / d sigma_i =
            hat(omega[..., i]) @ rot``, in the input port's frame.
    """

    z: np.ndarray
    x: np.ndarray
    cost: np.ndarray
    rot: np.ndarray
    dz: np.ndarray | None = None
    dx: np.ndarray | None = None
    dcost: np.ndarray | None = None
    omega: np.ndarray | None = None


@dataclass(frozen=True)
class NodeForward:
    """Forward kinematics of one node (Alg. 1 line 11), column vectors.

    Attributes:
        z: ``Z_k^joint``, shape (3, m).
        x: ``X_k^joint``, shape (3, m).
        cost: ``C_k``, shape (m,).
        rotations: ``portRot`` from the input port to each port, shape (P, 3, 3).
    """

    z: np.ndarray
    x: np.ndarray
    cost: np.ndarray
    rotations: np.ndarray


@dataclass(frozen=True)
class NodeJacobian:
    """Derivatives of :class:`NodeForward` with respect to ``sigma`` (d columns).

    Attributes:
        z: shape (3, m, d).
        x: shape (3, m, d).
        cost: shape (m, d).
        rotations: shape (P, 3, 3, d).
    """

    z: np.ndarray
    x: np.ndarray
    cost: np.ndarray
    rotations: np.ndarray


class KinematicNode:
    """A kinematic node: joint space, ordered edges and ports, forward kinematics.

    Subclasses set the class attributes and implement :meth:`evaluate`.

    Args:
        edges: ids of the edges (vector-carrying modules) in the node's order.
        vertices: ids of the vertices the node owns; they are its output ports.
        **params: parameters of the node type (see ``defaults``), such as the
            steering weight ``alpha`` or the joint bound ``bound`` [rad].

    Class attributes:
        name: the joint mode's name, unique per robot (``"opposite_steering"``).
        family: ``"fixed"``, ``"module_joint"`` or ``"parallel"``.
        dim: joint-space dimension.
        controller: id of the controller that executes this node.
        defaults: parameter names and default values.
        description: one line for tables.
        planted: the node's far end grips the ground (a planted foot): it holds its
            place while the rest moves, so a sequence gait's heading loop turns the body
            about it (:func:`~msrr.core.closed_loop.turned_goal`).
    """

    name: ClassVar[str] = ""
    family: ClassVar[Family] = "fixed"
    dim: ClassVar[int] = 0
    controller: ClassVar[str] = ""
    defaults: ClassVar[Mapping[str, float]] = {}
    description: ClassVar[str] = ""
    planted: ClassVar[bool] = False

    def __init__(self, edges: Iterable[str] = (), vertices: Iterable[str] = (), **params: float):
        self.edges: tuple[str, ...] = tuple(str(e) for e in edges)
        self.vertices: tuple[str, ...] = tuple(str(v) for v in vertices)
        unknown = set(params) - set(self.defaults)
        if unknown:
            known = ", ".join(sorted(self.defaults)) or "none"
            raise KinematicTreeError(f"{self.name} node: unknown parameter(s) "
                                     f"{', '.join(sorted(unknown))} (known: {known})")
        self.params: dict[str, float] = {**self.defaults,
                                         **{k: float(v) for k, v in params.items()}}
        if len(set(self.edges)) != len(self.edges) or len(set(self.vertices)) != len(self.vertices):
            raise KinematicTreeError(f"{self.name} node: an edge or vertex is listed twice")
        self.validate()

    # -- what a subclass defines --------------------------------------------------------

    def validate(self) -> None:
        """Check the node's shape (edge and vertex counts); raise KinematicTreeError."""

    @classmethod
    def prepare(cls, z: np.ndarray, x: np.ndarray, params: Mapping[str, float]) -> Any:
        """Anything :meth:`evaluate` can reuse while ``Z^init`` and ``X^init`` stay the same.

        Called once per batch and set of initial vectors (the IK evaluates the same
        initial vectors many times); the result is passed as ``context``.
        """
        return None

    @classmethod
    def evaluate(cls, z: np.ndarray, x: np.ndarray, sigma: np.ndarray,
                 params: Mapping[str, float], n_ports: int, derivatives: bool,
                 context: Any = None) -> NodeBatch:
        """Forward kinematics of ``N`` nodes of this type with equal shapes and parameters.

        Args:
            z: ``Z^init`` rows, shape (N, m, 3), unit.
            x: ``X^init`` rows, shape (N, m, 3), unit.
            sigma: joint values, shape (N, dim).
            params: the nodes' shared parameters.
            n_ports: ports per node ``P``.
            derivatives: also fill ``dz``, ``dx``, ``dcost`` and ``omega``.
            context: what :meth:`prepare` returned for these ``z`` and ``x``.
        """
        raise NotImplementedError

    # -- derived ------------------------------------------------------------------------

    @property
    def ports(self) -> tuple[str, ...]:
        """Output ports: the owned vertices, where child nodes attach."""
        return self.vertices

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper joint bounds, each shape (dim,); ``+-params['bound']``."""
        bound = float(self.params.get("bound", np.inf))
        return np.full(self.dim, -bound), np.full(self.dim, bound)

    def group_key(self) -> tuple[Any, ...]:
        """Nodes with equal keys are evaluated in one batch."""
        return (type(self), tuple(sorted(self.params.items())), len(self.edges),
                len(self.vertices))

    def forward(self, z_init: np.ndarray, x_init: np.ndarray, sigma: np.ndarray) -> NodeForward:
        """``Z^joint, X^joint, C`` and port rotations of this node (Alg. 1 line 11).

        Args:
            z_init: ``Z_k^init``, shape (3, m).
            x_init: ``X_k^init``, shape (3, m).
            sigma: joint values, shape (dim,).
        """
        out = self._one(z_init, x_init, sigma, derivatives=False)
        return NodeForward(out.z[0].T, out.x[0].T, out.cost[0], out.rot[0])

    def jacobian(self, z_init: np.ndarray, x_init: np.ndarray, sigma: np.ndarray
                 ) -> NodeJacobian:
        """Analytic derivatives of :meth:`forward` with respect to ``sigma``."""
        out = self._one(z_init, x_init, sigma, derivatives=True)
        assert out.dz is not None and out.dx is not None and out.dcost is not None
        assert out.omega is not None
        rot = out.rot[0]
        drot = np.einsum("pdab,pbc->pacd", skew(np.moveaxis(out.omega[0], -1, -2)), rot)
        return NodeJacobian(np.moveaxis(out.dz[0], 0, 1), np.moveaxis(out.dx[0], 0, 1),
                            out.dcost[0], drot)

    def _one(self, z_init: np.ndarray, x_init: np.ndarray, sigma: np.ndarray,
             derivatives: bool) -> NodeBatch:
        z = np.asarray(z_init, dtype=np.float64).reshape(3, -1).T[None]
        x = np.asarray(x_init, dtype=np.float64).reshape(3, -1).T[None]
        s = np.asarray(sigma, dtype=np.float64).reshape(1, self.dim)
        return self.evaluate(z, x, s, self.params, len(self.vertices), derivatives,
                             self.prepare(z, x, self.params))

    def to_dict(self) -> dict[str, Any]:
        """``{"type", "edges", "vertices", "params"}``; params only where not default."""
        changed = {k: v for k, v in self.params.items() if self.defaults.get(k) != v}
        out: dict[str, Any] = {"type": self.name, "edges": list(self.edges),
                               "vertices": list(self.vertices)}
        if changed:
            out["params"] = changed
        return out

    def __repr__(self) -> str:
        return (f"{type(self).__name__}(edges={list(self.edges)}, "
                f"vertices={list(self.vertices)})")

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, KinematicNode):
            return NotImplemented
        return (type(self), self.edges, self.vertices, self.params) == (
            type(other), other.edges, other.vertices, other.params)

    __hash__ = None  # type: ignore[assignment]


def constant_batch(z: np.ndarray, x: np.ndarray, n_ports: int, dim: int,
                   derivatives: bool) -> NodeBatch:
    """The output of a node that does not move: vectors unchanged, zero cost, identity ports."""
    n, m = z.shape[:2]
    out = NodeBatch(z.copy(), x.copy(), np.zeros((n, m)), np.broadcast_to(
        np.eye(3), (n, n_ports, 3, 3)).copy())
    if derivatives:
        out.dz = np.zeros((n, m, 3, dim))
        out.dx = np.zeros((n, m, 3, dim))
        out.dcost = np.zeros((n, m, dim))
        out.omega = np.zeros((n, n_ports, 3, dim))
    return out


class FixedNode(KinematicNode):
    """Fixed kinematic node: any sub-graph, no joint space, identity port rotations.

    The root of every kinematic tree is a fixed node (for a tree topology, the
    centre vertex alone). Cycles may lie inside it.
    """

    name = "fixed"
    family = "fixed"
    dim = 0
    controller = "hold"
    description = "modules held still relative to their parent; cycles allowed"

    @classmethod
    def evaluate(cls, z, x, sigma, params, n_ports, derivatives, context=None):
        return constant_batch(z, x, n_ports, 0, derivatives)


class ModuleJointNode(KinematicNode):
    """Module joint kinematic node: one edge (module) and the vertex it reaches.

    Concrete modes (FreeSN revolute, opposite steering, ...) subclass this and
    implement :meth:`evaluate` with ``m = 1`` and ``P = 1``.
    """

    family = "module_joint"

    def validate(self) -> None:
        if len(self.edges) != 1 or len(self.vertices) != 1:
            raise KinematicTreeError(
                f"{self.name} node: a module joint has exactly one edge and one vertex, got "
                f"edges {list(self.edges)} and vertices {list(self.vertices)}")


    @classmethod
    def for_edge(cls, edge: Edge, reached: str) -> Self:
        """The node of this mode for ``edge`` when a tree reaches vertex ``reached``
        through it (:func:`~msrr.core.kinematics.default_tree` builds nodes this way).

        A mode whose motion depends on the edge's direction (a joint about one end's
        centre) overrides this to set its parameters from ``edge``.
        """
        return cls([edge.id], [reached])


class ParallelNode(KinematicNode):
    """Parallel robot kinematic node: edges that close cycles through the parent's ports."""

    family = "parallel"


def fade(r2: np.ndarray, epsilon: float) -> tuple[np.ndarray, np.ndarray]:
    """``f = r^2 / (r^2 + eps^2)`` and ``df / d(r^2)``: fades a term in as motion grows.

    Used for steering costs, which the paper's equations leave undefined at zero
    motion: below ``eps`` [rad] of motion the connector does not need to steer.
    """
    e2 = epsilon * epsilon
    denom = r2 + e2
    if e2 == 0.0:
        return np.where(r2 > 0, 1.0, 0.0), np.zeros_like(r2)
    return r2 / denom, e2 / (denom * denom)
