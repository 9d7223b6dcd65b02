"""The drive controller: the generic runtime's controller in physics (the ``mujoco`` driver).

It reads only the observation -- the tracker's poses (``Observation.tracked``) and the
modules' reports
(:class:`~msrr.core.generic.driver.ModuleReading`: latches, joint encoders) -- and
commands wheel speeds and hinge goals; the executor arms and releases the ports. Every
tolerance is the robot's :class:`~msrr.core.robot.DockTolerance`.

* **dock between two groups** (approach, then connect): the group that can move (every
  module wheeled), the smaller one first, drives so that its port comes to the other's:
  clear of its neighbours first (straight along its heading), to a point ``APPROACH``
  body sizes out on the line of its final heading, through a detour around the others
  if the straight way is blocked, turns onto that line and drives along it to the docked
  pose (a side port slides in alongside), a small gap left along the port normal for
  the latch to close. The docked pose is read from the fixed module's tracked pose when
  this final approach begins; if that module moves (pushed), or if near the end of the
  line the group is off it by more than half the dock tolerance (a group docked in a
  row turns only by sliding its wheels sideways, and ends its turn off the line), it
  backs off to the line's start, steering back onto it, and comes in again. Each
  module of a moving group gets the wheel speeds of the group's rigid motion at its
  place (differential drive), scaled together within the wheels' top speeds.
* **dock within a group** (closing a loop): the hinge angles of the group that bring the
  two ports together (least squares from the reported angles, :func:`close_loop`) become
  hinge goals; reached when the encoders are there and the ports within tolerance.
* **move**: planar goals ``{module: [x, y, yaw]}`` are driven to like a dock's pose; a
  move without goals that changes connection vectors (a goal that differs in shape
  only) sets the hinge angles that lay the target out
  (:func:`msrr.core.bodies.vector_angles`) and is reached when the encoders are there.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import networkx as nx
import numpy as np

from ..bodies import (
    UNBENT,
    Frame,
    close_loops,
    connection_hinge,
    docked_pose,
    frame_of,
    hinge_edges,
    inscribed,
    layout,
    port_frame,
    port_mismatch,
    vector_angles,
)
from ..configuration import Configuration
from ..control import Control
from ..driver import ModuleCommand, Observation
from ..errors import ExecutionError
from ..events import Phase
from ..plan import Action, ConnectionChange
from ..robot import Hinge, ModuleKind, RobotSpec
from .geometry import wrap_angle
from .readings import ModuleReading

__all__ = ["DriveController"]

APPROACH = (1.6, 2.0, 2.5, 3.0, 4.0)
"""Distances of the approach point from the docked pose, in sizes of the moving group:
the first with room to turn there is taken."""

GAIN_TURN = 2.5
"""Heading loop gain [1/s]."""

GAIN_LINE = 10.0
"""Heading toward the final line per lateral error [1/m] (of ``atan``)."""

LINE_ANGLE = 0.05
"""Largest angle [rad] at which a module steers back onto its final line."""

GATE = 0.3
"""Fraction of the final line, before the docked pose, within which the leader must be on
the line within half the dock tolerance (else it backs off and comes in again)."""

GAIN_TRIM = 1.0
"""Integral gain [1/s] of a hinge goal's trim on its encoder's error."""

STALL = (3.0, 0.01)
"""A fold has stalled when the sum of its hinges' errors has not fallen by ``STALL[1]``
[rad] in ``STALL[0]`` [s] after its servos have had time to turn to their goals."""


MAX_TURN_RATE = 1.5
"""Largest commanded turn rate [rad/s] (a tenth of a turn per 10 Hz tick at most)."""


def _turn_rate(turn: float) -> float:
    """The turn rate [rad/s] that steers out a heading error ``turn`` [rad]."""
    return max(-MAX_TURN_RATE, min(MAX_TURN_RATE, GAIN_TURN * turn))


def _yaw(rotation: np.ndarray) -> float:
    return math.atan2(float(rotation[1, 0]), float(rotation[0, 0]))


def _frame(observation: Observation, module: str) -> Frame:
    pose = observation.tracked[module]
    x, y, z, w = (float(v) for v in pose.orientation)
    rotation = np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    return rotation, np.asarray(pose.position, dtype=float)


def _reported(spec: RobotSpec, observation: Observation) -> tuple[Configuration,
                                                                   dict[str, float]]:
    """The configuration the reports show (ports only) and each hinge edge's angle [rad]
    in the convention of :func:`~msrr.core.bodies.docked_pose` (from its encoder)."""
    config = Configuration(spec.name)
    readings = {m: r for m, r in observation.sensors.items() if isinstance(r, ModuleReading)}
    for module, reading in readings.items():
        config.add_module(module, reading.kind)
    angles = {}
    for module, reading in readings.items():
        for latch in reading.latches:
            if latch.port is None or latch.other_port is None:
                continue
            edge_id = config.connect(module, latch.other, ports=(latch.port, latch.other_port))
            source, target = spec.kind(reading.kind), spec.kind(readings[latch.other].kind)
            if connection_hinge((source, target), (latch.port, latch.other_port)) is None:
                continue
            if source.hinge is not None and source.hinge.port == latch.port:
                angles[edge_id] = float(reading.joints.get(latch.port, 0.0))
            else:
                angles[edge_id] = -float(readings[latch.other].joints.get(latch.other_port, 0.0))
    return config, angles


@dataclass
class _Drive:
    """A wheeled group led by ``leader`` to ``final`` (rotation, position), along
    ``waypoints`` (positions), then the final line from ``line`` (its start)."""

    leader: str
    group: set[str]
    final: Frame
    waypoints: deque = field(default_factory=deque)
    clear: bool = False
    out: float = 0.0  # the way out of its neighbours: +1 forward, -1 backward
    pivot: np.ndarray = field(default_factory=lambda: np.zeros(3))  # group centre, leader frame
    line: np.ndarray | None = None
    dock: tuple[str, str, str] | None = None  # fixed module, its port, the leader's port
    anchor: Frame | None = None  # the fixed module's pose when the final approach began
    backing: bool = False  # backing off to the line's start to align again


@dataclass
class _Fold:
    """Hinge goals (edge id -> rad) of a group, and the dock they make, if any; ``trim``
    (edge id -> rad) the integral of each encoder's error once its servo has had time to
    turn to the goal, added to what the servo is told (a servo of bounded stiffness sags
    under load: folding a long chain on the floor, a few hundredths of a radian at each
    hinge add up along it); ``start`` when and where each hinge began [s], [rad]."""

    goals: dict[str, float]
    change: ConnectionChange | None = None
    trim: dict[str, float] = field(default_factory=dict)
    start: dict[str, tuple[float, float]] = field(default_factory=dict)
    time: float | None = None
    best: tuple[float, float] = (math.inf, 0.0)  # least error sum [rad], since [s]
    stalled: str = ""


class DriveController:
    """The generic runtime's controller in physics (see the module docstring)."""

    name = "drive"
    description = "wheels and hinges to docked poses in physics (generic runtime)"
    generic = True

    def __init__(self, spec: RobotSpec):
        self.spec = spec
        self.tolerance = spec.defaults.dock_tolerance
        self.jobs: deque = deque()
        self.job: _Drive | _Fold | None = None
        self.target: Configuration | None = None
        self.arrived = False

    # -- the controller protocol --------------------------------------------------------

    def begin(self, action: Action, phase: Phase, observation: Observation) -> None:
        if phase is Phase.CONNECT:
            return  # the approach's last job keeps pushing while the ports latch
        self.job, self.jobs, self.arrived = None, deque(), False
        self.target = action.target
        if phase is Phase.MOVE:
            if action.goals:
                self.jobs.extend(sorted(action.goals.items()))
            else:
                goals = vector_angles(action.target, self.spec)
                if goals:
                    self.jobs.append(_Fold(goals))
        elif phase is Phase.APPROACH:
            self.jobs.extend(action.made())

    def control(self, action: Action, phase: Phase, observation: Observation) -> Control:
        commands: dict[str, ModuleCommand] = {}
        errors: dict[str, float] = {}
        if phase in (Phase.MOVE, Phase.APPROACH, Phase.CONNECT):
            self._advance(observation, commands, errors, phase)
        stalled = self.job.stalled if isinstance(self.job, _Fold) else ""
        return Control(commands, errors, reached=(self.job is None or self.arrived)
                       and not self.jobs, stalled=stalled)

    # -- jobs ---------------------------------------------------------------------------

    def _advance(self, observation: Observation, commands: dict[str, ModuleCommand],
                 errors: dict[str, float], phase: Phase) -> None:
        config, angles = _reported(self.spec, observation)
        while True:
            if self.job is None:
                if not self.jobs:
                    return
                self.job = self._start(self.jobs.popleft(), observation, config, angles)
                if self.job is None:
                    continue
            done = (self._drive(self.job, observation, commands, errors, phase)
                    if isinstance(self.job, _Drive)
                    else self._fold(self.job, observation, config, angles, commands, errors))
            if not done or phase is Phase.CONNECT:
                return
            if phase is Phase.APPROACH and not self.jobs:
                self.arrived = True  # the last dock: it keeps pressing while it latches
                return
            self.job = None

    def _start(self, item: object, observation: Observation, config: Configuration,
               angles: dict[str, float]) -> _Drive | _Fold | None:
        groups = {m: g for g in nx.connected_components(config.undirected()) for m in g}
        if isinstance(item, _Fold):
            return item
        if isinstance(item, ConnectionChange):
            if any({e.source, e.target} == {item.source, item.target}
                   and set(e.ports or ()) == {item.source_port, item.target_port}
                   for e in config.edges()):
                return None  # already latched
            if groups[item.source] is groups[item.target]:
                return self._close(item, config, angles)
            return self._dock_drive(item, observation, groups)
        module, goal = item  # type: ignore[misc]
        x, y, yaw = (float(v) for v in goal[:3])
        rotation, position = _frame(observation, module)
        turn = np.array([[math.cos(yaw), -math.sin(yaw), 0.0], [math.sin(yaw), math.cos(yaw),
                                                               0.0], [0.0, 0.0, 1.0]])
        return self._plan_drive(module, set(groups[module]), (turn, np.array(
            [x, y, position[2]])), observation, None)

    def _close(self, change: ConnectionChange, config: Configuration,
               angles: dict[str, float]) -> _Fold:
        """Hinge goals that dock ``change`` within one group: the angles that lay the
        action's target out (its vectors say which way to fold; a straight hinge folds the
        positive way, as :func:`~msrr.core.bodies.with_port_vectors` lays loops out),
        closed exactly from there."""
        closing = [(change.source, change.source_port, change.target, change.target_port)]
        if hinge_edges(config, self.spec):
            start = {**angles, **vector_angles(self.target, self.spec)}
            start = {e: a if abs(a) > UNBENT else UNBENT for e, a in start.items()}
            goals, gap = close_loops(config, self.spec, closing, start)
        else:  # rigid ports: a loop the geometry closes is already aligned
            goals, gap = {}, self._gap(config, angles, change)
        if gap > self.tolerance.position / 2:
            raise ExecutionError(f"drive controller: no hinge angles of the group dock "
                                 f"{change.source}{change.source_port}-{change.target}"
                                 f"{change.target_port} (a gap of {gap:.3g} m is left)")
        return _Fold(goals, change)

    def _dock_drive(self, change: ConnectionChange, observation: Observation,
                    groups: dict[str, set[str]]) -> _Drive:
        options = []
        for moving, fixed in ((change.target, change.source), (change.source, change.target)):
            if all(self._kind(observation, m).wheels is not None for m in groups[moving]):
                options.append((len(groups[moving]), moving != change.target, moving, fixed))
        if not options:
            raise ExecutionError(f"drive controller: neither {change.source} nor "
                                 f"{change.target} can move to dock (their groups are not all "
                                 "wheeled)")
        _, _, moving, fixed = min(options)
        fixed_port = change.source_port if fixed == change.source else change.target_port
        moving_port = change.target_port if fixed == change.source else change.source_port
        dock = (fixed, fixed_port, moving_port)
        final, normal = self._docked(observation, moving, dock)
        job = self._plan_drive(moving, set(groups[moving]), final, observation, normal)
        job.dock = dock
        return job

    def _docked(self, observation: Observation, moving: str, dock: tuple[str, str, str],
                *, gap: bool = True, at: Frame | None = None) -> tuple[Frame, np.ndarray]:
        """Where ``moving`` docks to ``dock`` (fixed module, its port, moving's port) as
        the fixed module is now (or ``at``), with ``gap`` half the latch distance left along
        the fixed port's horizontal normal; and that normal."""
        fixed, fixed_port, moving_port = dock
        kinds = (self._kind(observation, fixed), self._kind(observation, moving))
        here = _frame(observation, fixed) if at is None else at
        final = frame_of(here, docked_pose(kinds, (fixed_port, moving_port)))
        normal = here[0] @ port_frame(kinds[0], fixed_port)[0][:, 0]
        normal[2] = 0.0
        normal /= max(float(np.linalg.norm(normal)), 1e-9)
        shift = self.tolerance.position / 2 if gap else 0.0
        return (final[0], final[1] + shift * normal), normal

    def _plan_drive(self, leader: str, group: set[str], final: Frame, observation: Observation,
                    normal: np.ndarray | None) -> _Drive:
        """The approach line's side (along the final heading, from outside the fixed
        port, else whichever line is clear) and the detour to its start."""
        heading = final[0][:, 0].copy()
        heading[2] = 0.0
        heading /= np.linalg.norm(heading)
        size = 2 * max(max(self._kind(observation, m).body.half_extents) for m in group)
        signs = [1.0, -1.0]
        if normal is not None and abs(float(normal @ heading)) > 0.5:
            signs = [-math.copysign(1.0, float(normal @ heading))]  # come in against the normal
        rotation, position = _frame(observation, leader)
        centre = np.mean([_frame(observation, m)[1] for m in group], axis=0)
        pivot = rotation.T @ (centre - position)
        pivot[2] = 0.0
        final = (final[0], final[1] + final[0] @ pivot)  # where the group's centre goes
        offsets = self._offsets(observation, group, centre)
        others = [m for m in observation.tracked if m not in group]
        fixed = np.array([_frame(observation, m)[1] for m in others]) if others else None
        turning = 2 * self._reach(observation, group, centre)
        choices = []
        for sign in signs:  # a clear line first, then room to turn at its start, shorter
            for distance in APPROACH:
                start = final[1] - sign * distance * size * heading
                room = math.inf if fixed is None else float(np.min(np.linalg.norm(
                    (start + offsets)[:, None, :2] - fixed[None, :, :2], axis=2)))
                if room >= turning or distance == APPROACH[-1]:
                    break
            choices.append((not self._free(observation, offsets, others, start, final[1]),
                            room < turning, distance, sign, start))
        *_, sign, start = min(choices, key=lambda c: c[:3])
        route = self._route(observation, offsets, others, centre, start, size)
        return _Drive(leader, group, (final[0], final[1] - final[0] @ pivot),
                      deque([*route, start]), line=start - final[1], pivot=pivot)

    def _offsets(self, observation: Observation, group: set[str], centre: np.ndarray
                 ) -> np.ndarray:
        return np.array([_frame(observation, m)[1] - centre for m in sorted(group)])

    def _free(self, observation: Observation, offsets: np.ndarray, others: list[str],
              a: np.ndarray, b: np.ndarray, margin: float = 0.0) -> bool:
        """Whether the group (``offsets`` from its leader) carried from ``a`` to ``b`` keeps
        its centres a body size (plus ``margin``) from every other module's."""
        if not others:
            return True
        fixed = np.array([_frame(observation, m)[1] for m in others])
        size = 2 * max(inscribed(self._kind(observation, m)) for m in observation.tracked)
        for t in np.linspace(0.0, 1.0, 25):
            at = a + t * (b - a) + offsets
            gaps = np.linalg.norm(at[:, None, :2] - fixed[None, :, :2], axis=2)
            if np.any(gaps < size - 1e-3 + margin):
                return False
        return True

    def _route(self, observation: Observation, offsets: np.ndarray, others: list[str],
               here: np.ndarray, goal: np.ndarray, size: float) -> list[np.ndarray]:
        """Waypoints before ``goal``: none when the way is clear, else the shortest clear
        detour through one or two corners of the others' bounding box, ``size`` out."""
        margin = 0.2 * size
        if self._free(observation, offsets, others, here, goal, margin):
            return []
        fixed = np.array([_frame(observation, m)[1] for m in others])
        reach = float(np.max(np.linalg.norm(offsets[:, :2], axis=1))) + 1.5 * size
        low, high = fixed.min(axis=0) - reach, fixed.max(axis=0) + reach
        corners = [np.array([x, y, here[2]]) for x in (low[0], high[0]) for y in (low[1], high[1])]
        paths = [[c] for c in corners] + [[c, d] for c in corners for d in corners
                                          if not np.allclose(c, d)]
        best = None
        for path in paths:
            points = [here, *path, goal]
            if all(self._free(observation, offsets, others, p, q, margin)
                   for p, q in zip(points, points[1:], strict=False)):
                length = sum(float(np.linalg.norm(q - p)) for p, q in zip(points, points[1:],
                                                                           strict=False))
                if best is None or length < best[0]:
                    best = (length, path)
        return [] if best is None else best[1]

    # -- driving ------------------------------------------------------------------------

    def _drive(self, job: _Drive, observation: Observation,
               commands: dict[str, ModuleCommand], errors: dict[str, float],
               phase: Phase) -> bool:
        rotation, here = _frame(observation, job.leader)
        here = here + rotation @ job.pivot
        yaw = _yaw(rotation)
        if job.dock is not None:
            job.final = self._target(job, observation, phase)
        final_yaw = _yaw(job.final[0])
        tol = self.tolerance
        goal = job.final[1] + job.final[0] @ job.pivot
        error = goal[:2] - here[:2]
        errors[job.leader] = float(np.linalg.norm(error))
        if not job.clear:
            job.clear = self._clear_out(job, observation, commands, yaw)
            if not job.clear:
                return False
        if job.waypoints:
            target = job.waypoints[0]
            delta = target[:2] - here[:2]
            distance = float(np.linalg.norm(delta))
            if distance < tol.position * (0.25 if len(job.waypoints) == 1 else 2):
                job.waypoints.popleft()
                return False
            turn = wrap_angle(math.atan2(delta[1], delta[0]) - yaw)
            speed = 0.0 if abs(turn) > min(0.25, 4 * distance) else min(1.0, distance / 0.05)
            self._command(job, observation, commands, speed, _turn_rate(turn))
            return False
        heading = np.array([math.cos(final_yaw), math.sin(final_yaw)])
        along = float(error @ heading)
        lateral = float(error @ np.array([-heading[1], heading[0]]))
        turn = wrap_angle(final_yaw - yaw)
        if abs(along) <= tol.position / 2 and abs(lateral) <= tol.position / 2 and \
                abs(turn) <= tol.angle / 2:
            self._command(job, observation, commands, 0.0, 0.0)
            return True
        if job.line is not None:
            if job.anchor is None and job.dock is not None:
                job.anchor = _frame(observation, job.dock[0])  # the final approach begins
            along, lateral = self._gate(job, along, lateral)
        direction = 1.0 if along >= 0 else -1.0
        steer = max(-LINE_ANGLE, min(LINE_ANGLE, math.atan(GAIN_LINE * lateral)))
        turn = wrap_angle(final_yaw + direction * steer - yaw)
        if abs(turn) > LINE_ANGLE + tol.angle / 4 or abs(along) <= tol.position / 2:
            self._command(job, observation, commands, 0.0, _turn_rate(turn))
            return False
        speed = direction * max(0.1, min(1.0, abs(along) / 0.05))
        self._command(job, observation, commands, speed, _turn_rate(turn))
        return False

    def _target(self, job: _Drive, observation: Observation, phase: Phase) -> Frame:
        """The leader's docked pose at the fixed module as it was when the final approach
        began (in the connect phase with no gap: it presses on the port); if the fixed
        module has since moved by more than half the dock tolerance (pushed), the approach
        is aborted: back off to the line's start and read its pose again."""
        fixed = job.dock[0]
        now = _frame(observation, fixed)
        if job.anchor is not None and phase is not Phase.CONNECT:
            moved = float(np.linalg.norm((now[1] - job.anchor[1])[:2]))
            turned = abs(wrap_angle(_yaw(now[0]) - _yaw(job.anchor[0])))
            if moved > self.tolerance.position / 2 or turned > self.tolerance.angle / 2:
                job.anchor, job.backing = None, True
        return self._docked(observation, job.leader, job.dock, gap=phase is not Phase.CONNECT,
                            at=job.anchor or now)[0]

    def _gate(self, job: _Drive, along: float, lateral: float) -> tuple[float, float]:
        """The errors [m] along and across the final line to steer out: to the docked pose,
        or, backing off, to the line's start. Near its end (within :data:`GATE` of the
        line) the leader must be on the line within half the dock tolerance, else it backs
        off to the line's start and comes in again (a wheeled group cannot slide sideways,
        and pushing on would shove the target)."""
        heading = job.final[0][:2, 0] / max(float(np.linalg.norm(job.final[0][:2, 0])), 1e-9)
        offset = (float(job.line[:2] @ heading),
                  float(job.line[:2] @ np.array([-heading[1], heading[0]])))
        length = float(np.linalg.norm(job.line[:2]))
        if job.backing and abs(along + offset[0]) <= self.tolerance.position / 2:
            job.backing, job.anchor = False, None  # at the line's start: in again
        elif not job.backing and abs(along) < GATE * length and \
                abs(lateral) > self.tolerance.position / 2:
            job.backing = True
        if job.backing:
            return along + offset[0], lateral + offset[1]
        return along, lateral

    def _clear_out(self, job: _Drive, observation: Observation,
                   commands: dict[str, ModuleCommand], yaw: float) -> bool:
        """Drive straight along the heading until every other body is a turning circle
        away (a module just undocked touches its old neighbour); whether clear."""
        others = [m for m in observation.tracked if m not in job.group]
        if not others:
            return True
        rotation, here = _frame(observation, job.leader)
        here = here + rotation @ job.pivot
        offsets = self._offsets(observation, job.group, here)
        reach = self._reach(observation, job.group, here)
        heading = np.array([math.cos(yaw), math.sin(yaw), 0.0])
        fixed = np.array([_frame(observation, m)[1] for m in others])

        def nearest(at: np.ndarray) -> float:
            points = at + offsets
            return float(np.min(np.linalg.norm(points[:, None, :2] - fixed[None, :, :2],
                                               axis=2)))

        if nearest(here) >= 2 * reach or not job.waypoints and nearest(here) >= 0.99 * 2 * min(
                inscribed(self._kind(observation, m)) for m in observation.tracked):
            return True
        if job.out == 0.0:  # once: the way with more room a turning circle out, else
            goal = job.waypoints[0] if job.waypoints else here  # toward the goal
            room = [(round(nearest(here + sign * 2 * reach * heading), 3),
                     -float(np.linalg.norm(here + sign * 2 * reach * heading - goal)), sign)
                    for sign in (1.0, -1.0)]
            job.out = max(room)[2]
        self._command(job, observation, commands, 0.6 * job.out, 0.0)
        return False

    def _reach(self, observation: Observation, group: set[str] | None = None,
               centre: np.ndarray | None = None) -> float:
        """The largest horizontal radius [m] a module's body (or ``group`` turning about
        ``centre``) sweeps turning in place."""
        def radius(m: str) -> float:
            return float(np.linalg.norm(self._kind(observation, m).body.half_extents[:2]))

        if group is None or centre is None:
            return max(radius(m) for m in observation.tracked)
        return max(radius(m) + float(np.linalg.norm((_frame(observation, m)[1] - centre)[:2]))
                   for m in group)

    def _command(self, job: _Drive, observation: Observation,
                 commands: dict[str, ModuleCommand], speed: float, omega: float) -> None:
        """Wheel speeds of every module of the group for the leader's forward ``speed``
        (fraction of the slowest module's) and turn rate ``omega`` [rad/s], all scaled by
        one factor so that no wheel is asked beyond its top speed (a group's rigid motion
        keeps its shape: scaled module by module, docked modules would fight)."""
        top = min(self._kind(observation, m).wheels.speed for m in job.group)
        v = speed * top
        rotation, here = _frame(observation, job.leader)
        here = here + rotation @ job.pivot  # the group turns about its centre
        heading = rotation[:, 0]
        rims = {}
        for m in job.group:
            wheels = self._kind(observation, m).wheels
            r, at = _frame(observation, m)
            velocity = v * heading + np.cross([0.0, 0.0, omega], at - here)
            forward = float(velocity @ r[:, 0])
            half = wheels.track / 2 * omega
            rims[m] = (forward - half, forward + half, wheels.speed)
        scale = max([1.0] + [abs(w) / limit for left, right, limit in rims.values()
                             for w in (left, right)])
        for m, (left, right, _) in rims.items():
            commands[m] = ModuleCommand(wheels={"left": left / scale, "right": right / scale})

    # -- folding ------------------------------------------------------------------------

    def _fold(self, job: _Fold, observation: Observation, config: Configuration,
              angles: dict[str, float], commands: dict[str, ModuleCommand],
              errors: dict[str, float]) -> bool:
        worst, total, turned, stuck = 0.0, 0.0, 0.0, ""
        period = 0.0 if job.time is None else observation.time - job.time
        job.time = observation.time
        for edge_id, goal in job.goals.items():
            edge = config.edge(edge_id) if edge_id in config.edge_ids() else None
            if edge is None:
                continue
            owner, sign = ((edge.source, 1.0) if self._hinge(config, edge)
                           is self.spec.kind(config.kind_of(edge.source)).hinge
                           else (edge.target, -1.0))
            port = edge.ports[0] if owner == edge.source else edge.ports[1]
            error = wrap_angle(goal - angles.get(edge_id, 0.0))
            hinge = self._hinge(config, edge)
            job.start.setdefault(edge_id, (observation.time, angles.get(edge_id, 0.0)))
            began, start = job.start[edge_id]
            there = began + abs(goal - start) / hinge.speed  # its servo has turned by then
            turned, total = max(turned, there), total + abs(error)
            if observation.time > there:
                trim = job.trim.get(edge_id, 0.0) + GAIN_TRIM * error * period
                job.trim[edge_id] = max(-hinge.limit, min(hinge.limit, trim))
            base = commands.get(owner, ModuleCommand())
            commands[owner] = ModuleCommand(joints={
                **base.joints, port: sign * (goal + job.trim.get(edge_id, 0.0))})
            if abs(error) > worst:
                worst, stuck = abs(error), (
                    f"hinge {edge_id} at {angles.get(edge_id, 0.0):+.2f} rad, {error:+.2f} rad "
                    f"from its goal {goal:+.2f} rad, its servo at most "
                    f"{hinge.torque:g} N m")
        errors["joints"] = worst
        if total < job.best[0] - STALL[1] or observation.time < turned:
            job.best = (min(total, job.best[0]), observation.time)
        elif worst > self.tolerance.angle / 2 and observation.time - job.best[1] > STALL[0]:
            job.stalled = f"{stuck}, has not moved for {STALL[0]:g} s"
        if worst > self.tolerance.angle / 2:
            return False
        if job.change is None:
            return True
        gap = self._gap(config, angles, job.change)
        errors[job.change.target] = gap
        return gap <= self.tolerance.position / 2

    def _hinge(self, config: Configuration, edge: object) -> Hinge:
        """The hinge of a hinge connection (its source's at its port, else its target's)."""
        source = self.spec.kind(config.kind_of(edge.source))
        if source.hinge is not None and source.hinge.port == edge.ports[0]:
            return source.hinge
        return self.spec.kind(config.kind_of(edge.target)).hinge

    def _gap(self, config: Configuration, angles: dict[str, float],
             change: ConnectionChange) -> float:
        """How far apart [m] the ports of ``change`` are, laid out from the reports."""
        poses, _ = layout(config, self.spec, angles)
        kinds = (self.spec.kind(config.kind_of(change.source)),
                 self.spec.kind(config.kind_of(change.target)))
        return float(np.linalg.norm(port_mismatch(
            poses[change.source], poses[change.target], kinds,
            (change.source_port, change.target_port))[0]))

    def _kind(self, observation: Observation, module: str) -> ModuleKind:
        return self.spec.kind(observation.sensors[module].kind)
