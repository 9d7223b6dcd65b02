"""The MMRP controller: drives module groups to goal poses and docks them.

Per moving group (modules docked together; a moving action may drive several groups
at once, :mod:`..schedule`), the centroid is steered like a tracked vehicle (forward
speed and yaw rate only):

0. ``stops`` -- a plan's moving action is one leg of a route, driven exactly as
   :mod:`msrr.plugins.mmrp.motion` says and the plan checker replays (along x
   straight; along y a quarter turn about the centroid, the drive, the turn back),
   so the group sweeps only what the plan was checked for; then ``line`` settles
   on the goal without detours;
1. ``path`` -- (docking phases) follow a grid A* path around the other modules
   (pure pursuit, forwards or backwards) to the pre-goal point,
   ``approach_distance`` before the goal along the goal heading;
2. ``align`` -- turn in place to the goal heading;
3. ``line`` -- drive straight along the goal heading onto the goal, correcting
   lateral error; a lateral error larger than the latch tolerance near the goal
   sends the group back to ``path``.

The approach side (forwards onto the goal, or backwards) is the one whose final
straight line keeps clear of the other modules, so L-R docks slide in alongside
the partner and T-B docks come straight at it. In the ``approach`` and ``connect``
phases of a connection, the goal is recomputed from the partner's *measured* pose
(S_conn), and in ``connect`` pushed ``extrusion`` metres further (S_extr), so the
latch sees the faces aligned even if the structure drifted.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import networkx as nx
import numpy as np

from msrr.core.alignment import wrap_angle
from msrr.core.control import Control
from msrr.core.driver import ModuleCommand, Observation
from msrr.core.events import Phase
from msrr.core.plan import Action

from ..robot import MODULE, SPEC
from .geometry import neighbour_pose, track_speeds
from .paths import plan_path, segment_clearance

__all__ = ["MmrpController"]

Pose2 = tuple[float, float, float]

DRIVE_GAIN = 0.8
"""Forward speed asked per metre left to a stop [1/s] (bounded by the cruise speed)."""
MIN_DRIVE_SPEED = 0.01
"""Slowest forward speed asked while a stop is not yet reached [m/s]."""
TURN_GAIN = 2.0
"""Yaw rate asked per radian left of a turn in place [1/s] (bounded by the turn rate)."""


def settling_time(distance: float, gain: float, limit: float, tolerance: float,
                  floor: float = 0.0) -> float:
    """Time [s] for ``x' = -min(limit, max(gain x, floor))`` to bring ``x`` from
    ``|distance|`` to within ``tolerance``: the bounded proportional law that drives a
    group to a stop or turns it in place (saturated, then exponential, then at
    ``floor`` once ``gain x`` falls below it). Units of ``x``: [m] or [rad]."""
    x = abs(distance)
    if x <= tolerance:
        return 0.0
    seconds = 0.0
    knee = limit / gain
    if x > knee:
        seconds += (x - knee) / limit
        x = knee
    slow = max(floor / gain, tolerance)
    if x > slow:
        seconds += math.log(x / slow) / gain
        x = slow
    return seconds + (x - tolerance) / floor if floor > 0 else seconds


@dataclass
class _GroupPlan:
    """What one group is doing: its members' targets and the current stage."""

    modules: list[str]
    targets: dict[str, Pose2]
    sign: float
    stage: str = "path"
    waypoints: list[tuple[float, float]] = field(default_factory=list)
    stops: list[Pose2] = field(default_factory=list)
    legged: bool = False

    @property
    def centre(self) -> Pose2:
        pts = np.array([self.targets[m][:2] for m in self.modules])
        c = pts.mean(axis=0)
        return float(c[0]), float(c[1]), self.targets[self.modules[0]][2]


def _planar(observation: Observation) -> dict[str, Pose2]:
    return {m: (float(p.position[0]), float(p.position[1]), p.yaw)
            for m, p in observation.tracked.items()}


def _components(observation: Observation) -> list[set[str]]:
    graph = nx.Graph()
    graph.add_nodes_from(observation.tracked)
    for module, faces in observation.sensors.items():
        for link in faces.values():
            if link is not None:
                graph.add_edge(module, link[0])
    return [set(c) for c in nx.connected_components(graph)]


