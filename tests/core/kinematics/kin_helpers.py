"""Shared helpers of the kinematics tests: a tiny robot with its own joint modes.

The core kinematics is robot-agnostic, so its tests use a robot defined here rather
than a built-in plugin: ``stick`` is hubs (vertex modules) joined by rods (edge
modules carrying ``z`` and ``x``), with three node types whose equations are short
enough to check by hand:

* :class:`GimbalJoint` (default, ``dim 2``): ``R = Rot(a1, s1) Rot(a2, s2)`` about the
  rod's ``x`` (projected off ``z``) and ``z x a1``; moves ``z`` anywhere.
* :class:`TwistJoint` (``dim 1``): ``Rot(z, s)``; turns ``x`` and the subtree, never ``z``.
* :class:`BraceNode` (parallel, ``dim 1``): two rods from two parent ports to one hub
  turn together about the axis through the parent ports, ``z1 - z2``.

Every motion cost is ``|sigma|^2`` per rod.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from msrr.core import Configuration
from msrr.core.alignment import rot_z
from msrr.core.kinematics import (
    FixedNode,
    KinematicTree,
    KinematicTreeError,
    ModuleJointNode,
    NodeBatch,
    ParallelNode,
    default_tree,
)
from msrr.core.kinematics.rotations import cross, normalize, rodrigues
from msrr.core.random_configurations import random_configuration
from msrr.core.robot import DockingRules, ModuleKind, Robot, RobotDefaults, RobotSpec

_EYE = np.eye(3)


class GimbalJoint(ModuleJointNode):
    """Two revolute axes in series: ``a1`` = ``x`` projected off ``z``, then ``z x a1``."""

    name = "gimbal"
    dim = 2
    controller = "test"
    defaults = {"bound": 2.5}

    @classmethod
    def prepare(cls, z, x, params):
        z1, x1 = z[:, 0], x[:, 0]
        a1 = normalize(x1 - np.einsum("ni,ni->n", x1, z1)[:, None] * z1)[0]
        return a1, cross(z1, a1)

    @classmethod
    def evaluate(cls, z, x, sigma, params, n_ports, derivatives, context=None):
        a1, a2 = context if context is not None else cls.prepare(z, x, params)
        r1 = rodrigues(a1, sigma[:, 0])
        rot = r1 @ rodrigues(a2, sigma[:, 1])
        zj = np.einsum("nab,nb->na", rot, z[:, 0])
        xj = np.einsum("nab,nb->na", rot, x[:, 0])
        out = NodeBatch(zj[:, None], xj[:, None], np.sum(sigma * sigma, axis=1)[:, None],
                        rot[:, None])
        if derivatives:
            omega = np.stack([a1, np.einsum("nab,nb->na", r1, a2)], axis=-1)   # (N, 3, 2)
            out.omega = omega[:, None]
            out.dz = np.stack([cross(omega[..., i], zj) for i in range(2)], axis=-1)[:, None]
            out.dx = np.stack([cross(omega[..., i], xj) for i in range(2)], axis=-1)[:, None]
            out.dcost = (2.0 * sigma)[:, None]
        return out


class TwistJoint(ModuleJointNode):
    """Rotation by ``sigma`` about the rod's own ``z``: ``z`` stays, ``x`` and the subtree turn."""

    name = "twist"
    dim = 1
    controller = "test"
    defaults = {"bound": 3.0}

    @classmethod
    def evaluate(cls, z, x, sigma, params, n_ports, derivatives, context=None):
        axis = z[:, 0]
        rot = rodrigues(axis, sigma[:, 0])
        xj = np.einsum("nab,nb->na", rot, x[:, 0])
        out = NodeBatch(z.copy(), xj[:, None], (sigma * sigma), rot[:, None])
        if derivatives:
            out.omega = axis[:, None, :, None]
            out.dz = np.zeros((len(z), 1, 3, 1))
            out.dx = cross(axis, xj)[:, None, :, None]
            out.dcost = (2.0 * sigma)[:, None]
        return out


