"""Where a FreeSN system is, from its own sensors: gyro headings and rolling-contact
odometry (issue 31, item 1; issue 32, item 1). Dead reckoning: it drifts.

The FreeSN paper commands a system in its root node's horizontal frame and gives each
node an IMU (sections 2.1, 4.2); nothing on the robot measures where it stands on the
floor. :class:`ImuOdometry` estimates both from the module reports and the recognized
configuration, never from a simulator:

* **heading**: each node's rotation is propagated by its gyro and levelled by its
  accelerometer, ``R <- R exp([w dt]) Q`` (``w`` the gyro's mean body rate over the step,
  ``Q`` the least rotation that turns the result's vertical onto the reported tilt's:
  an accelerometer measures the vertical only), and its heading is the twist of ``R``
  about the vertical (:func:`~msrr.core.freeform.mujoco.yaw_of`). Until stop 39 the
  heading was re-attached to each reported tilt with its twist taken out (``R <- Rz(psi)
  T``), a split that turns a tilt's noise into heading error without bound as the node
  nears upside down: node wheels spinning about a leg pass there, and under 2 deg of
  noise fig18's wheel nodes lost 60-120 deg of heading for 10-25 s at a time (seed 15).
  Over the module link, where the host holds a report until the next arrives, a
  report is integrated once, from the reading used last (:func:`gyro_since`: the stamp
  and the delta-angle counter, issue 32). A node seen for the first time takes the
  heading the recognizer gives
  it relative to the root (:func:`.recognizer.node_headings`). The system's heading is
  its root node's (:func:`.recognizer.root_order`), the frame its commands are in.
* **position**: the recognized configuration places the nodes relative to the root
  (skeletal forward kinematics, ``p_t = p_s + L z``); the lowest nodes (within
  :data:`CONTACT` of the lowest) stand on the floor. A node on the floor rolls without
  slipping: its centre moves at ``w x (r e_z)`` (``w`` its world rate from the gyro, ``r``
  the node radius), so a foot at rest stays put and a wheel node rolls. The root's place
  moves by the mean motion of the feet that stayed on the floor over the step, ``anchor_i
  + rolled_i - q_i`` (``q_i`` the foot's offset from the root, turned by the heading,
  ``anchor_i`` where the last step put it); every foot is then anchored where the shape
  puts it. The estimate is the centre of the nodes.

A strut on the floor (its wheels, Fig. 18(d)-(i), or its body rolled as a roller, Fig.
22(e)) reports no encoder, and the nodes it drags slide rather than roll: while a free
strut end reaches the floor (:func:`on_struts`) the place is not known (``None``), and
those behaviors run for a duration, their heading held by the gyros alone.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from msrr.core.alignment import rot_z, wrap_angle
from msrr.core.configuration import Configuration
from msrr.core.driver import Observation
from msrr.core.estimation import Estimate
from msrr.core.freeform.mujoco import yaw_of

from ..robot import NODE, STRUT
from .recognizer import links_of, node_headings, root_order
from .world import NodeReport

__all__ = ["CONTACT", "LATCH", "ImuOdometry", "gyro_since", "node_positions", "on_struts"]

CONTACT = 0.015
"""A node whose centre is at most this much [m] above the lowest node's stands on the
floor (recognized heights carry the reports' noise: 2 deg over a 0.2 m strut is 7 mm)."""


LEAP = (0.05, 0.5)
"""The farthest the root's estimated place may move in one update, ``(a, b)``: ``a + b dt``
[m, m/s]; a FreeSN system rolls at most ~0.07 m/s (wheel speed x wheel radius), and a
foot set that changes moves the place by the shape's noise (2 deg over 0.4 m: 1.4 cm)."""


UPRIGHT = -0.5
"""A node whose vertical axis points above this (its ``z`` component) is upright enough
for its twist about the vertical to be its heading (within 120 deg of upright)."""


LATCH = -0.7
"""A root turning over past :data:`UPRIGHT` hands its own heading on to its upright
nodes' mean only while its vertical's ``z`` component is above this (its twist's error
then at most ``1 / (1 + LATCH)``, 3.3 times an upright node's); found further over (a
first report, or upright nodes found again) it takes their mean as it is."""


def gyro_since(report: NodeReport, last: tuple[float, np.ndarray] | None, dt: float
               ) -> tuple[np.ndarray, float] | None:
    """A node's mean body rate (3,) [rad/s] since the reading used last and over how long
    [s]; ``None`` when its report is no new reading (issue 32: over the module link the
    host holds a report until the next arrives).

    Args:
        report: the node's report; without a ``stamp``, its ``gyro`` over ``dt``.
        last: the ``(stamp, turned)`` of the node's report used last, if any.
        dt: the observations' time step [s].

    A stamp not past ``last``'s is no new reading; one ``step`` past it, the report's
    ``gyro`` over the stamps' difference; further, the delta-angle counter's difference
    ``log(Q_0^T Q_1)`` over it (the steps of the reports missed between included). The
    same instant observed again (``dt`` 0) turns nothing, as before stamps.
    """
    if report.stamp is None or last is None or dt <= 0.0:
        return np.asarray(report.gyro, dtype=float), dt
    gap = report.stamp - last[0]
    if not gap > 0.0:
        return None
    if gap < 1.5 * report.step:
        return np.asarray(report.gyro, dtype=float), gap
    return Rotation.from_matrix(last[1].T @ report.turned).as_rotvec() / gap, gap


def _turned(rotvec: np.ndarray) -> np.ndarray:
    """The rotation matrix (3, 3) of a rotation vector (3,) (Rodrigues)."""
    angle = float(np.sqrt(rotvec @ rotvec))
    if angle < 1e-12:
        return np.eye(3)
    x, y, z = rotvec / angle
    k = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)


