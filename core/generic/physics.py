"""The generic ``mujoco`` driver: any robot whose module kinds declare bodies, in physics.

Built with ``MjSpec`` from the description alone (:mod:`msrr.core.bodies`), on the
MuJoCo world every freeform robot shares (:class:`~msrr.core.freeform.mujoco.MujocoWorld`:
ground, implicit integrator, servo loop, switched equalities, seeded noise):

* every module a free body of its declared shape and mass, under gravity, colliding
  with the floor and with every other module (self-collision);
* **wheeled** kinds (:class:`~msrr.core.robot.Wheels`) stand on two wheels on their y
  axis, velocity-servoed with bounded torque, and two frictionless casters;
  ``ModuleCommand.wheels = {"left": m/s, "right": m/s}`` sets the rim speeds;
* **docking** as equality constraints from a pool (one slot per pair of ports that can
  be docked at once), switched on at run time only when an armed port and a free port
  of another module are aligned within the robot's
  :class:`~msrr.core.robot.DockTolerance` (positions within ``position``, normals
  opposite and ``up`` equal within ``angle``): a weld at the exact docked pose for
  rigid ports; for a port with a :class:`~msrr.core.robot.Hinge`, two point
  constraints on the hinge axis (the axes parallel within ``angle``), leaving the
  joint free;
* **jointed** modules: each docked hinge is a position servo of bounded torque (the
  hinge's ``torque``, the setpoint moving at its ``speed``): a MuJoCo position actuator
  on a site transmission from the source port's site to the target port's, so its
  damping is integrated implicitly with the bodies (an explicit PD torque on bodies of a
  few grams' inertia rings at any useful gain: a chain of ten never settled) and its
  torque acts equal and opposite on the two bodies; ``ModuleCommand.joints = {hinge
  port: rad}`` sets the goal, which the servo keeps until told otherwise;
* **reports** (:class:`ModuleReading`): latched ports, each with the direction ``z`` to
  the other module that the module computes from its IMU, its encoder and its geometry;
  the joint encoder; the IMU's orientation, all with seeded noise (``noise`` [rad]).
  ``Observation.tracked`` holds a tracker's poses (``tracking`` [m] of noise).

The generic recognizer reads the reports only; :meth:`PhysicsWorld.ground_truth` (the
judge's) reads the simulator's equalities and bodies.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import mujoco
import networkx as nx
import numpy as np

from ..bodies import (
    FLIP,
    Frame,
    connection_hinge,
    docked_pose,
    hinge_angle,
    layout,
    port_frame,
    vector_angles,
)
from ..configuration import Configuration
from ..driver import Companions, DriverOption, ModuleCommand, Observation, Pose
from ..errors import ExecutionError
from ..freeform.mujoco import WELD_SOLIMP, WELD_SOLREF, MujocoOptions, MujocoWorld
from ..freeform.mujoco_driver import MujocoDriver
from ..robot import ModuleKind, RobotSpec
from .readings import Latch, ModuleReading

__all__ = ["PhysicsDriver", "PhysicsDriverFactory", "PhysicsOptions", "PhysicsWorld"]

WHEEL_WIDTH = 0.01
"""Width [m] of a wheel."""

WHEEL_ARMATURE = 1e-4
"""Rotor inertia [kg m^2] of a wheel's drive, reflected through its gear."""

WHEEL_GAIN = 1.0
"""A wheel's velocity loop gives its full torque at this fraction of its top speed off."""

SKIN = 0.0005
"""A box's collision shape is this much [m] smaller on each side than its body, so that
the faces of two docked boxes do not touch (a contact per corner every step for
nothing, while their weld holds them)."""

CLEARANCE = 0.002
"""Height [m] above the floor at which a start layout is released."""

SERVO_SPAN = 0.15
"""A hinge servo gives its full torque at this error [rad] from its setpoint."""

SERVO_DAMPING = 0.03
"""A hinge servo's damping per stiffness [s]."""

SERVO_STABLE = 0.3
"""A hinge servo's stiffness is at most this times the smaller principal inertia of its
two bodies over the timestep squared: its spring acts explicitly, and a body between
two stiffer servos rings and throws the chain apart (a ring of 30 at 5 N m did)."""