class BraceNode(ParallelNode):
    """Two rods from two ports of the parent to one hub, turning about ``z1 - z2``."""

    name = "brace"
    dim = 1
    controller = "test"
    defaults = {"bound": 1.5}

    def validate(self) -> None:
        if len(self.edges) != 2 or len(self.vertices) != 1:
            raise KinematicTreeError("a brace has two edges and one vertex")

    @classmethod
    def evaluate(cls, z, x, sigma, params, n_ports, derivatives, context=None):
        axis = normalize(z[:, 0] - z[:, 1])[0]
        rot = rodrigues(axis, sigma[:, 0])
        zj = np.einsum("nab,nmb->nma", rot, z)
        xj = np.einsum("nab,nmb->nma", rot, x)
        cost = np.repeat(sigma * sigma, 2, axis=1)
        out = NodeBatch(zj, xj, cost, rot[:, None])
        if derivatives:
            out.omega = axis[:, None, :, None]
            out.dz = cross(axis[:, None], zj)[..., None]
            out.dx = cross(axis[:, None], xj)[..., None]
            out.dcost = np.repeat(2.0 * sigma, 2, axis=1)[..., None]
        return out


HUB = ModuleKind("hub", "H", "vertex", geometry={"mass": 1.0},
                 description="a ball the rods attach to")
ROD = ModuleKind("rod", "R", "edge", geometry={"length": 0.5, "mass": 0.2},
                 description="a rod with a joint at its parent end")
SPEC = RobotSpec("stick", "Stick", (HUB, ROD), defaults=RobotDefaults(joint_mode="gimbal"),
                 description="the kinematics tests' robot")
STICK = Robot(SPEC, DockingRules(), {"fixed": FixedNode, "gimbal": GimbalJoint,
                                     "twist": TwistJoint, "brace": BraceNode})


def stick_tree(config: Configuration, mode: type[ModuleJointNode] = GimbalJoint,
               **kwargs) -> KinematicTree:
    """The default tree of a stick configuration with joint class ``mode``."""
    return default_tree(config, mode, **kwargs)


def random_stick(n_edges: int, seed: int, *, free: int = 0, with_x: bool = True,
                 extra: int = 0) -> Configuration:
    """A random tree-shaped stick configuration with ``n_edges`` rods (``extra`` close cycles)."""
    rng = np.random.default_rng(seed)
    config = random_configuration(SPEC, STICK.rules, n_edges + 1 - free, rng,
                                  free_connectors=free, extra_edges=extra)
    return config if with_x else config.with_vectors(x={})


def chain(n: int) -> Configuration:
    """H1 - H2 - ... - H(n+1), rods R1..Rn along x."""
    config = Configuration("stick", name=f"chain{n}")
    for i in range(n + 1):
        config.add_module(f"H{i + 1}", "hub")
    for i in range(n):
        config.connect(f"H{i + 1}", f"H{i + 2}", id=f"R{i + 1}", kind="rod", z=[1, 0, 0])
    return config


def triangle_leg() -> Configuration:
    """A triangle H1 H2 H3 (rods R1-R3, a cycle) with a leg R4 from H1 to a free end v1."""
    s = np.sqrt(3) / 2
    config = Configuration("stick", name="triangle-leg")
    for v in ("H1", "H2", "H3"):
        config.add_module(v, "hub")
    config.add_virtual("v1")
    config.connect("H1", "H2", id="R1", kind="rod", z=[1, 0, 0])
    config.connect("H2", "H3", id="R2", kind="rod", z=[-0.5, s, 0])
    config.connect("H3", "H1", id="R3", kind="rod", z=[-0.5, -s, 0])
    config.connect("H1", "v1", id="R4", kind="rod", z=[0, 0, -1])
    return config


def yawed(config: Configuration, yaw: float) -> Configuration:
    """``config`` as seen from a horizontal frame turned by ``-yaw``: vectors turned by ``yaw``."""
    r = rot_z(yaw)
    return config.with_vectors(z={e.id: r @ e.z for e in config.edges()},
                               x={e.id: r @ e.x for e in config.edges() if e.x is not None})


def central_difference(f: Callable[[np.ndarray], np.ndarray], x: np.ndarray,
                       h: float = 1e-6) -> np.ndarray:
    """Central differences of array-valued ``f`` at ``x``; the last axis is the parameter."""
    columns = []
    for i in range(len(x)):
        e = np.zeros_like(x)
        e[i] = h
        columns.append((np.asarray(f(x + e)) - np.asarray(f(x - e))) / (2 * h))
    return np.stack(columns, axis=-1)


def relative_error(analytic: np.ndarray, numeric: np.ndarray) -> float:
    scale = max(float(np.linalg.norm(numeric)), float(np.linalg.norm(analytic)), 1e-12)
    return float(np.linalg.norm(np.asarray(analytic) - numeric)) / scale


def random_units(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` random unit vectors as columns, shape (3, n)."""
    v = rng.normal(size=(3, n))
    return v / np.linalg.norm(v, axis=0)