def _levelled(up: np.ndarray, predicted: np.ndarray) -> np.ndarray:
    """The least rotation (3, 3), in the node frame, that turns the gyro-propagated
    attitude's vertical ``predicted`` (3,) onto the accelerometer's ``up`` (3,) (both the
    world's vertical in node coordinates): ``R <- R Q`` with ``Q up = predicted``."""
    axis = np.cross(up, predicted)
    size = float(np.linalg.norm(axis))
    if size < 1e-12:
        return np.eye(3)
    return _turned(axis / size * math.atan2(size, float(up @ predicted)))


def node_positions(config: Configuration, root: str, length: float) -> dict[str, np.ndarray]:
    """Node centres [m], shape (3,) each, relative to ``root`` in ``config``'s frame: a
    breadth-first spanning tree of the struts between nodes, ``p_t = p_s + length z``.
    Nodes not connected to ``root`` are left out."""
    steps: dict[str, list[tuple[str, np.ndarray]]] = {}
    for edge in config.edges():
        if edge.z is None or config.is_virtual(edge.source) or config.is_virtual(edge.target):
            continue
        z = length * np.asarray(edge.z, dtype=float)
        steps.setdefault(edge.source, []).append((edge.target, z))
        steps.setdefault(edge.target, []).append((edge.source, -z))
    positions = {root: np.zeros(3)}
    queue = deque([root])
    while queue:
        u = queue.popleft()
        for v, step in steps.get(u, ()):
            if v not in positions:
                positions[v] = positions[u] + step
                queue.append(v)
    return positions


def on_struts(config: Configuration, placed: Mapping[str, np.ndarray], length: float,
              node_radius: float, strut_radius: float) -> bool:
    """Whether a free strut end of ``config`` reaches the floor: its tip, ``length`` [m]
    from its node along ``z``, is lower (less ``strut_radius``) than its own node's bottom
    (``node_radius`` below its centre; a strut lying level is not) and as low as the lowest
    node's bottom plus :data:`CONTACT`. The first compares one strut's vector with its
    own node (2 deg of noise: 7 mm), the second node heights along the shape (more).
    ``placed``: node centres [m], shape (3,) each, relative to the root
    (:func:`node_positions`)."""
    if not placed:
        return False
    floor = min(float(q[2]) for q in placed.values()) - node_radius + CONTACT
    for edge in config.edges():
        if edge.z is None:
            continue
        for node, free, sign in ((edge.source, edge.target, 1.0),
                                 (edge.target, edge.source, -1.0)):
            if node not in placed or not config.is_virtual(free):
                continue
            drop = sign * length * float(edge.z[2])   # tip below its node's centre: < 0
            if drop <= strut_radius - node_radius \
                    and float(placed[node][2]) + drop - strut_radius <= floor:
                return True
    return False