@dataclass(frozen=True, kw_only=True)
class PhysicsOptions(MujocoOptions):
    """The generic MuJoCo world's options (:class:`MujocoOptions` and a tracker).

    Attributes:
        tracking: standard deviation of the tracker's module positions [m].
    """

    OPTIONS: ClassVar[tuple[DriverOption, ...]] = (
        *MujocoOptions.OPTIONS,
        DriverOption("tracking", float, "standard deviation of tracked positions", "m",
                     0.0, 0.05),
    )
    noise: float = 0.002
    tracking: float = 0.0005

    def __post_init__(self) -> None:
        super().__post_init__()
        self._check(non_negative=("tracking",))


@dataclass
class _Slot:
    """One connection of the pool: its equalities and, when docked, what it joins."""

    weld: int
    points: tuple[int, int]
    servo: int = -1  # the hinge servo's actuator id (-1: the robot has no hinges)
    source: str = ""
    target: str = ""
    ports: tuple[str, str] = ("", "")
    hinge: np.ndarray | None = None  # axis in the source port frame, when a hinge
    goal: float = 0.0
    setpoint: float = 0.0

    @property
    def used(self) -> bool:
        return bool(self.source)


class PhysicsWorld(MujocoWorld[int, tuple[str, str]]):
    """One configuration of described modules in MuJoCo (see the module docstring).

    Args:
        spec: the robot's description; every vertex kind declares a body.
        start: the configuration, laid out from its ports (and its vectors' hinge angles).
        options: the run's options.
    """

    def __init__(self, spec: RobotSpec, start: Configuration, options: PhysicsOptions):
        super().__init__(options, seat=1.0)
        self.spec = spec
        self.tolerance = spec.defaults.dock_tolerance
        self.kinds = {v: spec.kind(start.kind_of(v)) for v in start.vertices(virtual=False)}
        missing = sorted(k.name for k in self.kinds.values() if k.body is None)
        if missing:
            raise ExecutionError(f"mujoco driver: module kind {missing[0]!r} of robot "
                                 f"{spec.name!r} declares no body (ModuleKind.body)")
        self.wheel_goals: dict[str, tuple[float, float]] = {}
        self.armed: set[tuple[str, str]] = set()
        poses = self._start_poses(start)
        mj = self.new_spec(spec.name)
        for module, (rotation, position) in poses.items():
            self._add_module(mj, module, rotation, position)
        self.slots = self._add_slots(mj)
        self.compile(mj)
        self.bodies = {m: self.model.body(m).id for m in self.kinds}
        self.sites = {(m, p.name): self.model.site(f"{m}/{p.name}").id
                      for m, k in self.kinds.items() for p in k.ports}
        self.model.site_sameframe[list(self.sites.values())] = 0  # set at each dock
        if any(k.hinge is not None for k in self.kinds.values()):
            for i, slot in enumerate(self.slots):
                slot.servo = self.model.actuator(f"dock{i}/servo").id
        self.actuators = {m: (self.model.actuator(f"{m}/left").id,
                              self.model.actuator(f"{m}/right").id)
                          for m, k in self.kinds.items() if k.wheels is not None}
        mujoco.mj_forward(self.model, self.data)
        for edge in start.edges():
            if edge.ports is not None and edge.source in self.kinds and edge.target in self.kinds:
                self._dock(edge.source, edge.ports[0], edge.target, edge.ports[1])
        self.events.clear()

    # -- building -----------------------------------------------------------------------

    def _start_poses(self, start: Configuration) -> dict[str, Frame]:
        """Each group laid out from its ports and hinge angles, on the floor, groups side
        by side along y."""
        angles = vector_angles(start, self.spec)
        poses, _ = layout(start, self.spec, angles)
        graph = nx.Graph()
        graph.add_nodes_from(poses)
        graph.add_edges_from((e.source, e.target) for e in start.edges() if e.ports is not None
                             and e.source in poses and e.target in poses)
        out: dict[str, Frame] = {}
        offset = 0.0
        for group in sorted(nx.connected_components(graph), key=lambda g: min(
                list(poses).index(v) for v in g)):
            low = {v: self._rest(v, poses[v][0]) for v in group}
            bottom = min(poses[v][1][2] - low[v] for v in group)
            ys = [poses[v][1][1] for v in group]
            size = max(max(self.kinds[v].body.half_extents) for v in group)
            shift = np.array([0.0, offset - min(ys) + size, CLEARANCE - bottom])
            out.update({v: (poses[v][0], poses[v][1] + shift) for v in group})
            offset = max(out[v][1][1] for v in group) + 3 * size
        return out

    def _rest(self, module: str, rotation: np.ndarray) -> float:
        """Height [m] of ``module``'s centre above its lowest point (wheels included)."""
        kind = self.kinds[module]
        half = np.asarray(kind.body.half_extents)
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1)
                            for sz in (-1, 1)]) * half
        low = -float(np.min((corners @ rotation.T)[:, 2]))
        if kind.wheels is not None:
            low += kind.wheels.radius / 2
        return low

    def _add_module(self, mj: mujoco.MjSpec, module: str, rotation: np.ndarray,
                    position: np.ndarray) -> None:
        kind = self.kinds[module]
        body = kind.body
        part = mj.worldbody.add_body(name=module, pos=position.tolist(),
                                     quat=_quat(rotation).tolist())
        part.add_freejoint(name=f"{module}/free")
        friction = [body.friction, 0.02, 0.001]  # its own against the floor: MuJoCo takes
        shell = {"friction": friction, "priority": 1}  # the higher priority's (else the max)
        along_x = [math.sqrt(0.5), 0.0, math.sqrt(0.5), 0.0]  # z axis turned onto x
        if body.shape == "box":  # a hair smaller: docked faces do not collide
            part.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX,
                          size=[s / 2 - SKIN for s in body.size], mass=body.mass, **shell)
        elif body.shape == "sphere":
            part.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[body.size[0], 0, 0],
                          mass=body.mass, **shell)
        else:
            shape = (mujoco.mjtGeom.mjGEOM_CAPSULE if body.shape == "capsule"
                     else mujoco.mjtGeom.mjGEOM_CYLINDER)
            part.add_geom(type=shape, size=[body.size[0], body.size[1] / 2, 0], quat=along_x,
                          mass=body.mass, **shell)
        for port in kind.ports:  # where a hinge servo measures and acts
            rotation, at = port_frame(kind, port.name)
            part.add_site(name=f"{module}/{port.name}", pos=at.tolist(),
                          quat=_quat(rotation).tolist())
        if kind.wheels is not None:
            self._add_wheels(mj, part, module, kind)

    def _add_wheels(self, mj: mujoco.MjSpec, part: Any, module: str, kind: ModuleKind) -> None:
        """Two velocity-servoed wheels on the body's y axis, casters fore and aft."""
        wheels, half = kind.wheels, kind.body.half_extents
        axle = -half[2] + wheels.radius / 2
        caster = wheels.radius / 2
        for x in (half[0] - caster, -half[0] + caster):
            part.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[caster, 0, 0],
                          pos=[x, 0.0, -half[2]], condim=1, priority=1, friction=[0.0, 0.0, 0.0],
                          mass=0.001, rgba=[0.3, 0.3, 0.3, 1])
        for side, y in (("left", wheels.track / 2), ("right", -wheels.track / 2)):
            wheel = part.add_body(name=f"{module}/{side}", pos=[0.0, y, axle])
            wheel.add_joint(name=f"{module}/{side}", type=mujoco.mjtJoint.mjJNT_HINGE,
                            axis=[0.0, 1.0, 0.0], armature=WHEEL_ARMATURE)
            wheel.add_geom(type=mujoco.mjtGeom.mjGEOM_CYLINDER,
                           size=[wheels.radius, WHEEL_WIDTH / 2, 0],
                           quat=[math.sqrt(0.5), math.sqrt(0.5), 0.0, 0.0], mass=0.01,
                           friction=[1.2, 0.02, 0.001], rgba=[0.1, 0.1, 0.1, 1])
            motor = mj.add_actuator(name=f"{module}/{side}", target=f"{module}/{side}",
                                    trntype=mujoco.mjtTrn.mjTRN_JOINT)
            motor.set_to_velocity(kv=WHEEL_GAIN * wheels.torque * wheels.radius / wheels.speed)
            motor.forcelimited = True
            motor.forcerange = [-wheels.torque, wheels.torque]

    def _add_slots(self, mj: mujoco.MjSpec) -> list[_Slot]:
        """The pool: as many slots as port pairs can be docked at once; each a weld, two
        axis points and, when a kind has a hinge, a servo (idle until docked)."""
        modules = list(self.kinds)
        count = sum(len(k.ports) for k in self.kinds.values()) // 2 if len(modules) > 1 else 0
        hinges = any(k.hinge is not None for k in self.kinds.values())
        # compiled between two bodies: MuJoCo sizes each servo's moment for their dofs
        sites = [f"{m}/{self.kinds[m].ports[0].name}" for m in modules[:2]]
        slots = []
        for i in range(count):
            for key, (name, kind) in enumerate(((f"dock{i}", mujoco.mjtEq.mjEQ_WELD),
                                                (f"dock{i}/p", mujoco.mjtEq.mjEQ_CONNECT),
                                                (f"dock{i}/q", mujoco.mjtEq.mjEQ_CONNECT)),
                                               start=3 * i):
                self.welds.add(mj, key, name, type=kind, objtype=mujoco.mjtObj.mjOBJ_BODY,
                               name1=modules[0], name2=modules[1], solref=list(WELD_SOLREF),
                               solimp=list(WELD_SOLIMP))
            slots.append(_Slot(3 * i, (3 * i + 1, 3 * i + 2)))
            if hinges:
                servo = mj.add_actuator(name=f"dock{i}/servo", trntype=mujoco.mjtTrn.mjTRN_SITE,
                                        target=sites[1], refsite=sites[0])
                servo.gear = [0.0, 0.0, 0.0, 0.0, 0.0, 1.0]
                servo.set_to_position(kp=0.0, kv=0.0)
                servo.forcelimited = True
                servo.forcerange = [-1.0, 1.0]  # the hinge's, set when docked
        return slots

    # -- docking ------------------------------------------------------------------------

    def _frame(self, module: str) -> Frame:
        body = self.bodies[module]
        return self.data.xmat[body].reshape(3, 3).copy(), self.data.xpos[body].copy()

    def _port_world(self, module: str, port: str) -> Frame:
        rotation, position = self._frame(module)
        pr, pp = port_frame(self.kinds[module], port)
        return rotation @ pr, rotation @ pp + position

    def _used_ports(self) -> set[tuple[str, str]]:
        return {end for s in self.slots if s.used
                for end in ((s.source, s.ports[0]), (s.target, s.ports[1]))}

    def _dock(self, source: str, source_port: str, target: str, target_port: str) -> None:
        """Switch on a free slot joining the two ports: a weld at the docked pose, or the
        hinge's two axis points (the angle as it is now)."""
        free = [s for s in self.slots if not s.used]
        if not free:
            raise ExecutionError("mujoco driver: no free dock slot (more docks than ports allow)")
        slot = free[0]
        kinds, ports = (self.kinds[source], self.kinds[target]), (source_port, target_port)
        slot.source, slot.target, slot.ports = source, target, ports
        slot.hinge = connection_hinge(kinds, ports)
        m = self.model
        a, b = self.bodies[source], self.bodies[target]
        if slot.hinge is None:
            rotation, position = docked_pose(kinds, ports)
            eq = self.welds.id(slot.weld)
            m.eq_obj1id[eq], m.eq_obj2id[eq] = a, b
            m.eq_data[eq, :3] = 0.0
            m.eq_data[eq, 3:6] = position
            m.eq_data[eq, 6:10] = _quat(rotation)
            m.eq_data[eq, 10] = 1.0
            self.welds.on(self.data, slot.weld)
        else:
            (ra, pa), (rs, ps) = port_frame(kinds[0], ports[0]), self._frame(source)
            rt, pt = self._frame(target)
            axis = ra @ slot.hinge
            half = 0.5 * min(self.kinds[source].body.half_extents)
            for key, sign in zip(slot.points, (1.0, -1.0), strict=True):
                point = pa + sign * half * axis  # source frame
                world = rs @ point + ps
                eq = self.welds.id(key)
                m.eq_obj1id[eq], m.eq_obj2id[eq] = a, b
                m.eq_data[eq, :3] = point
                m.eq_data[eq, 3:6] = rt.T @ (world - pt)
                self.welds.on(self.data, key)
            slot.goal = slot.setpoint = self._angle(slot)
            self._servo_on(slot)
        self.events.append(("dock", f"{source}{source_port}-{target}{target_port}"))

    def _undock(self, module: str, port: str) -> None:
        for slot in self.slots:
            if slot.used and (module, port) in ((slot.source, slot.ports[0]),
                                                (slot.target, slot.ports[1])):
                for key in (slot.weld, *slot.points):
                    self.welds.off(self.data, key)
                if slot.hinge is not None:
                    self._servo_gains(slot.servo, 0.0, 0.0)
                self.events.append(("undock", f"{slot.source}{slot.ports[0]}-"
                                    f"{slot.target}{slot.ports[1]}"))
                slot.source = slot.target = ""

    def _servo_on(self, slot: _Slot) -> None:
        """Point the slot's servo from the source port's site (its frame the port's) to the
        target port's (the port's turned onto the source's: their relative turn is the
        hinge angle about ``slot.hinge``) with the hinge's gains and torque bound."""
        m = self.model
        kinds = (self.kinds[slot.source], self.kinds[slot.target])
        source = self.sites[(slot.source, slot.ports[0])]
        target = self.sites[(slot.target, slot.ports[1])]
        m.site_quat[source] = _quat(port_frame(kinds[0], slot.ports[0])[0])
        m.site_quat[target] = _quat(port_frame(kinds[1], slot.ports[1])[0] @ FLIP)
        m.actuator_trnid[slot.servo] = (target, source)
        m.actuator_gear[slot.servo, 3:] = slot.hinge
        hinge = self._hinge_of(slot)
        inertia = float(np.min(m.body_inertia[[self.bodies[slot.source],
                                                self.bodies[slot.target]]]))
        gain = min(hinge.torque / SERVO_SPAN, SERVO_STABLE * inertia / m.opt.timestep ** 2)
        self._servo_gains(slot.servo, gain, SERVO_DAMPING * gain)
        m.actuator_forcerange[slot.servo] = (-hinge.torque, hinge.torque)
        self.data.ctrl[slot.servo] = slot.setpoint

    def _servo_gains(self, servo: int, stiffness: float, damping: float) -> None:
        """A position actuator's stiffness [N m/rad] and damping [N m s/rad] (0, 0: idle)."""
        m = self.model
        m.actuator_gainprm[servo, 0] = stiffness
        m.actuator_biasprm[servo, 1:3] = (-stiffness, -damping)

    def _angle(self, slot: _Slot) -> float:
        rs, _ = self._frame(slot.source)
        rt, _ = self._frame(slot.target)
        return hinge_angle(rs.T @ rt, (self.kinds[slot.source], self.kinds[slot.target]),
                           slot.ports)

    def _docking(self) -> bool:
        return bool(self.armed)

    def _check_docks(self) -> None:
        """Latch each armed port to a free port of another module aligned within the
        robot's dock tolerance."""
        used = self._used_ports()
        tol = self.tolerance
        for module, port in sorted(self.armed):
            if (module, port) in used:
                continue
            rot, pos = self._port_world(module, port)
            for other, kind in self.kinds.items():
                if other == module:
                    continue
                for spec in kind.ports:
                    if (other, spec.name) in used:
                        continue
                    orot, opos = self._port_world(other, spec.name)
                    if float(np.linalg.norm(opos - pos)) > tol.position:
                        continue
                    if self._aligned(module, port, other, spec.name, rot, orot):
                        self._dock(*self._directed(module, port, other, spec.name))
                        used = self._used_ports()
                        break
                else:
                    continue
                break

    def _aligned(self, module: str, port: str, other: str, other_port: str,
                 rot: np.ndarray, orot: np.ndarray) -> bool:
        limit = math.cos(self.tolerance.angle)
        axis = connection_hinge((self.kinds[module], self.kinds[other]), (port, other_port))
        if axis is not None:  # a hinge docks at any angle, its axes parallel
            return float((rot @ axis) @ (orot @ (FLIP @ axis))) >= limit
        return (float(rot[:, 0] @ -orot[:, 0]) >= limit
                and float(rot[:, 2] @ orot[:, 2]) >= limit)

    def _directed(self, module: str, port: str, other: str, other_port: str
                  ) -> tuple[str, str, str, str]:
        """The new connection from its active end (else from the armed end)."""
        mine = self.kinds[module].port(port).role
        theirs = self.kinds[other].port(other_port).role
        if theirs == "active" and mine != "active" or mine == "passive" and theirs != "passive":
            return other, other_port, module, port
        return module, port, other, other_port

    def _period_done(self, steps: int) -> None:
        """Docks are welded at their exact pose: nothing to seat."""

    # -- commanding ---------------------------------------------------------------------

    def command(self, commands: Mapping[str, ModuleCommand]) -> None:
        """Release, set wheel speeds and hinge goals, arm ports (see the module docstring).

        Raises:
            ExecutionError: an unknown module, wheel or joint, or a port the module lacks.
        """
        unknown = set(commands) - set(self.kinds)
        if unknown:
            raise ExecutionError(f"mujoco driver: commands for unknown module(s) "
                                 f"{sorted(unknown)}")
        self.armed = set()
        self.wheel_goals = {}
        for module, command in sorted(commands.items()):
            kind = self.kinds[module]
            names = {p.name for p in kind.ports}
            for port in (*command.undock, *command.dock):
                if port not in names:
                    raise ExecutionError(f"mujoco driver: module {module} has no port {port!r}")
            for port in command.undock:
                self._undock(module, port)
            self.armed |= {(module, port) for port in command.dock}
            if command.wheels:
                if kind.wheels is None or set(command.wheels) - {"left", "right"}:
                    raise ExecutionError(f"mujoco driver: module {module} has no wheels "
                                         f"{sorted(command.wheels)} (a wheeled kind has left "
                                         "and right)")
                limit = kind.wheels.speed
                self.wheel_goals[module] = tuple(  # type: ignore[assignment]
                    max(-limit, min(limit, float(command.wheels.get(s, 0.0))))
                    for s in ("left", "right"))
            for joint, goal in command.joints.items():
                self._joint_goal(module, joint, float(goal))

    def _joint_goal(self, module: str, joint: str, goal: float) -> None:
        hinge = self.kinds[module].hinge
        if hinge is None or joint != hinge.port:
            raise ExecutionError(f"mujoco driver: module {module} has no joint {joint!r} "
                                 "(a hinge is commanded by its port's name)")
        for slot in self.slots:
            if slot.used and slot.hinge is not None and (module, joint) in (
                    (slot.source, slot.ports[0]), (slot.target, slot.ports[1])):
                sign = 1.0 if slot.source == module else -1.0
                slot.goal = max(-hinge.limit, min(hinge.limit, sign * goal))

    def _servo(self) -> None:
        """Wheel velocity goals; each hinge's setpoint moved toward its goal at the hinge's
        speed (its servo holds it, see :meth:`_servo_on`)."""
        period = self._every * self.options.timestep
        for module, (left, right) in self.wheel_goals.items():
            radius = self.kinds[module].wheels.radius
            ids = self.actuators[module]
            self.data.ctrl[ids[0]], self.data.ctrl[ids[1]] = left / radius, right / radius
        for module, ids in self.actuators.items():
            if module not in self.wheel_goals:
                self.data.ctrl[ids[0]] = self.data.ctrl[ids[1]] = 0.0
        for slot in self.slots:
            if slot.used and slot.hinge is not None:
                step = self._hinge_of(slot).speed * period
                slot.setpoint += max(-step, min(step, slot.goal - slot.setpoint))
                self.data.ctrl[slot.servo] = slot.setpoint

    def _hinge_of(self, slot: _Slot) -> Any:
        source = self.kinds[slot.source]
        if source.hinge is not None and source.hinge.port == slot.ports[0]:
            return source.hinge
        return self.kinds[slot.target].hinge

    # -- reading ------------------------------------------------------------------------

    def reports(self) -> dict[str, ModuleReading]:
        """Each module's latches (with the direction it computes to the other module from
        its IMU, encoder and geometry), encoder and IMU, with the run's noise."""
        imu = {m: self.noise.rotation(self._frame(m)[0]) for m in self.kinds}
        latches: dict[str, list[Latch]] = {m: [] for m in self.kinds}
        joints: dict[str, dict[str, float]] = {m: {} for m in self.kinds}
        for slot in self.slots:
            if not slot.used:
                continue
            kinds = (self.kinds[slot.source], self.kinds[slot.target])
            angle = 0.0
            if slot.hinge is not None:
                angle = self._angle(slot) + float(self.rng.normal(0.0, self.noise.std))
                owner = slot.source if self._hinge_of(slot) is kinds[0].hinge else slot.target
                joints[owner][self._hinge_of(slot).port] = angle if owner == slot.source \
                    else -angle
            _, offset = docked_pose(kinds, slot.ports, angle)
            z = imu[slot.source] @ (offset / np.linalg.norm(offset))
            latches[slot.source].append(Latch(slot.ports[0], slot.target, slot.ports[1],
                                              tuple(float(c) for c in z)))
        out = {}
        for m, kind in self.kinds.items():
            out[m] = ModuleReading(kind.name, tuple(latches[m]), joints=joints[m],
                                   imu=tuple(float(q) for q in _quat(imu[m])))
        return out

    def tracked(self) -> dict[str, Pose]:
        """The tracker's module poses: positions and orientations with the run's noise."""
        out = {}
        for m in self.kinds:
            rotation, position = self._frame(m)
            w, x, y, z = _quat(self.noise.rotation(rotation))
            out[m] = Pose(position + self.rng.normal(0.0, self.options.tracking, 3),
                          np.array([x, y, z, w]))
        return out

    def ground_truth(self, *, name: str = "") -> Configuration:
        """The connections the active equalities hold, ``z`` from the bodies' centres."""
        config = Configuration(self.spec.name, name=name)
        for m, kind in self.kinds.items():
            config.add_module(m, kind.name)
        for slot in self.slots:
            if slot.used and self.data.eq_active[self.welds.id(
                    slot.weld if slot.hinge is None else slot.points[0])]:
                between = self._frame(slot.target)[1] - self._frame(slot.source)[1]
                config.connect(slot.source, slot.target, ports=slot.ports,
                               z=between / np.linalg.norm(between))
        return config

    def groups(self) -> list[frozenset[str]]:
        graph = nx.Graph()
        graph.add_nodes_from(self.kinds)
        graph.add_edges_from((s.source, s.target) for s in self.slots if s.used)
        return [frozenset(c) for c in nx.connected_components(graph)]


