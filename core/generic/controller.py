"""The latch controller: moves modules of the kinematic driver into place and docks them.

It reads only the observation (poses and :class:`~msrr.core.generic.driver.ModuleReading`
sensors) and commands pose targets (``joints={"x", "y", "z", "yaw"}``) and docks:

* **move** (an action with planar goals ``{id: [x, y, yaw]}``): each goal module (with
  its group) lifts clear of every other body, travels and turns, and lowers onto its
  goal (its height kept); an action without goals is reached at once (the kinematic
  world has no joints to move);
* **approach**: for each connection the action makes, one side's group
  is carried so that the two ports face each other (or the bodies touch, along the
  target's ``z`` or, if that place is taken, along an axis or a horizontal diagonal,
  for connections without ports): the smaller group moves, the target's on a tie,
  unless its place or its path would overlap another body; the path is straight, or
  lifts clear of every body, travels and lowers (after a side step if needed); the
  first whose sweep is free is taken; when every place is taken by modules of other
  groups (left where an undock put them), one such group is first parked beside the
  others; once there, the
  controller arms the ports itself, so parallel connections dock one by one and each
  next placement starts from the merged group (the last waits for the connect phase,
  where the executor arms its ports);
* **release**: connections without ports are released with ``undock=("@other",)``
  (the executor sends the port commands of every other change, in release, connect
  and handover);
* **connect**: keeps the docks of the action armed;
* **flow** (section 4.1; the executor's flow contract): when the leaf's links are
  contacts (no port normals: FreeBOT, SnailBot), the leaf slides over its parent
  (``joints={"slide_x", "slide_y", "slide_z"}``, see the kinematic driver) to where
  it touches the new parent as well (:func:`~msrr.core.generic.geometry.touching_direction`),
  in the plane of parent, new parent and leaf, else over the top or around the side,
  whichever sweep is free, in arcs of at most 60 degrees; then in **handover** it
  sends the leaf ``undock=("@parent",)`` and ``dock=("@new parent",)`` in one tick.
  A leaf held by a rigid port cannot slide: its flow is reached at once and the
  handover carries the released leaf to its new place like an approach.
"""

from __future__ import annotations

import itertools
import math
from collections import deque
from dataclasses import dataclass, field

import networkx as nx
import numpy as np

from ..actions import Flow, flow_of
from ..control import Control
from ..driver import ModuleCommand, Observation
from ..events import Phase
from ..plan import Action, ConnectionChange, ConnectionKey, connection_key
from ..robot import ModuleKind, RobotSpec, body_half_size
from .geometry import (
    BodyPose,
    contact_distance,
    inscribed_radius,
    place_for_contact,
    place_for_ports,
    slide_toward,
    touching_direction,
    wrap_angle,
)
from .readings import FREEFORM_PREFIX, SLIDE_KEYS, ModuleReading

__all__ = ["LatchController"]

REACHED = 0.5
"""A waypoint counts as reached within this fraction of the robot's
:class:`~msrr.core.robot.DockTolerance` (its position [m] and angle [rad]), as in the
drive controller: the kinematic world moves exactly, so it is reached well within."""

CONTACT_DIRECTIONS = ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1),
                      (1, 1, 0), (1, -1, 0), (-1, 1, 0), (-1, -1, 0))
"""Connection directions tried after the target's own for a contact dock."""


SLIDE_ARC = math.pi / 3
"""Largest arc [rad] between two waypoints of a slide (each arc's great circle unique)."""


@dataclass
class _Slide:
    """A flow's leaf sliding over its parent through unit directions ``waypoints``."""

    leaf: str
    parent: str
    waypoints: deque = field(default_factory=deque)


@dataclass
class _Job:
    """One module (and its group) to bring somewhere, then possibly one dock."""

    leader: str
    waypoints: deque = field(default_factory=deque)
    final: BodyPose | None = None
    change: ConnectionChange | None = None


def _body(observation: Observation, module: str) -> BodyPose:
    pose = observation.tracked[module]
    return BodyPose(np.asarray(pose.position, dtype=float), pose.yaw)