class ImuOdometry:
    """Heading and place of one FreeSN system over one run (see the module docstring).

    Args:
        root: the root node the recognizer was given (``None``: :func:`root_order`'s).
        length: strut length, node centre to node centre [m].
        radius: node radius [m].
        strut_radius: strut body radius [m].
    """

    def __init__(self, root: str | None = None, *, length: float = STRUT.geometry["length"],
                 radius: float = NODE.geometry["radius"],
                 strut_radius: float = STRUT.geometry["radius"]):
        self.root, self.length, self.radius = root, float(length), float(radius)
        self.strut_radius = float(strut_radius)
        self.time: float | None = None
        self.yaw: dict[str, float] = {}          # each node's heading [rad]
        self.tilt: dict[str, np.ndarray] = {}
        self.anchors: dict[str, np.ndarray] = {}  # feet on the floor, horizontal [m]
        self.origin = np.zeros(2)                 # the root's horizontal place [m]
        self.last: Estimate | None = None         # the last estimate accepted
        self.counted: dict[str, tuple[float, np.ndarray]] = {}  # stamp, counter used last
        self.spans: dict[str, float] = {}         # per node, the time its last turn covered
        self.carry: float | None = None           # root's own heading less the consensus [rad]

    def update(self, observation: Observation, configuration: Configuration) -> Estimate:
        """The estimate after ``observation`` and the configuration recognized from it."""
        reports: Mapping[str, Any] = observation.sensors
        nodes = {m: r for m, r in reports.items() if isinstance(r, NodeReport)}
        if not nodes:
            return Estimate()
        dt = 0.0 if self.time is None else max(0.0, observation.time - self.time)
        self.time = observation.time
        links = links_of(reports)
        root = self.root if self.root in nodes else root_order(list(nodes), links)[0]
        turned = self._turn(nodes, dt)
        self._first_seen(reports, links, root, [n for n in nodes if n not in self.yaw])
        placed = node_positions(configuration, root, self.length)
        heading = self._consensus(reports, links, root, placed)
        offsets = {n: rot_z(heading) @ p for n, p in placed.items()}
        if on_struts(configuration, placed, self.length, self.radius, self.strut_radius):
            self.anchors = {}  # what lands next is anchored where the shape puts it
            self.last = Estimate(position=None, heading=heading)
            return self.last
        if not self._step_feet(offsets, turned, dt, self.spans) and self.last is not None:
            return self.last
        centre = self.origin + np.mean([q[:2] for q in offsets.values()], axis=0)
        self.last = Estimate(position=centre, heading=heading)
        return self.last

    def _consensus(self, reports: Mapping[str, Any], links: dict, root: str,
                   group: Mapping[str, np.ndarray]) -> float:
        """The root's heading [rad]. A node's heading is the twist of its rotation about
        the vertical, which is singular when the node is turned over (the squirm's
        rolling root): there one report's noise swings it by radians. So a root turned
        past :data:`UPRIGHT` takes the mean over the group's upright nodes of their gyro
        heading less their heading relative to the root (the struts' attitudes,
        :func:`.recognizer.node_headings`), and so does every other node turned over; an
        upright root keeps its own.

        The mean is circular and weighted by ``(1 + cos tilt)^2``: the twist
        (:func:`~msrr.core.freeform.mujoco.yaw_of`) is the angle of a vector of length
        ``1 + cos tilt`` that a tilt's noise moves, so its error grows as ``1 / (1 + cos
        tilt)`` and this is its inverse variance. A node that turns past :data:`UPRIGHT`
        leaves the mean at a sixteenth of an upright node's weight; the circular median
        used before (stops 39-44) jumped to another node's heading when one left: +7 deg
        in one tick, kept for the rest of the run (fig19-squirm at 2 deg + 5 %, seed 10).

        The switch of source is continuous: when the root turns over (or finds upright
        nodes again) the mean is offset by what it differs from the root's own heading
        then (:attr:`carry`; only while that heading is still well defined, :data:`LATCH`),
        so it gives the heading's changes, not its level. The votes
        carry the relative headings' errors (the connectors' twist, slip on the rolling
        root's shell): at 2 deg + 5 %, seed 10 (stop 47), they differed from the root's
        own heading by 5 deg as it turned over, and the body's estimate jumped from 0.6
        to 8.4 deg off the truth, where it stayed.
        """
        if self.tilt[root][2, 2] >= UPRIGHT:
            self.carry = None
            return self.yaw[root]
        relative = node_headings(reports, links, root)
        members = [n for n in group if n in relative and n in self.yaw]
        upright = [n for n in members if self.tilt[n][2, 2] >= UPRIGHT]
        if not upright:
            self.carry = None
            return self.yaw[root]
        votes = np.array([self.yaw[n] - relative[n] for n in upright])
        weights = np.array([(1.0 + self.tilt[n][2, 2]) ** 2 for n in upright])
        heading = math.atan2(float(weights @ np.sin(votes)), float(weights @ np.cos(votes)))
        if self.carry is None:
            near = self.tilt[root][2, 2] >= LATCH
            self.carry = wrap_angle(self.yaw[root] - heading) if near else 0.0
        heading = wrap_angle(heading + self.carry)
        for n in members:
            if n not in upright:
                self.yaw[n] = wrap_angle(heading + relative[n])
        return heading

    def _turn(self, nodes: Mapping[str, NodeReport], dt: float) -> dict[str, np.ndarray]:
        """Each known node with a new reading: its attitude propagated by its gyro since
        the reading used last (:func:`gyro_since`) and levelled by its reported tilt (the
        module docstring); its world rate (3,) [rad/s] at the step's start (over how long
        [s]: :attr:`spans`)."""
        rates: dict[str, np.ndarray] = {}
        self.spans: dict[str, float] = {}
        for node, report in nodes.items():
            tilt = np.asarray(report.tilt, dtype=float)
            since = gyro_since(report, self.counted.get(node), dt)
            if since is None:
                continue
            if report.stamp is not None:
                self.counted[node] = (report.stamp, np.asarray(report.turned, dtype=float))
            if node not in self.yaw:
                self.tilt[node] = rot_z(-yaw_of(tilt)) @ tilt  # a tilt has no heading: noise
                continue
            gyro, span = since
            before = rot_z(self.yaw[node]) @ self.tilt[node]
            rates[node], self.spans[node] = before @ gyro, span
            after = before @ _turned(gyro * span)
            after = after @ _levelled(tilt[2], after[2])
            self.yaw[node] = yaw_of(after)
            self.tilt[node] = rot_z(-self.yaw[node]) @ after
        return rates

    def _first_seen(self, reports: Mapping[str, Any], links: dict, root: str,
                    new: list[str]) -> None:
        """Headings of nodes seen for the first time, from the recognizer's relative ones."""
        if not new:
            return
        relative = node_headings(reports, links, root)
        known = [n for n in relative if n in self.yaw and n not in new]
        base = self.yaw[known[0]] - relative[known[0]] if known else 0.0
        for node in new:
            self.yaw[node] = wrap_angle(base + relative.get(node, 0.0))

    def _step_feet(self, offsets: Mapping[str, np.ndarray], rates: Mapping[str, np.ndarray],
                   dt: float, spans: Mapping[str, float] | None = None) -> bool:
        """The feet on the floor roll by their rates (each over its ``spans`` entry, the
        time since its reading used last; default ``dt``); the root's place moves by
        their mean motion this step; every foot is then anchored where the shape puts it. ``False``
        (and nothing changed) when that place would move faster than :data:`LEAP` allows:
        a glitch of the recognized shape, not a motion.

        Anchors last one step, not from a foot's landing: node wheels scrub (each rolls
        25-50 deg off the body's travel, 2 m of rolling for 1.45 m of travel over
        fig18-node-wheels), so anchors kept per foot drift metres apart, and each change
        of the set of feet (a shape's noise lifting one past :data:`CONTACT`: a quarter
        of the ticks at 2 deg) jumped the place toward the subset left: the estimated
        travel turned 24 deg off the true one (issue 31, seed 13). The mean of the feet's
        motions is the least-squares rigid motion; with a constant set of feet the two
        agree exactly."""
        if not offsets:
            return True
        lowest = min(float(q[2]) for q in offsets.values())
        feet = [n for n, q in offsets.items() if float(q[2]) <= lowest + CONTACT]
        stayed = [n for n in feet if n in self.anchors]
        origin = self.origin
        if stayed:
            moved = []
            for node in stayed:
                rate, span = rates.get(node), dt if spans is None else spans.get(node, dt)
                rolled = np.zeros(2) if rate is None else \
                    span * self.radius * np.array([rate[1], -rate[0]])   # w x (r e_z)
                moved.append(self.anchors[node] + rolled - offsets[node][:2])
            origin = np.mean(moved, axis=0)
            if float(np.linalg.norm(origin - self.origin)) > LEAP[0] + LEAP[1] * dt:
                return False
        self.origin = origin
        self.anchors = {n: origin + offsets[n][:2] for n in feet}
        return True
