"""The kinematic driver: an ideal world that needs no physics model.

Modules are rigid bodies with planar poses (:mod:`~msrr.core.generic.geometry`). A
module commanded to a pose goes there in a straight line at a bounded speed and turn
rate, carrying every module latched to it (its group moves rigidly); ports latch when
commanded and aligned within a tolerance, and release when commanded. It is
collision-aware: a step that would make two bodies overlap (their inscribed balls
intersect) is refused with an :class:`~msrr.core.errors.ExecutionError` naming the two
modules, and so is a start whose bodies overlap.

**Commands** (:class:`~msrr.core.driver.ModuleCommand`):

* ``joints={"x": m, "y": m, "z": m, "yaw": rad}`` -- the pose target of the module
  (missing keys keep the current value); one commanded module per group leads it;
* ``joints={"slide_x": .., "slide_y": .., "slide_z": ..}`` -- a *slide*: a module
  whose one link is a contact (no port normals: FreeBOT, SnailBot) moves alone over
  the surface of the module it rests on, its direction from that module's centre
  turning toward this unit vector (world frame) along a great circle at the bounded
  speed, contact kept; the link stays latched and its sensed ``z`` turns with it
  (a flow's first phase, see :mod:`msrr.core.executor`);
* ``dock=(port, ...)`` arms ports: a port latches to a free port of another module
  whose position is within ``tolerance`` and whose normal is opposite; a connector
  without ports is named ``"@<other module>"`` and latches when the two bodies touch;
* ``undock=(port, ...)`` (or ``"@<other module>"``; ``"a"``/``"b"`` for the ends of a
  connection that is a module) releases.

**Observation.** ``tracked``: the pose of every vertex module (the generic runtime's
modules are tracked by an external pose sensor, exact here; :meth:`KinematicDriver.witness`
gives the judge the same poses); ``sensors`` maps every module id (edge modules too) to a
:class:`ModuleReading`: its kind and the :class:`Latch` es it is the source of, each with
the sensed direction ``z`` (unit, world frame, from this module to the other).

Edge modules (FreeSN struts) have no body here: their ends stay where the start puts
them and can be released, but not docked (the generic planner does not plan them).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

import networkx as nx
import numpy as np

from ..configuration import Configuration
from ..driver import Companions, Driver, DriverOption, ModuleCommand, Observation, Pose
from ..errors import ExecutionError
from ..robot import ModuleKind, RobotSpec, body_half_size
from ..witness import Witness
from .geometry import (
    BodyPose,
    contact_distance,
    contact_reach,
    inscribed_radius,
    place_for_contact,
    place_for_ports,
    port_frame,
    rotate_z,
    slide_toward,
    wrap_angle,
)
from .readings import FREEFORM_PREFIX, SLIDE_KEYS, Latch, ModuleReading

__all__ = ["DEFAULT_SPEED", "DEFAULT_TOLERANCE", "DEFAULT_TURN_RATE", "FREEFORM_PREFIX",
           "SLIDE_KEYS", "KinematicDriver", "KinematicDriverFactory", "Latch", "ModuleReading"]

DEFAULT_SPEED = 0.5
"""Largest speed [m/s] of a commanded module (and its group)."""

DEFAULT_TURN_RATE = 2.0
"""Largest turn rate [rad/s] about z."""

DEFAULT_TOLERANCE = 0.005
"""Largest distance [m] between two ports (or from touching, for contact) that latch."""

ANGLE_TOLERANCE = 0.05
"""Largest angle [rad] between one port's normal and the other's reversed that latch."""

POSE_KEYS = ("x", "y", "z", "yaw")


@dataclass
class _Link:
    source: str
    target: str
    source_port: str | None
    target_port: str | None
    z: np.ndarray | None = None

    def ends(self) -> tuple[tuple[str, str | None], tuple[str, str | None]]:
        return (self.source, self.source_port), (self.target, self.target_port)


@dataclass
class _Strut:
    kind: str
    ends: dict[str, str | None] = field(default_factory=dict)  # "a"/"b" -> vertex or None
    z: np.ndarray | None = None


def _unit(v: np.ndarray) -> np.ndarray:
    return v / max(float(np.linalg.norm(v)), 1e-12)


class KinematicDriver(Driver):
    """The ideal kinematic world of one robot (see the module docstring).

    Args:
        spec: the robot's description (module kinds, ports, geometry).
        speed: largest module speed [m/s].
        turn_rate: largest turn rate [rad/s].
        tolerance: latch distance [m].
        gui: must be false (no viewer; the rerun timeline shows the run).
        seed: unused (the world is deterministic); kept for the factory interface.
    """

    name = "kinematic"
    description = "ideal kinematic world: bounded-speed rigid moves, latching within tolerance"
    options: ClassVar[tuple[DriverOption, ...]] = (
        DriverOption("speed", float, "largest module speed", "m/s", 0.0, 100.0, low_open=True,
                     default=DEFAULT_SPEED),
        DriverOption("turn_rate", float, "largest turn rate", "rad/s", 0.0, 100.0,
                     low_open=True, default=DEFAULT_TURN_RATE),
        DriverOption("tolerance", float, "latch distance", "m", 0.0, 1.0, low_open=True,
                     default=DEFAULT_TOLERANCE),
    )

    def __init__(self, spec: RobotSpec, *, speed: float = DEFAULT_SPEED,
                 turn_rate: float = DEFAULT_TURN_RATE, tolerance: float = DEFAULT_TOLERANCE,
                 gui: bool = False, seed: int = 0, **_: Any):
        if gui:
            raise ExecutionError("the kinematic driver has no GUI; open the run's recording "
                                 "with rerun instead")
        self.spec = spec
        self.speed = speed
        self.turn_rate = turn_rate
        self.tolerance = tolerance
        self._connected = False
        self.kinds: dict[str, ModuleKind] = {}
        self.poses: dict[str, BodyPose] = {}
        self.links: list[_Link] = []
        self.struts: dict[str, _Strut] = {}
        self.targets: dict[str, dict[str, float]] = {}
        self.slides: dict[str, np.ndarray] = {}
        self.armed: set[tuple[str, str]] = set()
        self._time = 0.0

    # -- lifecycle ------------------------------------------------------------------------

    @property
    def is_connected(self) -> bool:
        return self._connected

    def connect(self) -> None:
        self._connected = True

    def disconnect(self) -> None:
        self._connected = False

    def reset(self, start: Configuration) -> None:
        """Lay ``start`` out (its positions if every module has one, else each group from
        its centre, docked as it says) and latch its connections.

        Raises:
            ExecutionError: two bodies overlap, or a docked port pair cannot face.
        """
        self.require_connected()
        self.kinds = {v: self.spec.kind(start.kind_of(v)) for v in start.vertices(virtual=False)}
        self.links, self.struts = [], {}
        for e in start.edges():
            z = None if e.z is None else np.array(e.z, dtype=float)
            if e.kind is not None:
                ends = {"a": None if start.is_virtual(e.source) else e.source,
                        "b": None if start.is_virtual(e.target) else e.target}
                self.struts[e.id] = _Strut(e.kind, ends, z)
            elif not (start.is_virtual(e.source) or start.is_virtual(e.target)):
                ports = e.ports or (None, None)
                self.links.append(_Link(e.source, e.target, ports[0], ports[1], z))
        self.poses = self._layout(start)
        self.targets, self.slides, self.armed, self._time = {}, {}, set(), 0.0
        for link in self.links:
            if link.z is None:
                link.z = _unit(self.poses[link.target].position - self.poses[link.source].position)
        overlap = self._overlap(set(self.poses), set(self.poses))
        if overlap:
            raise ExecutionError(f"kinematic driver: modules {overlap[0]} and {overlap[1]} "
                                 "overlap in the start layout")

    def _layout(self, start: Configuration) -> dict[str, BodyPose]:
        modules = list(self.kinds)
        if modules and all(start.position(v) is not None for v in modules):
            return {v: BodyPose(np.array(start.position(v), dtype=float)) for v in modules}
        graph = nx.Graph()
        graph.add_nodes_from(modules)
        for link in self.links:
            graph.add_edge(link.source, link.target)
        for strut in self.struts.values():
            if strut.ends["a"] and strut.ends["b"]:
                graph.add_edge(strut.ends["a"], strut.ends["b"])
        rank = {v: (i,) for i, v in enumerate(modules)}
        poses: dict[str, BodyPose] = {}
        offset = 0.0
        for group in sorted(nx.connected_components(graph), key=lambda c: min(rank[v] for v in c)):
            # the rule of kinematics.build.tree_centre (smallest eccentricity, then rank),
            # not imported: the kinematics package would put scipy into every command's
            # start-up through the plugin host
            root = min(nx.center(graph.subgraph(group)), key=rank.__getitem__)
            placed = {root: BodyPose(np.zeros(3))}
            for parent, child in nx.bfs_edges(graph.subgraph(group), root,
                                              sort_neighbors=lambda vs: sorted(vs, key=rank.get)):
                placed[child] = self._place_neighbour(parent, child, placed[parent])
            low = min(p.position[1] - self._extent(v) for v, p in placed.items())
            shift = np.array([0.0, offset - low, 0.0])
            poses.update({v: BodyPose(p.position + shift, p.yaw) for v, p in placed.items()})
            offset = max(p.position[1] + self._extent(v) for v, p in poses.items()) + \
                4 * max(self._extent(v) for v in group)
        return poses

    def _extent(self, module: str) -> float:
        return float(max(body_half_size(self.kinds[module])))

    def _place_neighbour(self, parent: str, child: str, at: BodyPose) -> BodyPose:
        """Where ``child`` sits next to ``parent`` (at ``at``) by the link between them."""
        for link in self.links:
            if {link.source, link.target} == {parent, child}:
                return self._placement(link, fixed=parent, fixed_pose=at, moving_yaw=at.yaw)
        for strut in self.struts.values():
            if {strut.ends["a"], strut.ends["b"]} == {parent, child}:
                z = strut.z if strut.z is not None else np.array([1.0, 0.0, 0.0])
                sign = 1.0 if strut.ends["a"] == parent else -1.0
                length = float(self.spec.kind(strut.kind).geometry.get(
                    "length", 2 * max(body_half_size(self.spec.kind(strut.kind)))))
                return BodyPose(at.position + sign * _unit(z) * length, at.yaw)
        raise ExecutionError(f"no link between {parent} and {child}")  # pragma: no cover

    def _placement(self, link: _Link, *, fixed: str, fixed_pose: BodyPose,
                   moving_yaw: float) -> BodyPose:
        """Pose of the non-fixed end of ``link`` that makes it: ports facing, or touching."""
        moving = link.target if fixed == link.source else link.source
        fixed_port = link.source_port if fixed == link.source else link.target_port
        moving_port = link.target_port if fixed == link.source else link.source_port
        fk, mk = self.kinds[fixed], self.kinds[moving]
        if (fixed_port is not None and moving_port is not None
                and fk.port(fixed_port).normal is not None and mk.port(moving_port).normal
                is not None):
            return place_for_ports(fk, fixed_port, fixed_pose, mk, moving_port, moving_yaw)
        z = link.z if link.z is not None else np.array([1.0, 0.0, 0.0])
        return place_for_contact(fk, fixed_pose, mk, moving_yaw, z, fixed == link.source)

    # -- reading ----------------------------------------------------------------------------

    def get_observation(self) -> Observation:
        self.require_connected()
        latches: dict[str, list[Latch]] = {m: [] for m in self.kinds}
        for link in self.links:
            z = None if link.z is None else tuple(float(c) for c in link.z)
            latches[link.source].append(Latch(link.source_port, link.target, link.target_port, z))
        sensors: dict[str, ModuleReading] = {
            m: ModuleReading(self.kinds[m].name, tuple(latches[m])) for m in self.kinds}
        sensors.update(self._strut_readings())
        # the generic runtime's modules are tracked by an external pose sensor (its
        # controller steers each module to planar goals), exact as everything here
        return Observation(self._time, sensors, tracked=self._poses())

    def ground_truth(self, *, name: str = "") -> Configuration:
        """The world's own state, for the judge: the connections its latches hold, each
        ``z`` from the two bodies' exact positions (a strut's as the world turned it),
        assembled as :class:`~msrr.core.generic.recognizer.LatchRecognizer` assembles
        latches (one reading of latches into a configuration)."""
        from .recognizer import LatchRecognizer

        self.require_connected()
        latches: dict[str, list[Latch]] = {m: [] for m in self.kinds}
        for link in self.links:
            between = _unit(self.poses[link.target].position - self.poses[link.source].position)
            latches[link.source].append(Latch(link.source_port, link.target, link.target_port,
                                              tuple(float(c) for c in between)))
        sensors = {m: ModuleReading(self.kinds[m].name, tuple(latches[m])) for m in self.kinds}
        sensors.update(self._strut_readings())
        config = LatchRecognizer(self.spec).recognize(sensors)
        config.name = name
        return config

    def _poses(self) -> dict[str, Pose]:
        return {m: Pose(p.position.copy(), np.array([0.0, 0.0, math.sin(p.yaw / 2),
                                                     math.cos(p.yaw / 2)]))
                for m, p in self.poses.items()}

    def _strut_readings(self) -> dict[str, ModuleReading]:
        """What each strut reports: its latched ends and its direction."""
        out = {}
        for strut_id, strut in self.struts.items():
            z = None if strut.z is None else tuple(float(c) for c in strut.z)
            out[strut_id] = ModuleReading(strut.kind, tuple(
                Latch(end, vertex, None, z) for end, vertex in sorted(strut.ends.items())
                if vertex is not None))
        return out

    def witness(self) -> Witness:
        """Every module's pose, for the judge and the recording."""
        self.require_connected()
        return Witness(self._time, self._poses())

    @property
    def time(self) -> float:
        return self._time

    # -- commanding -------------------------------------------------------------------------

    def send_action(self, commands: Mapping[str, ModuleCommand]) -> None:
        """Release what is commanded at once; remember pose targets and armed ports.

        Raises:
            ExecutionError: a command for an unknown module, an unknown pose key, a
                dock of an edge module's end, or a slide of a module whose one link is
                not a contact (or mixed with pose keys).
        """
        self.require_connected()
        unknown = set(commands) - set(self.kinds) - set(self.struts)
        if unknown:
            raise ExecutionError(f"kinematic driver: commands for unknown module(s) "
                                 f"{sorted(unknown)}")
        self.targets, self.slides, self.armed = {}, {}, set()
        for module, command in sorted(commands.items()):
            for port in command.undock:
                self._release(module, port)
            if module in self.struts:
                if command.dock:
                    raise ExecutionError(f"kinematic driver: cannot dock the ends of edge module "
                                         f"{module} (edge modules have no body here)")
                continue
            bad = set(command.joints) - set(POSE_KEYS) - set(SLIDE_KEYS)
            if bad:
                raise ExecutionError(f"kinematic driver: module {module}: unknown pose key(s) "
                                     f"{sorted(bad)} (known: x, y, z, yaw; or slide_x, "
                                     "slide_y, slide_z)")
            if set(command.joints) & set(SLIDE_KEYS):
                self.slides[module] = self._slide_goal(module, command.joints)
            elif command.joints:
                self.targets[module] = {k: float(v) for k, v in command.joints.items()}
            self.armed |= {(module, port) for port in command.dock}

    def _slide_goal(self, module: str, joints: Mapping[str, float]) -> np.ndarray:
        if set(joints) != set(SLIDE_KEYS):
            raise ExecutionError(f"kinematic driver: module {module}: a slide takes exactly "
                                 f"slide_x, slide_y, slide_z, got {sorted(joints)}")
        self._contact_of(module)
        goal = np.array([float(joints[k]) for k in SLIDE_KEYS])
        if not np.all(np.isfinite(goal)) or float(np.linalg.norm(goal)) < 1e-9:
            raise ExecutionError(f"kinematic driver: module {module}: slide direction "
                                 f"{goal.tolist()} is not a direction")
        return goal / np.linalg.norm(goal)

    def _contact_of(self, module: str) -> tuple[_Link, str]:
        """The one link of ``module`` and the module at its other end, if a contact."""
        mine = [lk for lk in self.links if module in (lk.source, lk.target)]
        mine_struts = [s for s in self.struts.values() if module in s.ends.values()]
        if len(mine) != 1 or mine_struts:
            raise ExecutionError(f"kinematic driver: module {module} cannot slide: it has "
                                 f"{len(mine) + len(mine_struts)} links, a slide needs one")
        link = mine[0]
        other = link.target if link.source == module else link.source
        for end, port in ((link.source, link.source_port), (link.target, link.target_port)):
            if port is not None and self.kinds[end].port(port).normal is not None:
                raise ExecutionError(f"kinematic driver: module {module} cannot slide on "
                                     f"{other}: port {end}{port} is a rigid latch, not a contact")
        return link, other

    def _slide(self, module: str, dt: float) -> None:
        """Turn ``module`` over the surface of the module it rests on (module docstring)."""
        link, other = self._contact_of(module)
        centre, here = self.poses[other], self.poses[module]
        offset = here.position - centre.position
        radius = float(np.linalg.norm(offset))
        direction = slide_toward(offset / radius, self.slides[module], self.speed * dt / radius)
        distance = contact_distance(self.kinds[other], centre.yaw, self.kinds[module],
                                    here.yaw, direction)
        self.poses[module] = BodyPose(centre.position + direction * distance, here.yaw)
        overlap = self._overlap({module}, set(self.poses) - {module})
        if overlap:
            self.poses[module] = here
            raise ExecutionError(f"kinematic driver: sliding {module} over {other} would "
                                 f"overlap {overlap[1]} at t={self._time:.2f} s (refused)")
        link.z = direction if link.target == module else -direction

    def _release(self, module: str, port: str) -> None:
        if module in self.struts:
            if port not in self.struts[module].ends:
                raise ExecutionError(f"kinematic driver: edge module {module} has no end {port!r}")
            self.struts[module].ends[port] = None
            return
        if port.startswith(FREEFORM_PREFIX):
            other = port[len(FREEFORM_PREFIX):]
            self.links = [lk for lk in self.links if not (
                lk.source_port is None and {lk.source, lk.target} == {module, other})]
        else:
            self.links = [lk for lk in self.links if (module, port) not in lk.ends()]

    def step(self, dt: float) -> None:
        """Move each commanded group toward its target, slide each sliding module, then
        latch armed aligned ports.

        Raises:
            ExecutionError: a move would make two bodies overlap (nothing moves then).
        """
        self.require_connected()
        if dt <= 0:
            raise ExecutionError(f"kinematic driver: dt must be positive, got {dt}")
        for group in self.groups():
            leaders = sorted(m for m in group if m in self.targets)
            if leaders:
                self._move_group(group, leaders[0], dt)
        for module in sorted(self.slides):
            self._slide(module, dt)
        self._latch()
        self._time += dt

    def groups(self) -> list[set[str]]:
        """Modules that move together (joined by links or by both ends of a strut)."""
        graph = nx.Graph()
        graph.add_nodes_from(self.kinds)
        graph.add_edges_from((lk.source, lk.target) for lk in self.links)
        graph.add_edges_from((s.ends["a"], s.ends["b"]) for s in self.struts.values()
                             if s.ends["a"] and s.ends["b"])
        return [set(c) for c in nx.connected_components(graph)]

    def _move_group(self, group: set[str], leader: str, dt: float) -> None:
        pose = self.poses[leader]
        target = self.targets[leader]
        goal = np.array([target.get(k, float(pose.position[i])) for i, k in enumerate("xyz")])
        delta = goal - pose.position
        distance = float(np.linalg.norm(delta))
        reach = self.speed * dt
        if distance > reach:
            delta = delta * (reach / distance)
        turn = wrap_angle(target.get("yaw", pose.yaw) - pose.yaw)
        turn = max(-self.turn_rate * dt, min(self.turn_rate * dt, turn))
        moved = {}
        for m in group:
            p = self.poses[m]
            moved[m] = BodyPose(pose.position + delta + rotate_z(p.position - pose.position, turn),
                                wrap_angle(p.yaw + turn))
        before = {m: self.poses[m] for m in group}
        self.poses.update(moved)
        overlap = self._overlap(group, set(self.poses) - group)
        if overlap:
            self.poses.update(before)
            a, b = overlap
            raise ExecutionError(f"kinematic driver: moving {a} toward {goal.round(3).tolist()} "
                                 f"would overlap {b} at t={self._time:.2f} s (refused)")
        for link in self.links:  # a rigid turn turns the sensed directions with it
            if link.source in group and link.z is not None:
                link.z = rotate_z(link.z, turn)

    def _overlap(self, movers: set[str], others: set[str]) -> tuple[str, str] | None:
        """The first pair (mover, other) whose inscribed balls intersect, if any."""
        a_ids, b_ids = sorted(movers), sorted(others)
        if not a_ids or not b_ids:
            return None
        a = np.array([self.poses[m].position for m in a_ids])
        b = np.array([self.poses[m].position for m in b_ids])
        radius = {m: inscribed_radius(k) for m, k in self.kinds.items()}
        limit = (np.array([radius[m] for m in a_ids])[:, None]
                 + np.array([radius[m] for m in b_ids])[None, :] - 1e-9)
        same = np.array(a_ids)[:, None] == np.array(b_ids)[None, :]
        hits = np.argwhere((np.linalg.norm(a[:, None] - b[None, :], axis=2) < limit) & ~same)
        if not len(hits):
            return None
        i, j = hits[0]
        return a_ids[i], b_ids[j]

    # -- latching ---------------------------------------------------------------------------

    def _used(self) -> set[tuple[str, str]]:
        return {end for lk in self.links for end in lk.ends() if end[1] is not None}

    def _latch(self) -> None:
        for module, port in sorted(self.armed):
            if port.startswith(FREEFORM_PREFIX):
                self._latch_contact(module, port[len(FREEFORM_PREFIX):])
            else:
                self._latch_port(module, port)

    def _latch_contact(self, module: str, other: str) -> None:
        if other not in self.poses or any(lk.source_port is None and {lk.source, lk.target}
                                          == {module, other} for lk in self.links):
            return
        between = self.poses[other].position - self.poses[module].position
        distance = float(np.linalg.norm(between))
        z = _unit(between)
        touch = (contact_reach(self.kinds[module], rotate_z(z, -self.poses[module].yaw))
                 + contact_reach(self.kinds[other], rotate_z(-z, -self.poses[other].yaw)))
        if abs(distance - touch) <= self.tolerance:
            self.links.append(_Link(module, other, None, None, z))

    def _latch_port(self, module: str, port: str) -> None:
        used = self._used()
        if (module, port) in used:
            return
        here = port_frame(self.kinds[module], port, self.poses[module])
        if here is None:
            return
        for other in sorted(self.kinds):
            if other == module:
                continue
            for spec in self.kinds[other].ports:
                if (other, spec.name) in used:
                    continue
                there = port_frame(self.kinds[other], spec.name, self.poses[other])
                if there is None:
                    continue
                if (np.linalg.norm(there[0] - here[0]) <= self.tolerance
                        and float(there[1] @ here[1]) <= -math.cos(ANGLE_TOLERANCE)):
                    self.links.append(self._directed(module, port, other, spec.name))
                    return

    def _directed(self, module: str, port: str, other: str, other_port: str) -> _Link:
        """The new link, from its active end (else from the armed end)."""
        mine = self.kinds[module].port(port).role
        theirs = self.kinds[other].port(other_port).role
        if theirs == "active" and mine != "active" or mine == "passive" and theirs != "passive":
            source, sp, target, tp = other, other_port, module, port
        else:
            source, sp, target, tp = module, port, other, other_port
        z = _unit(self.poses[target].position - self.poses[source].position)
        return _Link(source, target, sp, tp, z)


class KinematicDriverFactory:
    """What the generic runtime registers through ``msrr_drivers``: builds a
    :class:`KinematicDriver` of one robot, ``factory(gui=..., seed=...)``."""

    name = KinematicDriver.name
    description = KinematicDriver.description
    generic = True
    companions = Companions(recognizer="latches", controller="latches")
    """The recognizer and controller that read and command this driver."""
    layout = None
    options = KinematicDriver.options

    def __init__(self, spec: RobotSpec, **defaults: Any):
        self.spec = spec
        self.defaults = defaults

    def __call__(self, **options: Any) -> KinematicDriver:
        return KinematicDriver(self.spec, **{**self.defaults, **options})