class MmrpController:
    """Closed-loop group driving and docking for MMRP (registered as ``tracks``).

    Args:
        approach_distance: length of the final straight approach [m].
        speed: cruise speed of a group centroid [m/s].
        turn_rate: largest yaw rate [rad/s].
        extrusion: how far past S_conn the connect phase pushes [m].
        tolerance: reaching tolerance in position [m].
        yaw_tolerance: reaching tolerance in heading [rad].
    """

    name = "tracks"
    description = "group pure pursuit on grid A* paths, straight final approach, docking"

    def __init__(self, *, approach_distance: float = 0.25, speed: float = 0.12,
                 turn_rate: float = 0.8, extrusion: float = 0.004, tolerance: float = 0.003,
                 yaw_tolerance: float = 0.012):
        geometry = MODULE.geometry
        self.pitch = float(geometry["pitch"])
        self.width = float(geometry["width"])
        self.half_diagonal = math.hypot(geometry["length"], geometry["width"]) / 2
        self.lateral_limit = float(geometry["dock_tolerance"]) * 0.6
        self.approach_distance = approach_distance
        self.max_speed = float(geometry["max_speed"])
        self.speed = min(speed, self.max_speed * 0.8)
        self.turn_rate = turn_rate
        self.extrusion = extrusion
        self.tolerance = tolerance
        self.yaw_tolerance = yaw_tolerance
        self.leg_tolerance = float(SPEC.defaults.shape_tolerance.position)
        self.goals: dict[str, Pose2] = {}
        self.plans: list[_GroupPlan] = []

    # -- setting up a phase ------------------------------------------------------------

    def begin(self, action: Action, phase: Phase, observation: Observation) -> float | None:
        """Plan every moving group's stops or path; the driver time the slowest group's
        drive takes at cruise speed and turn rate [s] (``None`` in other phases)."""
        for module, goal in action.goals.items():
            self.goals[module] = (float(goal[0]), float(goal[1]), float(goal[2]))
        self.plans = []
        poses = _planar(observation)
        if phase is Phase.MOVE and action.goals:
            targets = {m: self.goals[m] for m in action.goals}
        elif phase in (Phase.APPROACH, Phase.CONNECT):
            targets = self._connection_targets(action, phase, observation, poses)
        else:
            return None
        # one plan per docked group: a moving action may drive several groups at once
        for component in _components(observation):
            modules = sorted(component & set(targets))
            if modules:
                self.plans.append(self._group_plan(modules, targets, phase, poses))
        return max((self._drive_time(plan, poses) for plan in self.plans), default=0.0)

    def _drive_time(self, plan: _GroupPlan, poses: Mapping[str, Pose2]) -> float:
        """Driver time [s] of ``plan`` under the stop and turn laws
        (:func:`settling_time`): its stops (or path waypoints, then the turn onto the goal
        heading) from the group's centre."""
        here = self._current_centre(plan, poses)
        course = plan.stops or [(*w, here[2]) for w in plan.waypoints] + [plan.centre]
        seconds = 0.0
        for stop in course:
            seconds += (settling_time(math.dist(here[:2], stop[:2]), DRIVE_GAIN, self.speed,
                                      self.tolerance, MIN_DRIVE_SPEED)
                        + settling_time(wrap_angle(stop[2] - here[2]), TURN_GAIN, self.turn_rate,
                                        self.yaw_tolerance))
            here = stop
        return seconds

    def _group_plan(self, modules: list[str], targets: Mapping[str, Pose2], phase: Phase,
                    poses: Mapping[str, Pose2]) -> _GroupPlan:
        mine = {m: targets[m] for m in modules}
        others = [poses[m][:2] for m in poses if m not in mine]
        plan = _GroupPlan(modules, mine, self._approach_sign(mine, others))
        centre = self._current_centre(plan, poses)
        target = plan.centre
        if phase is Phase.MOVE:
            plan.stops, plan.stage = self._leg_stops(centre, target), "stops"
            plan.legged = True
        elif math.dist(centre[:2], target[:2]) < 0.05 and abs(wrap_angle(centre[2] - target[2])) < 0.1:
            plan.stage = "line"
        else:
            self._plan_path(plan, poses)
        return plan

    @staticmethod
    def _leg_stops(centre: Pose2, target: Pose2) -> list[Pose2]:
        """The group centre's poses along one leg of a plan, as :mod:`..motion` drives it:
        along x straight to the target; along y a quarter turn in place, the drive
        turned, and the turn back."""
        if abs(target[1] - centre[1]) <= abs(target[0] - centre[0]):
            return [target]
        turned = wrap_angle(target[2] + math.pi / 2)
        return [(centre[0], centre[1], turned), (target[0], target[1], turned), target]

    def _connection_targets(self, action: Action, phase: Phase, observation: Observation,
                            poses: Mapping[str, Pose2]) -> dict[str, Pose2]:
        components = _components(observation)
        targets: dict[str, Pose2] = {}
        for change in action.changes:
            if change.source_port is None or change.target_port is None:
                continue
            a, b = change.source, change.target
            comp_a = next(c for c in components if a in c)
            comp_b = next(c for c in components if b in c)
            if comp_a is comp_b:
                continue
            if len(comp_a) < len(comp_b):
                mover, partner, partner_face, group = a, b, change.target_port, comp_a
            else:
                mover, partner, partner_face, group = b, a, change.source_port, comp_b
            reach = self.pitch - (self.extrusion if phase is Phase.CONNECT else 0.0)
            goal = neighbour_pose(poses[partner], partner_face, reach)
            now = poses[mover]
            turn = wrap_angle(goal[2] - now[2])
            c, s = math.cos(turn), math.sin(turn)
            for member in group:
                dx, dy = poses[member][0] - now[0], poses[member][1] - now[1]
                targets[member] = (goal[0] + c * dx - s * dy, goal[1] + s * dx + c * dy,
                                   goal[2])
        return targets

    def _approach_sign(self, targets: Mapping[str, Pose2], others: list[tuple[float, float]]
                       ) -> float:
        best, best_clear = 1.0, -math.inf
        for sign in (1.0, -1.0):
            clear = math.inf
            for x, y, yaw in targets.values():
                back = (x - sign * self.approach_distance * math.cos(yaw),
                        y - sign * self.approach_distance * math.sin(yaw))
                clear = min(clear, segment_clearance(back, (x, y), others),
                            segment_clearance(back, back, others) - 0.05)
            if clear >= self.pitch - 0.03:
                return sign
            if clear > best_clear:
                best, best_clear = sign, clear
        return best

    def _current_centre(self, plan: _GroupPlan, poses: Mapping[str, Pose2]) -> Pose2:
        pts = np.array([poses[m][:2] for m in plan.modules])
        c = pts.mean(axis=0)
        return float(c[0]), float(c[1]), poses[plan.modules[0]][2]

    def _pre_goal(self, plan: _GroupPlan) -> tuple[float, float]:
        x, y, yaw = plan.centre
        d = plan.sign * self.approach_distance
        return x - d * math.cos(yaw), y - d * math.sin(yaw)

    def _plan_path(self, plan: _GroupPlan, poses: Mapping[str, Pose2]) -> None:
        centre = self._current_centre(plan, poses)
        radius = max(math.dist(poses[m][:2], centre[:2]) for m in plan.modules)
        others = [poses[m][:2] for m in poses if m not in plan.modules]
        clearance = radius + 2 * self.half_diagonal + 0.03
        plan.waypoints = plan_path(centre[:2], self._pre_goal(plan), others, clearance)
        plan.stage = "path"

    # -- one tick ---------------------------------------------------------------------

    def control(self, action: Action, phase: Phase, observation: Observation) -> Control:
        poses = _planar(observation)
        commands: dict[str, ModuleCommand] = {}
        errors: dict[str, float] = {}
        reached = True
        for plan in self.plans:
            centre = self._current_centre(plan, poses)
            v, omega, done = self._drive(plan, centre, poses)
            reached &= done
            commands.update(self._tracks(plan, centre, poses, v, omega))
            errors.update({m: math.dist(poses[m][:2], plan.targets[m][:2])
                           for m in plan.modules})
        return Control(commands=commands, errors=errors, reached=reached)

    def _tracks(self, plan: _GroupPlan, centre: Pose2, poses: Mapping[str, Pose2], v: float,
                omega: float) -> dict[str, ModuleCommand]:
        """Each member's track speeds for the group twist ``(v, omega)`` about ``centre``."""
        tracks = {}
        for module in plan.modules:
            r = np.subtract(poses[module][:2], centre[:2])
            left_offset = float(-r[0] * math.sin(centre[2]) + r[1] * math.cos(centre[2]))
            tracks[module] = track_speeds(v, omega, left_offset, self.width)
        # one scale for the whole group: a module's driver clips its own tracks to
        # max_speed, which would bend the group's twist (a turn would drift its centre)
        scale = max(1.0, *(abs(t) / self.max_speed for pair in tracks.values() for t in pair))
        return {m: ModuleCommand(wheels={"left": left / scale, "right": right / scale})
                for m, (left, right) in tracks.items()}

    def _follow_stops(self, plan: _GroupPlan, centre: Pose2) -> tuple[float, float]:
        """Toward the next stop of a leg: turn in place at it, else drive straight along
        its heading (forwards or backwards) with lateral and heading correction."""
        stop = plan.stops[0]
        heading = np.array([math.cos(stop[2]), math.sin(stop[2])])
        delta = np.subtract(stop[:2], centre[:2])
        along = float(delta @ heading)
        lateral = float(delta @ np.array([-heading[1], heading[0]]))
        yaw_error = wrap_angle(stop[2] - centre[2])
        if abs(along) < self.tolerance:
            if abs(yaw_error) < self.yaw_tolerance:
                plan.stops.pop(0)
                return 0.0, 0.0
            return 0.0, float(np.clip(TURN_GAIN * yaw_error, -self.turn_rate, self.turn_rate))
        v = float(np.clip(DRIVE_GAIN * along, -self.speed, self.speed))
        if abs(v) < MIN_DRIVE_SPEED:
            v = math.copysign(MIN_DRIVE_SPEED, along)
        omega = 2.5 * yaw_error + 6.0 * lateral * math.copysign(1.0, v)
        return v, float(np.clip(omega, -self.turn_rate, self.turn_rate))

    def _drive(self, plan: _GroupPlan, centre: Pose2, poses: Mapping[str, Pose2]
               ) -> tuple[float, float, bool]:
        target = plan.centre
        if plan.stage == "stops":
            if plan.stops:
                return (*self._follow_stops(plan, centre), False)
            plan.stage = "line"
        if plan.stage == "path":
            goal = plan.waypoints[-1]
            if math.dist(centre[:2], goal) < 0.02:
                plan.stage = "align"
            else:
                return (*self._pursue(plan, centre), False)
        if plan.stage == "align":
            error = wrap_angle(target[2] - centre[2])
            if abs(error) < self.yaw_tolerance:
                plan.stage = "line"
            else:
                return 0.0, float(np.clip(TURN_GAIN * error, -self.turn_rate, self.turn_rate)), \
                    False
        heading = np.array([math.cos(target[2]), math.sin(target[2])])
        left = np.array([-heading[1], heading[0]])
        delta = np.subtract(target[:2], centre[:2])
        along, lateral = float(delta @ heading), float(delta @ left)
        yaw_error = wrap_angle(target[2] - centre[2])
        lateral_reach = self.tolerance * 2
        if plan.legged:  # a plan's leg: its sweep, no detours; the next leg or dock corrects
            lateral_reach = self.leg_tolerance
            if abs(lateral) >= lateral_reach and abs(along) < 0.02:  # the leg again from here
                plan.stops, plan.stage = self._leg_stops(centre, target), "stops"
                return 0.0, 0.0, False
        elif (abs(lateral) > self.lateral_limit * 2.5 and abs(along) < 0.08) or (
                abs(lateral) > 2 * self.tolerance and abs(along) < 0.02):
            self._plan_path(plan, poses)
            return 0.0, 0.0, False
        if abs(along) < self.tolerance and abs(lateral) < lateral_reach \
                and abs(yaw_error) < self.yaw_tolerance:
            return 0.0, 0.0, True
        v = float(np.clip(DRIVE_GAIN * along, -self.speed * 0.6, self.speed * 0.6))
        if abs(along) > self.tolerance / 2 and abs(v) < MIN_DRIVE_SPEED:
            v = math.copysign(MIN_DRIVE_SPEED, along)
        if abs(along) <= self.tolerance / 2:
            v = 0.0
        omega = 2.5 * yaw_error + (12.0 * lateral * math.copysign(1.0, v) if v else 0.0)
        return v, float(np.clip(omega, -self.turn_rate, self.turn_rate)), False

    def _pursue(self, plan: _GroupPlan, centre: Pose2) -> tuple[float, float]:
        here = np.array(centre[:2])
        points = [np.array(w) for w in plan.waypoints]
        nearest = min(range(len(points)), key=lambda i: float(np.linalg.norm(points[i] - here)))
        plan.waypoints = plan.waypoints[nearest:]
        points = points[nearest:]
        aim = next((p for p in points if np.linalg.norm(p - here) > 0.12), points[-1])
        bearing = math.atan2(aim[1] - here[1], aim[0] - here[0])
        error = wrap_angle(bearing - centre[2])
        direction = 1.0
        if abs(error) > math.pi / 2:
            direction, error = -1.0, wrap_angle(error + math.pi)
        omega = float(np.clip(TURN_GAIN * error, -self.turn_rate, self.turn_rate))
        if abs(error) > 0.35:
            return 0.0, omega
        distance = float(np.linalg.norm(points[-1] - here))
        speed = min(self.speed, 0.6 * distance + 0.02) * math.cos(error)
        return direction * speed, omega