class LatchController:
    """Controller of the generic runtime for robot ``spec`` (see the module docstring)."""

    name = "latches"
    description = "lift, carry and dock modules in the kinematic world (generic runtime)"
    generic = True

    def __init__(self, spec: RobotSpec):
        self.spec = spec
        self.tolerance = spec.defaults.dock_tolerance
        self.jobs: deque[_Job | ConnectionChange | tuple[str, list[float]]] = deque()
        self.job: _Job | None = None
        self.parked = 0
        self.slide: _Slide | None = None

    # -- the controller protocol -------------------------------------------------------------

    def begin(self, action: Action, phase: Phase, observation: Observation) -> None:
        self.job = None
        self.jobs = deque()
        self.parked = 0
        self.slide = None
        if phase is Phase.MOVE:
            self.jobs.extend(sorted(action.goals.items()))
        elif phase is Phase.APPROACH:
            self.jobs.extend(self._made(action))
        elif phase is Phase.FLOW:
            flow = flow_of(action)
            if self._slides(observation, flow):
                self.slide = self._plan_slide(observation, flow)
        elif phase is Phase.HANDOVER:
            flow = flow_of(action)
            if not self._slides(observation, flow) or not self._touching(observation, flow):
                self.jobs.extend(self._made(action))  # a rigid latch: carry the leaf over

    def control(self, action: Action, phase: Phase, observation: Observation) -> Control:
        commands: dict[str, ModuleCommand] = {}
        if phase in (Phase.RELEASE, Phase.HANDOVER):
            for change in self._broken(action):
                if change.source_port is None and change.target_port is None:
                    self._add(commands, change.source, undock=f"{FREEFORM_PREFIX}{change.target}")
        if phase is Phase.CONNECT:
            for change in self._made(action):
                self._arm(commands, change)
        if phase is Phase.HANDOVER:
            for change in self._made(action):
                if change.source_port is None and change.target_port is None:
                    self._arm(commands, change)
        errors: dict[str, float] = {}
        if phase is Phase.FLOW:
            self._advance_slide(observation, commands, errors)
        if phase in (Phase.MOVE, Phase.APPROACH, Phase.HANDOVER):
            self._advance(action, phase, observation, commands, errors)
        return Control(commands, errors, reached=self.job is None and not self.jobs
                       and (self.slide is None or not self.slide.waypoints))

    # -- flows --------------------------------------------------------------------------------

    def _slides(self, observation: Observation, flow: Flow) -> bool:
        """Whether the flow's links are contacts (no port normals), so the leaf can slide."""
        for change in (flow.broken, flow.made):
            for module in (change.source, change.target):
                port = flow.port(change, module)
                if port is not None and self._kind(observation, module).port(port).normal \
                        is not None:
                    return False
        return True

    def _touching(self, observation: Observation, flow: Flow) -> bool:
        """Whether the leaf touches the new parent (a slide ended there)."""
        leaf, other = _body(observation, flow.leaf), _body(observation, flow.new_parent)
        between = other.position - leaf.position
        span = float(np.linalg.norm(between))
        reach = contact_distance(self._kind(observation, flow.leaf), leaf.yaw,
                                 self._kind(observation, flow.new_parent), other.yaw,
                                 between / span)
        return abs(span - reach) <= 1e-3

    def _plan_slide(self, observation: Observation, flow: Flow) -> _Slide | None:
        """Waypoints (unit directions from the parent) that bring the leaf to touch the new
        parent: in the plane of parent, new parent and leaf, over the top, or around the
        side, the first whose sweep is free; ``None`` when no place touches both."""
        parent, leaf = _body(observation, flow.parent), _body(observation, flow.leaf)
        other = _body(observation, flow.new_parent)
        kinds = {m: self._kind(observation, m) for m in (flow.parent, flow.leaf,
                                                         flow.new_parent)}
        here = leaf.position - parent.position
        here = here / np.linalg.norm(here)
        e1 = other.position - parent.position
        e1 = e1 / np.linalg.norm(e1)
        sides = []
        for side in (here, np.array([0.0, 0.0, 1.0]), np.cross([0.0, 0.0, 1.0], e1),
                     -np.cross([0.0, 0.0, 1.0], e1)):
            side = side - float(side @ e1) * e1
            if float(np.linalg.norm(side)) > 1e-6:
                sides.append(side / np.linalg.norm(side))
        first: _Slide | None = None
        for side in sides:
            goal = touching_direction(kinds[flow.parent], parent, kinds[flow.leaf], leaf.yaw,
                                      kinds[flow.new_parent], other, side)
            if goal is None:
                continue
            start = math.atan2(float(here @ side), float(here @ e1)) % (2 * math.pi)
            end = math.atan2(float(goal @ side), float(goal @ e1)) % (2 * math.pi)
            count = max(1, math.ceil(abs(end - start) / SLIDE_ARC))
            waypoints = deque(math.cos(a) * e1 + math.sin(a) * side
                              for a in np.linspace(start, end, count + 1)[1:])
            slide = _Slide(flow.leaf, flow.parent, waypoints)
            if self._slide_free(observation, slide):
                return slide
            first = first or slide
        return first  # the driver refuses the move and says where

    def _slide_free(self, observation: Observation, slide: _Slide) -> bool:
        """Whether the leaf's sweep along ``slide`` stays clear of every body but its
        parent (sampled finer than the smallest body)."""
        parent = _body(observation, slide.parent)
        leaf = _body(observation, slide.leaf)
        kinds = {m: self._kind(observation, m) for m in observation.tracked}
        others = [m for m in observation.tracked if m not in (slide.leaf, slide.parent)]
        if not others:
            return True
        fixed = np.array([observation.tracked[m].position for m in others])
        limit = np.array([inscribed_radius(kinds[m]) for m in others]) \
            + inscribed_radius(kinds[slide.leaf]) - 1e-9
        offset = leaf.position - parent.position
        radius = float(np.linalg.norm(offset))
        step = min(inscribed_radius(k) for k in kinds.values()) / 2 / radius
        direction = offset / radius
        for goal in slide.waypoints:
            while True:
                direction = slide_toward(direction, goal, step)
                at = parent.position + direction * contact_distance(
                    kinds[slide.parent], parent.yaw, kinds[slide.leaf], leaf.yaw, direction)
                if np.any(np.linalg.norm(fixed - at, axis=1) < limit):
                    return False
                if float(direction @ goal) >= 1 - 1e-12:
                    break
        return True

    def _advance_slide(self, observation: Observation, commands: dict[str, ModuleCommand],
                       errors: dict[str, float]) -> None:
        slide = self.slide
        if slide is None:
            return
        offset = _body(observation, slide.leaf).position - _body(observation,
                                                                 slide.parent).position
        radius = float(np.linalg.norm(offset))
        here = offset / radius
        near = math.cos(REACHED * self.tolerance.angle)
        while slide.waypoints and float(here @ slide.waypoints[0]) >= near:
            slide.waypoints.popleft()
        if not slide.waypoints:
            return
        goal = slide.waypoints[0]
        errors[slide.leaf] = radius * math.acos(max(-1.0, min(1.0, float(here @ goal))))
        commands[slide.leaf] = ModuleCommand(joints=dict(zip(SLIDE_KEYS, (float(v)
                                                                           for v in goal),
                                                             strict=True)))

    # -- jobs ---------------------------------------------------------------------------------

    def _advance(self, action: Action, phase: Phase, observation: Observation,
                 commands: dict[str, ModuleCommand], errors: dict[str, float]) -> None:
        latched = _latched(observation)
        while True:
            if self.job is None:
                if not self.jobs:
                    return
                self.job = self._start(self.jobs.popleft(), action, observation, latched)
                if self.job is None:
                    continue
            job = self.job
            here = _body(observation, job.leader)
            while job.waypoints and self._close(here, job.waypoints[0]):
                job.waypoints.popleft()
            if job.final is not None:
                errors[job.leader] = float(np.linalg.norm(here.position - job.final.position))
            if job.waypoints:
                target = job.waypoints[0]
                self._add(commands, job.leader, pose=target)
                return
            if job.change is None or job.change.key in latched or (
                    phase is Phase.APPROACH and not self.jobs):
                self.job = None  # the last dock of an approach latches in the connect phase
                continue
            self._arm(commands, job.change)
            self._add(commands, job.leader, pose=job.final)
            return

    def _start(self, item: ConnectionChange | tuple[str, list[float]], action: Action,
               observation: Observation, latched: set[ConnectionKey]) -> _Job | None:
        if isinstance(item, ConnectionChange):
            if item.key in latched:
                return None
            return self._dock_job(item, action, observation, latched)
        module, goal = item
        here = _body(observation, module)
        x, y, yaw = (float(v) for v in goal[:3])
        final = BodyPose(np.array([x, y, here.position[2]]), wrap_angle(yaw))
        group = self._groups(observation, latched, set())[module]
        return _Job(module, self._path(observation, group, module, final), final)

    def _dock_job(self, change: ConnectionChange, action: Action, observation: Observation,
                  latched: set[ConnectionKey]) -> _Job:
        broken = {c.key for c in self._broken(action)}
        groups = self._groups(observation, latched, broken)
        source, target = change.source, change.target
        if target in groups[source]:  # closing a loop: nothing can move, dock if aligned
            return _Job(target, deque(), _body(observation, target), change)
        options = [(target, source), (source, target)]
        if len(groups[source]) < len(groups[target]):
            options.reverse()
        places = [(moving, final) for moving, fixed in options
                  for final in self._placements(change, action, observation, moving, fixed)]
        free_place = None
        for moving, final in places:
            if self._collides(observation, groups[moving], moving, final):
                continue
            path = self._path(observation, groups[moving], moving, final)
            job = _Job(moving, path, final, change)
            if self._sweep_free(observation, groups[moving], moving,
                                [_body(observation, moving), *path]):
                return job
            free_place = free_place or job
        if free_place is not None:
            return free_place  # the driver refuses the move and says where
        park = self._park_blockers(observation, groups, places, change)
        if park is not None:
            return park
        moving, final = places[0]
        return _Job(moving, self._path(observation, groups[moving], moving, final), final, change)

    def _park_blockers(self, observation: Observation, groups: dict[str, set[str]],
                       places: list[tuple[str, BodyPose]], change: ConnectionChange
                       ) -> _Job | None:
        """When every place of a dock is taken by modules of other groups (modules left
        where an undock put them), a job that parks one such group clear of everything
        (beside the others, along +y); the dock is queued again after it."""
        if self.parked >= 2 * len(observation.tracked):
            return None
        involved = groups[change.source] | groups[change.target]
        for moving, final in places:
            blockers = self._blockers(observation, groups[moving], moving, final)
            if not blockers or blockers & involved:
                continue
            group = groups[min(blockers)]
            leader = min(group)
            here = _body(observation, leader)
            extent = 2 * max(max(body_half_size(k)) for k in self.spec.module_kinds)
            top = max(float(p.position[1]) for m, p in observation.tracked.items())
            bottom = min(float(observation.tracked[m].position[1]) for m in group)
            spot = BodyPose(here.position + np.array([0.0, top - bottom + 2 * extent, 0.0]),
                            here.yaw)
            self.parked += 1
            self.jobs.appendleft(change)
            return _Job(leader, self._path(observation, group, leader, spot), spot)
        return None

    def _blockers(self, observation: Observation, group: set[str], leader: str,
                  final: BodyPose) -> set[str]:
        """Modules outside ``group`` that overlap it when ``leader`` is at ``final``."""
        members = sorted(group)
        others = [m for m in observation.tracked if m not in group]
        if not others:
            return set()
        start = _body(observation, leader)
        turn = wrap_angle(final.yaw - start.yaw)
        c, s_ = math.cos(turn), math.sin(turn)
        offsets = np.array([observation.tracked[m].position for m in members]) - start.position
        moved = final.position + offsets @ np.array([[c, s_, 0.0], [-s_, c, 0.0],
                                                     [0.0, 0.0, 1.0]])
        fixed = np.array([observation.tracked[m].position for m in others])
        radius = {m: inscribed_radius(self._kind(observation, m)) for m in observation.tracked}
        limit = (np.array([radius[m] for m in members])[:, None]
                 + np.array([radius[m] for m in others])[None, :] - 1e-9)
        hits = np.linalg.norm(moved[:, None, :] - fixed[None, :, :], axis=2) < limit
        return {others[j] for j in np.nonzero(hits.any(axis=0))[0]}

    def _placements(self, change: ConnectionChange, action: Action, observation: Observation,
                    moving: str, fixed: str) -> list[BodyPose]:
        """Where ``moving`` may go to make ``change`` with ``fixed``: one pose for two ports
        with normals; for contact, along the target's ``z`` first, then along the axes and
        the horizontal diagonals (a freeform connector docks anywhere on the surface)."""
        kind = {m: self.spec.kind(observation.sensors[m].kind) for m in (moving, fixed)}
        here, there = _body(observation, moving), _body(observation, fixed)
        fixed_port = change.source_port if fixed == change.source else change.target_port
        moving_port = change.target_port if fixed == change.source else change.source_port
        if (fixed_port is not None and moving_port is not None
                and kind[fixed].port(fixed_port).normal is not None
                and kind[moving].port(moving_port).normal is not None):
            return [place_for_ports(kind[fixed], fixed_port, there, kind[moving], moving_port,
                                    here.yaw)]
        first = _target_z(action, change)
        directions = [] if first is None else [np.asarray(first, dtype=float)]
        directions += [np.array(d, dtype=float) / np.linalg.norm(d) for d in CONTACT_DIRECTIONS]
        return [place_for_contact(kind[fixed], there, kind[moving], here.yaw, z,
                                  fixed == change.source) for z in directions]

    # -- geometry of moves --------------------------------------------------------------------

    def _kind(self, observation: Observation, module: str) -> ModuleKind:
        return self.spec.kind(observation.sensors[module].kind)

    def _collides(self, observation: Observation, group: set[str], leader: str,
                  final: BodyPose) -> bool:
        """Whether ``group`` moved rigidly so that ``leader`` is at ``final`` overlaps
        another body (inscribed balls)."""
        return not self._sweep_free(observation, group, leader, [final])

    def _sweep_free(self, observation: Observation, group: set[str], leader: str,
                    path: list[BodyPose]) -> bool:
        """Whether ``group``, carried by ``leader`` through the poses of ``path`` (straight
        segments between them, heading turned evenly; a single pose is checked alone),
        stays clear of every other body, sampled finer than the smallest body."""
        members = sorted(group)
        others = [m for m in observation.tracked if m not in group]
        if not others:
            return True
        radius = {m: inscribed_radius(self._kind(observation, m)) for m in observation.tracked}
        start = _body(observation, leader)
        offsets = np.array([observation.tracked[m].position for m in members]) - start.position
        fixed = np.array([observation.tracked[m].position for m in others])
        limit = (np.array([radius[m] for m in members])[:, None]
                 + np.array([radius[m] for m in others])[None, :] - 1e-9)
        step = min(radius.values()) / 2
        samples = []
        for a, b in itertools.pairwise(path) if len(path) > 1 else [(path[0], path[0])]:
            count = max(1, math.ceil(float(np.linalg.norm(b.position - a.position)) / step))
            turn = wrap_angle(b.yaw - a.yaw)
            for t in np.linspace(1.0 / count, 1.0, count):
                samples.append((a.position + t * (b.position - a.position),
                                wrap_angle(a.yaw + t * turn - start.yaw)))
        for position, turn in samples:
            c, s_ = math.cos(turn), math.sin(turn)
            rotated = offsets @ np.array([[c, s_, 0.0], [-s_, c, 0.0], [0.0, 0.0, 1.0]])
            moved = position + rotated
            gaps = np.linalg.norm(moved[:, None, :] - fixed[None, :, :], axis=2)
            if np.any(gaps < limit):
                return False
        return True

    def _path(self, observation: Observation, group: set[str], leader: str, final: BodyPose
              ) -> deque[BodyPose]:
        """Waypoints of ``leader`` to ``final`` whose sweep hits no other body: the first
        free of a straight move, lift-travel-lower, and lift-travel-lower after a side step
        (away from the nearest bodies, else along +-x, +-y, one to three body sizes); the lift path if none is free
        (the driver then refuses the move and says where)."""
        here = _body(observation, leader)
        if self._close(here, final):
            return deque()
        candidates = [[final]]
        for side in self._side_steps(observation, group, here):
            start = BodyPose(here.position + side, here.yaw)
            lift = self._lift(observation, group, start, final)
            candidates.append(([start] if side.any() else []) + lift)
        for path in candidates:
            if self._sweep_free(observation, group, leader, [here, *path]):
                return deque(path)
        return deque(candidates[1])

    def _side_steps(self, observation: Observation, group: set[str], here: BodyPose
                    ) -> list[np.ndarray]:
        extent = 2 * max(max(body_half_size(k)) for k in self.spec.module_kinds)
        near = [observation.tracked[m].position - here.position for m in observation.tracked
                if m not in group]
        steps = [np.zeros(3)]
        if near:
            away = -np.sum([v / max(float(np.linalg.norm(v)), 1e-9) ** 3 for v in near], axis=0)
            away[2] = 0.0
            if float(np.linalg.norm(away)) > 1e-9:
                steps.append(away / np.linalg.norm(away) * extent)
        steps += [np.array(d, dtype=float) * extent * k for k in (1, 2, 3)
                  for d in ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0))]
        return steps

    def _lift(self, observation: Observation, group: set[str], here: BodyPose, final: BodyPose
              ) -> list[BodyPose]:
        """Lift clear of every other body, travel and turn at that height, lower."""
        others = [m for m in observation.tracked if m not in group]
        tallest = max((float(observation.tracked[m].position[2])
                       + max(body_half_size(self._kind(observation, m))) for m in others),
                      default=float(here.position[2]))
        lowest = min(float(observation.tracked[m].position[2])
                     - max(body_half_size(self._kind(observation, m))) for m in group)
        height = max(float(here.position[2]), float(final.position[2]),
                     tallest + (float(here.position[2]) - lowest)) + 2 * max(
            max(body_half_size(k)) for k in self.spec.module_kinds)
        up = BodyPose(np.array([here.position[0], here.position[1], height]), here.yaw)
        over = BodyPose(np.array([final.position[0], final.position[1], height]), final.yaw)
        return [up, over, final]

    # -- helpers ------------------------------------------------------------------------------

    @staticmethod
    def _groups(observation: Observation, latched: set[ConnectionKey],
                ignore: set[ConnectionKey]) -> dict[str, set[str]]:
        graph = nx.Graph()
        graph.add_nodes_from(observation.tracked)
        for key in latched - ignore:
            ends = [m for m, _ in key]
            if len(ends) == 2 and all(m in observation.tracked for m in ends):
                graph.add_edge(*ends)
        return {m: group for group in nx.connected_components(graph) for m in group}

    @staticmethod
    def _made(action: Action) -> tuple[ConnectionChange, ...]:
        return action.made()

    @staticmethod
    def _broken(action: Action) -> tuple[ConnectionChange, ...]:
        return action.broken()

    def _arm(self, commands: dict[str, ModuleCommand], change: ConnectionChange) -> None:
        if change.source_port is None or change.target_port is None:
            self._add(commands, change.source, dock=f"{FREEFORM_PREFIX}{change.target}")
        else:
            self._add(commands, change.source, dock=change.source_port)
            self._add(commands, change.target, dock=change.target_port)

    def _close(self, pose: BodyPose, target: BodyPose) -> bool:
        """Whether ``pose`` is within reach of ``target`` (see :data:`REACHED`)."""
        return (float(np.linalg.norm(pose.position - target.position))
                <= REACHED * self.tolerance.position
                and abs(wrap_angle(pose.yaw - target.yaw)) <= REACHED * self.tolerance.angle)

    @staticmethod
    def _add(commands: dict[str, ModuleCommand], module: str, *, pose: BodyPose | None = None,
             dock: str | None = None, undock: str | None = None) -> None:
        base = commands.get(module, ModuleCommand())
        joints = dict(base.joints)
        if pose is not None:
            joints.update(x=float(pose.position[0]), y=float(pose.position[1]),
                          z=float(pose.position[2]), yaw=float(pose.yaw))
        commands[module] = ModuleCommand(joints=joints, wheels=base.wheels,
                                         dock=base.dock + ((dock,) if dock else ()),
                                         undock=base.undock + ((undock,) if undock else ()))


def _latched(observation: Observation) -> set[ConnectionKey]:
    """The links the modules report (vertex-to-vertex latches and edge-module ends)."""
    found = set()
    for module, reading in observation.sensors.items():
        if isinstance(reading, ModuleReading):
            for latch in reading.latches:
                found.add(connection_key(module, latch.other, latch.port, latch.other_port))
    return found


def _target_z(action: Action, change: ConnectionChange) -> np.ndarray | None:
    for e in action.target.edges():
        if connection_key(e.source, e.target, *(e.ports or (None, None))) == change.key:
            if e.z is None:
                return None
            return np.asarray(e.z) if e.source == change.source else -np.asarray(e.z)
    return None
