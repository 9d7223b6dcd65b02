"""MuJoCo pieces every freeform world shares: ground, switched equalities, sensor noise.

A freeform robot docks by switching equality constraints on and off at run time
(``data.eq_active``) rather than by rebuilding its model (FreeSN paper, section 6.1:
"the connection ... is simulated by an equality constraint"). :class:`Switches` keeps
the bookkeeping of such constraints by a key of the robot's choosing; :class:`SensorNoise`
is the seeded white noise of every reported angle; :func:`add_ground` the floor.
``mujoco`` is imported here at the top, so import this module only where a world is built.
"""

from __future__ import annotations

from collections.abc import Hashable, Iterable, Iterator
from typing import Any

import mujoco
import networkx as nx
import numpy as np
from scipy.spatial.transform import Rotation

__all__ = ["GROUND_FRICTION", "SensorNoise", "Switches", "add_ground", "connected_groups",
           "heading", "quat_conj",
           "quat_log", "quat_mul", "yaw_of"]

GROUND_FRICTION = (0.8, 0.02, 0.001)
"""Sliding, torsional and rolling friction of the floor and the module shells."""


def add_ground(spec: mujoco.MjSpec, *, friction: tuple[float, float, float] = GROUND_FRICTION,
               size: float = 10.0) -> None:
    """Add a plane at ``z = 0`` colliding with everything, and a light above it."""
    spec.worldbody.add_geom(name="ground", type=mujoco.mjtGeom.mjGEOM_PLANE,
                            size=[size, size, 0.1], friction=list(friction),
                            conaffinity=0x7FFFFFFF, rgba=[0.85, 0.85, 0.8, 1.0])
    spec.worldbody.add_light(pos=[0, 0, 3], dir=[0, 0, -1])


class Switches:
    """Equality constraints switched at run time, found by key.

    Declare each while building (:meth:`add`, inactive), then :meth:`bind` the compiled
    model; :meth:`on` and :meth:`off` flip ``data.eq_active``; :meth:`active` reads it
    back from the simulator.
    """

    def __init__(self) -> None:
        self._names: dict[Hashable, str] = {}
        self._ids: dict[Hashable, int] = {}

    def add(self, spec: mujoco.MjSpec, key: Hashable, name: str, **equality: Any) -> None:
        """Declare an inactive equality ``name`` (keyword arguments of ``add_equality``)."""
        spec.add_equality(name=name, active=False, **equality)
        self._names[key] = name

    def bind(self, model: mujoco.MjModel) -> None:
        """Resolve the declared names to equality ids of ``model``."""
        self._ids = {key: model.equality(name).id for key, name in self._names.items()}

    def id(self, key: Hashable) -> int:
        """The equality id of ``key``."""
        return self._ids[key]

    def on(self, data: mujoco.MjData, key: Hashable) -> int:
        """Activate ``key``'s equality; its id."""
        eq = self._ids[key]
        data.eq_active[eq] = 1
        return eq

    def off(self, data: mujoco.MjData, key: Hashable) -> None:
        """Deactivate ``key``'s equality."""
        data.eq_active[self._ids[key]] = 0

    def active(self, data: mujoco.MjData) -> Iterator[Hashable]:
        """Keys whose equality the simulator holds active now."""
        return (key for key, eq in self._ids.items() if data.eq_active[eq])


class SensorNoise:
    """Seeded white noise of reported rotations and directions.

    Args:
        std: standard deviation of every reported angle [rad] (0: exact readings).
        seed: seed of the generator.
    """

    def __init__(self, std: float, seed: int):
        self.std = float(std)
        self.rng = np.random.default_rng(seed)

    def rotation(self, rotation: np.ndarray) -> np.ndarray:
        """``rotation`` (3, 3) turned by a random small rotation (each axis ``std``)."""
        if not self.std:
            return rotation
        return Rotation.from_rotvec(self.rng.normal(0.0, self.std, 3)).as_matrix() @ rotation

    def vector(self, vector: np.ndarray) -> np.ndarray:
        """``vector`` (3,) turned by a random small rotation."""
        return self.rotation(np.eye(3)) @ vector


def heading(quat: np.ndarray) -> np.ndarray:
    """Yaw [rad] of the twist about world ``z`` of quaternions ``(w, x, y, z)``, (..., 4)
    (swing-twist decomposition: the twist is ``normalise(w, 0, 0, z)``)."""
    q = np.asarray(quat, dtype=np.float64)
    return 2.0 * np.arctan2(q[..., 3], q[..., 0])


def yaw_of(rotation: np.ndarray) -> float:
    """The yaw [rad] of the rotation about ``z`` nearest to ``rotation`` (3, 3) (Frobenius)."""
    return float(np.arctan2(rotation[1, 0] - rotation[0, 1], rotation[0, 0] + rotation[1, 1]))


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton products of quaternions ``(w, x, y, z)``, shape (n, 4)."""
    aw, ax, ay, az = a.T
    bw, bx, by, bz = b.T
    return np.column_stack([aw * bw - ax * bx - ay * by - az * bz,
                            aw * bx + ax * bw + ay * bz - az * by,
                            aw * by - ax * bz + ay * bw + az * bx,
                            aw * bz + ax * by - ay * bx + az * bw])


def quat_conj(q: np.ndarray) -> np.ndarray:
    """Conjugates (inverses of unit quaternions) ``(w, x, y, z)``, shape (n, 4)."""
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def quat_log(q: np.ndarray) -> np.ndarray:
    """Rotation vectors (n, 3) of unit quaternions (n, 4), angles in [0, pi]."""
    q = np.where(q[:, :1] < 0, -q, q)
    v = q[:, 1:]
    s = np.sqrt(np.einsum("ni,ni->n", v, v))
    angle = 2.0 * np.arctan2(s, q[:, 0])
    return v * np.where(s > 1e-12, angle / np.maximum(s, 1e-12), 2.0)[:, None]


def connected_groups(modules: Iterable[str], links: Iterable[tuple[str, str]]
                     ) -> list[frozenset[str]]:
    """The modules of each physically separate system, joined by ``links`` (docks), in
    the order of each group's first module in ``modules``."""
    graph = nx.Graph()
    graph.add_nodes_from(modules)
    graph.add_edges_from(links)
    return [frozenset(c) for c in nx.connected_components(graph)]