def _quat(rotation: np.ndarray) -> np.ndarray:
    """MuJoCo's quaternion (w, x, y, z) of a rotation matrix (3, 3)."""
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(rotation, dtype=float).reshape(-1))
    return quat


class PhysicsDriver(MujocoDriver[PhysicsWorld]):
    """The generic ``mujoco`` driver of one robot (see the module docstring)."""

    name = "mujoco"
    description = "MuJoCo physics from the robot's description (bodies, wheels, hinges, docks)"
    options_type = PhysicsOptions
    arguments = ("spec", "gui", "seed", "options")

    def __init__(self, spec: RobotSpec, **options: Any):
        super().__init__(**options)
        self.spec = spec

    def build(self, start: Configuration) -> PhysicsWorld:
        return PhysicsWorld(self.spec, start, self.sim_options)  # type: ignore[arg-type]

    def get_observation(self) -> Observation:
        """The modules' reports and the tracker's poses (the bodies' exact poses are the
        witness's)."""
        world = self._world()
        return Observation(time=world.time, sensors=world.reports(), tracked=world.tracked())

    def send_action(self, commands: Mapping[str, ModuleCommand]) -> None:
        self._world().command(commands)

    def constraint_events(self) -> dict[str, int]:
        events = self._world().events
        return {"dock": sum(e[0] == "dock" for e in events),
                "undock": sum(e[0] == "undock" for e in events)}


class PhysicsDriverFactory:
    """What the generic runtime registers through ``msrr_drivers`` for a robot whose
    kinds declare bodies: builds a :class:`PhysicsDriver`."""

    name = PhysicsDriver.name
    description = PhysicsDriver.description
    generic = True
    companions = Companions(recognizer="latches", controller="drive")
    layout = None
    options = PhysicsDriver.options

    def __init__(self, spec: RobotSpec):
        self.spec = spec

    def __call__(self, **options: Any) -> PhysicsDriver:
        return PhysicsDriver(self.spec, **options)
