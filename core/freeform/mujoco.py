"""What every MuJoCo world of freeform modules shares (FreeBOT, SnailBot and FreeSN).

A freeform robot docks by switching weld equality constraints on and off at run time
(``data.eq_active``) rather than by rebuilding its model (FreeSN paper, section 6.1:
"the connection ... is simulated by an equality constraint"):

* :class:`MujocoWorld` -- the base of such a world: its options (:class:`MujocoOptions`),
  the model built on :meth:`~MujocoWorld.new_spec` (ground, implicit integrator), the step
  loop with its servo period, docking and undocking by weld (:meth:`~MujocoWorld.weld`,
  a fresh dock drawn onto the target's centre), the constraint events, time, poses and
  the residual of the active welds. A robot's world adds its bodies, drives, reports
  and ground truth;
* :class:`MujocoDriver` -- the :class:`~msrr.core.driver.Driver` over a
  :class:`MujocoWorld`: options with keyword overrides, the world built at each reset,
  the viewer, observation, time and ground truth;
* :class:`Switches` -- equality constraints switched at run time, found by key;
  :class:`SensorNoise` -- the seeded white noise of every reported angle;
  :func:`add_ground`, headings and quaternion helpers.

``mujoco`` is imported here at the top, so import this module only where a world is built.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Hashable, Iterable, Iterator, Mapping
from dataclasses import MISSING, dataclass, fields, replace
from typing import Any, ClassVar, Generic, TypeVar

import mujoco
import networkx as nx
import numpy as np
from scipy.spatial.transform import Rotation

from ..configuration import Configuration
from ..driver import DriverOption
from ..errors import ExecutionError

__all__ = ["GROUND_FRICTION", "MujocoOptions", "MujocoWorld", "SensorNoise",
           "Switches", "add_ground", "connected_groups", "heading", "quat_conj", "quat_log",
           "quat_mul", "yaw_of"]

K = TypeVar("K", bound=Hashable)
"""Key of a switched constraint (a world's connection: ``(module, target)``, ...)."""
E = TypeVar("E")
"""A world's constraint event."""

GROUND_FRICTION = (0.8, 0.02, 0.001)
"""Sliding, torsional and rolling friction of the floor and the module shells."""


def add_ground(spec: mujoco.MjSpec, *, friction: tuple[float, float, float] = GROUND_FRICTION,
               size: float = 10.0) -> None:
    """Add a plane at ``z = 0`` colliding with everything, and a light above it."""
    spec.worldbody.add_geom(name="ground", type=mujoco.mjtGeom.mjGEOM_PLANE,
                            size=[size, size, 0.1], friction=list(friction),
                            conaffinity=0x7FFFFFFF, rgba=[0.85, 0.85, 0.8, 1.0])
    spec.worldbody.add_light(pos=[0, 0, 3], dir=[0, 0, -1])


class Switches(Generic[K]):
    """Equality constraints switched at run time, found by key.

    Declare each while building (:meth:`add`, inactive), then :meth:`bind` the compiled
    model; :meth:`on` and :meth:`off` flip ``data.eq_active``; :meth:`active` reads it
    back from the simulator. A key may be a slot of a pool rather than one pair of
    bodies: :meth:`attach` points its equality at the two bodies it joins now.
    MuJoCo reads ``eq_obj1id``, ``eq_obj2id`` and ``eq_data`` afresh at every step
    (``mj_instantiateEquality``; the islands and sleeping trees too, through
    ``body_treeid``), and nothing the compiler derives depends on them, so both may
    change between steps (``eq_data`` "has no side effects", MuJoCo issue #1404).
    """

    def __init__(self) -> None:
        self._names: dict[K, str] = {}
        self._ids: dict[K, int] = {}
        self._all = np.zeros(0, dtype=int)

    def add(self, spec: mujoco.MjSpec, key: K, name: str, **equality: Any) -> None:
        """Declare an inactive equality ``name`` (keyword arguments of ``add_equality``)."""
        spec.add_equality(name=name, active=False, **equality)
        self._names[key] = name

    def bind(self, model: mujoco.MjModel) -> None:
        """Resolve the declared names to equality ids of ``model``."""
        self._ids = {key: model.equality(name).id for key, name in self._names.items()}
        self._all = np.array(list(self._ids.values()), dtype=int)

    def id(self, key: K) -> int:
        """The equality id of ``key``."""
        return self._ids[key]

    def on(self, data: mujoco.MjData, key: K) -> int:
        """Activate ``key``'s equality; its id."""
        eq = self._ids[key]
        data.eq_active[eq] = 1
        return eq

    def attach(self, model: mujoco.MjModel, key: K, body1: int, body2: int) -> int:
        """Point ``key``'s equality at bodies ``body1`` and ``body2``; its id."""
        eq = self._ids[key]
        model.eq_obj1id[eq], model.eq_obj2id[eq] = body1, body2
        return eq

    def off(self, data: mujoco.MjData, key: K) -> None:
        """Deactivate ``key``'s equality."""
        data.eq_active[self._ids[key]] = 0

    def active(self, data: mujoco.MjData) -> Iterator[K]:
        """Keys whose equality the simulator holds active now."""
        return (key for key, eq in self._ids.items() if data.eq_active[eq])

    def active_ids(self, data: mujoco.MjData) -> np.ndarray:
        """Equality ids (n,) of the active ones, in declaration order."""
        return self._all[data.eq_active[self._all] != 0]


class SensorNoise:
    """Seeded white noise of reported rotations and directions.

    Args:
        std: standard deviation of every reported angle [rad] (0: exact readings).
        seed: seed of the generator, or a generator to draw from (shared with other
            noise of the world, such as odometry slip).
    """

    def __init__(self, std: float, seed: int | np.random.Generator):
        self.std = float(std)
        self.rng = np.random.default_rng(seed)

    def rotation(self, rotation: np.ndarray) -> np.ndarray:
        """``rotation`` (3, 3) turned by a random small rotation (each axis ``std``)."""
        if not self.std:
            return rotation
        return Rotation.from_rotvec(self.rng.normal(0.0, self.std, 3)).as_matrix() @ rotation

    def rotations(self, rotations: np.ndarray) -> np.ndarray:
        """Each of ``rotations`` (n, 3, 3) turned as :meth:`rotation` would, one after
        another (the same draws, to the bit)."""
        if not self.std:
            return rotations
        draws = self.rng.normal(0.0, self.std, (len(rotations), 3))
        return Rotation.from_rotvec(draws).as_matrix() @ rotations

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


def yaws_of(rotations: np.ndarray) -> np.ndarray:
    """:func:`yaw_of` of each of ``rotations`` (n, 3, 3), shape (n,): the same bits."""
    r = rotations
    return np.arctan2(r[:, 1, 0] - r[:, 0, 1], r[:, 0, 0] + r[:, 1, 1])


_TERMS = np.array([[0, 1, 2, 3], [1, 0, 3, 2], [2, 3, 0, 1], [3, 2, 1, 0]])
"""Hamilton product: term ``i`` of component ``c`` is ``a_i b_TERMS[i, c]``, signed by
``_SIGNS[i, c]``."""
_SIGNS = np.array([[1.0, 1.0, 1.0, 1.0], [-1.0, 1.0, -1.0, 1.0], [-1.0, 1.0, 1.0, -1.0],
                   [-1.0, -1.0, 1.0, 1.0]])
_FEW = 48
"""Up to this many products (of one shape), the terms are gathered in one array: fewer
numpy calls."""


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton products of quaternions ``(w, x, y, z)``, shape (n, 4). Each component
    sums its four terms in one order, ``((t0 + t1) + t2) + t3``, whichever way it runs
    (a sign flip and ``x - y = x + (-y)`` are exact): the same bits."""
    if a.shape == b.shape and a.ndim == 2 and len(a) <= _FEW:
        t = np.take(b, _TERMS, axis=1)
        t *= a[:, :, None]
        t *= _SIGNS
        out = t[:, 0] + t[:, 1]
        out += t[:, 2]
        out += t[:, 3]
        return out
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


WELD_SOLREF = (0.004, 1.0)
"""Time constant [s] and damping ratio of a dock weld (stiff: a magnet holds its module)."""
WELD_SOLIMP = (0.99, 0.999, 0.001, 0.5, 2.0)
"""Impedance of a dock weld (MuJoCo ``solimp``)."""


@dataclass(frozen=True, kw_only=True)
class MujocoOptions:
    """How one MuJoCo world runs: what every robot's options hold (a robot's own options
    subclass it and add theirs).

    Attributes:
        timestep: physics step [s].
        noise: standard deviation of every reported angle [rad].
        position_gain: drive position loop gain [1/s].
        servo_rate: rate of the drive loops [Hz].
        seed: seed of the world's noise.

    Raises:
        ExecutionError: a value out of range (the message names the option).
    """

    OPTIONS: ClassVar[tuple[DriverOption, ...]] = (
        DriverOption("timestep", float, "physics step", "s", 1e-4, 0.05),
        DriverOption("noise", float, "standard deviation of every reported angle", "rad",
                     0.0, math.pi / 2),
        DriverOption("position_gain", float, "drive position loop gain", "1/s", 0.0, 1000.0,
                     low_open=True),
        DriverOption("servo_rate", float, "rate of the drive loops", "Hz", 1.0, 10_000.0),
    )
    """The fields a run may set with ``--driver-option`` (every field but ``seed``, set by
    ``--seed``), with their bounds; a subclass adds its own."""

    timestep: float = 0.002
    noise: float = 0.0
    position_gain: float = 8.0
    servo_rate: float = 250.0
    seed: int = 0

    @classmethod
    def driver_options(cls) -> tuple[DriverOption, ...]:
        """:attr:`OPTIONS` with each field's default filled in (a driver's ``options``)."""
        defaults = {f.name: f.default for f in fields(cls) if f.default is not MISSING}
        return tuple(replace(o, default=defaults.get(o.name)) for o in cls.OPTIONS)

    def __post_init__(self) -> None:
        self._check(positive=("timestep", "position_gain", "servo_rate"), non_negative=("noise",))

    def _check(self, *, positive: Iterable[str] = (), non_negative: Iterable[str] = ()) -> None:
        """Refuse options named in ``positive`` that are not > 0, and in ``non_negative``
        that are < 0."""
        for name in positive:
            if not getattr(self, name) > 0:
                raise ExecutionError(f"simulation option {name} must be positive, "
                                     f"got {getattr(self, name)}")
        for name in non_negative:
            if getattr(self, name) < 0:
                raise ExecutionError(f"simulation option {name} must be >= 0, "
                                     f"got {getattr(self, name)}")


class MujocoWorld(ABC, Generic[K, E]):
    """One configuration of freeform modules in MuJoCo whose connections are welds
    switched at run time: what every such world shares.

    A subclass builds in its constructor: ``super().__init__(options, seat=...)``; a spec
    from :meth:`new_spec` with its bodies and one :meth:`add_weld` per connection that
    may form; :meth:`compile`; ``bodies`` (the body of each module's pose); then it
    docks its starting connections with :meth:`weld`. It drives its motors in
    :meth:`_servo` (at the start of each servo period), latches armed connectors in
    :meth:`_check_docks` (after each physics step while :meth:`_docking`), and reports
    (:meth:`reports`, :meth:`ground_truth`, :meth:`groups`); :meth:`_before_step`,
    :meth:`_period_done` and :meth:`_after_step` let it add to the step loop.

    Args:
        options: the run's options.
        seat: time constant [s] of a fresh dock drawing its body onto the target's centre.

    Attributes:
        model, data: the compiled model and its state.
        welds: the dock constraints by key (a connection of the world).
        bodies: module id -> the body whose pose is the module's pose.
        events: constraint events in the order they happened.
        time: simulated time [s].
        rng: the world's generator; ``noise`` (sensor noise) draws from it.
    """

    model: mujoco.MjModel
    data: mujoco.MjData

    def __init__(self, options: MujocoOptions, *, seat: float):
        self.options = options
        self.rng = np.random.default_rng(options.seed)
        self.noise = SensorNoise(options.noise, self.rng)
        self.welds: Switches[K] = Switches()
        self.bodies: dict[str, int] = {}
        self.events: list[E] = []
        self.time = 0.0
        self._reported = 0
        self._seat_time = seat
        self._every = max(1, round(1.0 / (options.servo_rate * options.timestep)))
        """Physics steps per servo period."""

    # -- building -----------------------------------------------------------------------

    def new_spec(self, name: str) -> mujoco.MjSpec:
        """An ``MjSpec`` named ``name`` with the run's timestep, the implicit-fast
        integrator (the motors' back-EMF damping integrated implicitly) and the ground."""
        spec = mujoco.MjSpec()
        spec.modelname = name
        spec.option.timestep = self.options.timestep
        spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
        add_ground(spec)
        return spec

    def add_weld(self, spec: mujoco.MjSpec, key: K, name: str, body: str, onto: str) -> None:
        """Declare the (inactive) dock weld ``key`` of body ``body`` onto body ``onto``."""
        self.welds.add(spec, key, name, type=mujoco.mjtEq.mjEQ_WELD,
                       objtype=mujoco.mjtObj.mjOBJ_BODY, name1=body, name2=onto,
                       solref=list(WELD_SOLREF), solimp=list(WELD_SOLIMP))

    def compile(self, spec: mujoco.MjSpec) -> None:
        """Compile ``spec`` into ``model`` and ``data``; bind the welds."""
        self.model = spec.compile()
        self.welds.bind(self.model)
        self.data = mujoco.MjData(self.model)

    # -- docking ------------------------------------------------------------------------

    def weld(self, key: K, body: int, onto: int) -> int:
        """Switch on ``key``'s weld, holding ``body`` to ``onto`` as the two are now; its
        equality id. The weld is pointed at the two bodies (a slot of a pool may join
        any pair; a weld declared for this pair keeps its bodies). The anchor is
        ``onto``'s centre: the magnet then draws ``body``'s origin onto it (:meth:`_seat`)
        instead of snapping it there."""
        d = self.data
        self.welds.attach(self.model, key, body, onto)
        eq = self.welds.on(d, key)
        rel, inv = np.empty(4), np.empty(4)
        mujoco.mju_negQuat(inv, d.xquat[body])
        mujoco.mju_mulQuat(rel, inv, d.xquat[onto])
        data = self.model.eq_data[eq]
        data[:3] = 0.0       # anchor: the centre of ``onto``
        data[3:6] = d.xmat[body].reshape(3, 3).T @ (d.xpos[onto] - d.xpos[body])
        data[6:10] = rel     # relpose: the relative orientation now
        data[10] = 1.0       # torque scale
        return eq

    def _seat(self, duration: float) -> None:
        """Draw fresh docks onto their targets' centres (time constant ``seat``)."""
        active = self.welds.active_ids(self.data)
        if len(active):
            offsets = self.model.eq_data[active, 3:6]
            if np.any(offsets):
                self.model.eq_data[active, 3:6] = offsets * max(
                    0.0, 1.0 - duration / self._seat_time)

    # -- stepping -----------------------------------------------------------------------

    def step(self, duration: float) -> None:
        """Advance by ``duration`` [s] (whole physics steps, at least one): the drives
        servo at the start of each servo period, fresh docks seat at its end, armed
        connectors latch after every physics step."""
        self._before_step()
        timestep, every = self.options.timestep, self._every
        n = max(1, round(duration / timestep))
        for i in range(n):
            if i % every == 0:
                self._servo()
            mujoco.mj_step(self.model, self.data)
            self.time += timestep
            if i % every == every - 1 or i == n - 1:
                self._period_done(min(every, i % every + 1))
            if self._docking():
                self._check_docks()
        self._after_step(n * timestep)

    def _before_step(self) -> None:
        """Called once before the physics steps of :meth:`step`."""

    @abstractmethod
    def _servo(self) -> None:
        """The drives' loops: the torques they apply until the next servo period."""

    def _period_done(self, steps: int) -> None:
        """Called at the end of each servo period (or of :meth:`step`), ``steps`` physics
        steps long."""
        self._seat(steps * self.options.timestep)

    @abstractmethod
    def _docking(self) -> bool:
        """Whether a connector is armed to dock (then :meth:`_check_docks` runs)."""

    @abstractmethod
    def _check_docks(self) -> None:
        """Latch armed connectors that reach their target."""

    def _after_step(self, duration: float) -> None:
        """Called once after the physics steps of :meth:`step`, ``duration`` [s] long."""

    # -- reading ------------------------------------------------------------------------

    def new_events(self) -> list[E]:
        """Constraint events since the previous call (a module reports each once)."""
        new = self.events[self._reported:]
        self._reported = len(self.events)
        return new

    def poses(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """World pose of every module's body: ``(position (3,), quaternion (x, y, z, w))``."""
        d = self.data
        out = {}
        for module, body in self.bodies.items():
            w, x, y, z = d.xquat[body]
            out[module] = (d.xpos[body].copy(), np.array([x, y, z, w]))
        return out

    def docked_pairs(self) -> set[Hashable]:
        """The connection every active dock weld makes (simulator state, :meth:`_joins`)."""
        return {self._joins(key) for key in self.welds.active(self.data)}

    def _joins(self, key: K) -> Hashable:
        """The connection the active weld ``key`` makes: the key itself, for a weld
        declared per connection; a pool's slot reads the bodies it holds."""
        return key

    def constraint_residual(self) -> float:
        """Largest distance [m] between a welded body and its target's centre."""
        d, m = self.data, self.model
        worst = 0.0
        for eq in self.welds.active_ids(d):
            gap = d.xpos[m.eq_obj1id[eq]] - d.xpos[m.eq_obj2id[eq]]
            worst = max(worst, float(np.linalg.norm(gap)))
        return worst

    @abstractmethod
    def reports(self) -> Mapping[str, object]:
        """Every module's report, with the run's noise; events since the previous call."""

    @abstractmethod
    def ground_truth(self, *, name: str = "") -> Configuration:
        """The configuration the bodies form (simulator state, never reports)."""

    @abstractmethod
    def groups(self) -> list[frozenset[str]]:
        """Modules of each physically separate system (connected through docks)."""
