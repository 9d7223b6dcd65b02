"""FreeSN controllers: joint-vector targets -> per-connector commands (paper 4.1-4.2).

The inverse kinematics gives the joint vectors ``Z^joint`` of the target in the root
horizontal frame ``H_r`` (section 4.1, Fig. 8). Like the hardware's centralised
computer, :func:`connector_commands` turns them into what each strut's low-level
controller takes (section 4.2, Fig. 11b): for every docked connector, the connection
vector in the horizontal frame of *its* node, ``^{H_i} z = Rz(-psi_i) (+/-) z``, with the
node headings ``psi_i`` estimated from the same module reports the recognizer uses
(so slip that shifts the node frames shifts the commands too). The target is first
turned about the vertical onto the recognized configuration (eq. 8): the yaw of a
free-standing robot is not the controllers' business.

The joint modes (Figs. 6-7) differ in what the connectors are told:

* ``opposite_steering`` (default), ``full_opposite``, ``parallel_strut``: connection
  vectors only; each connector reaches its vector by the minimal rotation (the
  opposite connector cancelling the steering), and the strut keeps its roll;
* ``differential_spherical``, ``revolute``: the strut's forward vector ``x`` too (the
  steering, or the rotation about the axis, is part of the motion);
* ``planted``: as ``opposite_steering``, but the connector on a leaf node (the leg's
  foot) is braked (an effort without a direction: it holds where it is on the node),
  so the foot turns with the leg and grips instead of rolling;
* ``swing``: as ``opposite_steering``, with the connector on a leaf node coasting
  (effort 0: motors off), so the foot rolls freely.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping
from dataclasses import replace
from functools import lru_cache

import networkx as nx
import numpy as np

from msrr.core.alignment import align_yaw, rot_z, wrap_angle
from msrr.core.configuration import Configuration
from msrr.core.control import Control
from msrr.core.driver import ModuleCommand, Observation
from msrr.core.errors import ExecutionError
from msrr.core.events import Phase
from msrr.core.plan import Action
from msrr.core.shape import skeletal_errors

from ..robot import NODE, STRUT
from .commands import ENDS, connector_joints
from .geometry import END_SIGN
from .recognizer import FreeSNRecognizer, Links, links_of, node_headings, root_order
from .world import NodeReport, StrutReport

__all__ = ["FOLLOW_EFFORT", "FORWARD_MODES", "LONE_WHEEL_BAND", "LONE_WHEEL_BOUND",
           "LONE_WHEEL_GAIN", "NODE_ROLLING", "PLANTED_MODE", "SWING_MODE", "FreeSNController",
           "bridges",
           "connector_commands", "driving_ends", "feet", "lone_wheel_corrections",
           "lone_wheels", "plant_feet"]

FOLLOW_EFFORT = 0.25
"""Torque fraction of a connector that closes a loop (it follows rather than fights)."""

FORWARD_MODES = frozenset({"differential_spherical", "revolute"})
"""Joint modes whose controllers also command the strut's forward vector."""

PLANTED_MODE = "planted"
"""The leg joint whose foot connector (on a leaf node) is braked."""

SWING_MODE = "swing"
"""The leg joint whose foot connector (on a leaf node) coasts."""

LONE_WHEEL_GAIN = 1.0
"""Gain [1/s] of a lone node wheel's stance loop (:func:`lone_wheel_corrections`): the
rate at which it closes its strut's azimuth error. Fig. 22(j), 4 deg + 10 % slip, seed 19
(docs/freesn.md): 0.5 closed too little (28.4 deg off the heading), 2 failed the run."""

LONE_WHEEL_BOUND = 2.0
"""Bound [rad/s] of a lone node wheel's correction (its wheels run to 6 rad/s)."""

LONE_WHEEL_BAND = float(np.radians(3.0))
"""Dead band [rad] of a lone node wheel's azimuth error: only the error beyond it is
corrected. It is of the order of the recognized azimuth's noise at 4 deg of tilt noise;
without it the correction chases that noise (fig. 22, 4 deg + 10 % slip, seed 23: 16.0 deg
off the heading; with it 12.2 deg worst over seeds 10-29 at that setting, docs/freesn.md
"Stop 53: the lone wheel's dead band")."""

NODE_ROLLING = NODE.geometry["radius"] * STRUT.geometry["wheel_radius"] / (
    0.5 * STRUT.geometry["wheel_base"])
"""How far [m] a node rolls on the floor per radian of its connector's wheels, per unit
horizontal part of the strut axis: the wheels in opposition turn the node about the strut
axis ``u`` at ``r / (b/2)`` rad per rad, and its centre rolls at ``R`` times that along
``u x e_z`` (the node wheels' gains: ``library_sources/design.py``,
``node_wheel_commands``)."""


def feet(links: Links) -> set[tuple[str, str]]:
    """The connectors docked at a leaf node (a node with one connector docked): feet."""
    degree: dict[str, int] = {}
    for node in links.values():
        degree[node] = degree.get(node, 0) + 1
    return {end for end, node in links.items() if degree[node] == 1}


def plant_feet(commands: Mapping[str, ModuleCommand], links: Links, *, coast: bool = False
               ) -> dict[str, ModuleCommand]:
    """``commands`` with the feet's connectors (:func:`feet`) braked at full effort (an
    effort without a direction: they hold where they are on the node when the brake
    begins); with ``coast``, switched off instead (effort 0: the foot rolls freely).
    The leg's other end (its hip) drives at full effort, whichever end
    :func:`driving_ends` chose (the foot, when the root is a foot node).
    """
    at = feet(links)
    out: dict[str, ModuleCommand] = {}
    for strut, command in commands.items():
        ends = {end for end in ENDS if (strut, end) in at}
        if len(ends) == 1:   # the leg's other end (its hip) drives it, at full effort
            command = replace(command, joints={k: v for k, v in command.joints.items()
                                               if k.split(".")[0] in ends
                                               or not k.endswith(".effort")})
        if coast:
            joints = dict(command.joints)
            joints.update({f"{end}.effort": 0.0 for end in ends if f"{end}.dir_x" in joints})
        else:
            joints = {k: v for k, v in command.joints.items() if k.split(".")[0] not in ends}
            joints.update({f"{end}.effort": 1.0 for end in ends})
        out[strut] = replace(command, joints=joints)
    return out


def driving_ends(links: Links, root: str | None = None) -> frozenset[tuple[str, str]]:
    """The connectors that drive at full effort: one spanning tree of locks, and both
    ends of a strut that closes no loop between two hubs.

    A strut docked at both ends is two spherical joints; in a loop of rigid struts, if
    every connector held its own target, measurement noise alone would set them against
    each other. Breadth-first from ``root`` (a running behavior's drive root), then from
    each other group's :func:`~.recognizer.root_order` first (the recognizer's root),
    the strut that first reaches a node is driven from the node it comes from; every other end of a strut
    docked at both ends (the child end, and both ends of a strut that closes a loop)
    follows softly. A strut with one free end is driven from its docked end. This is the
    kinematic tree's choice of which connector is the joint (FreeSN paper, section 3.2).

    A strut on no loop (:func:`bridges`) between two hubs, nodes that each hold at least
    three other struts, drives at both ends: nothing can set its connectors against each
    other (a node's shell turns freely under its connectors), and a soft end would leave
    the strut a hinge of ``FOLLOW_EFFORT`` of the torque, across which every torque
    between the two nodes must pass. The S12N6 quadruped's single bar was such a hinge:
    its front node's hips pitched the front half about it and a connector broke (issue
    32). Elsewhere the soft end stays, as measured (docs/freesn.md): driven at both ends,
    the S4N5 chain's inner struts (nodes with one other strut) made the squirm turn 112
    deg and go backwards, and S6N3's open-triangle strut (nodes with two) let the noisy
    connection 2.3 -> 3.1 press S5 3 mm into N1; a strut to a leaf node keeps it too (a
    foot or a wheel, whose connector its gait or wheel command sets, :func:`plant_feet`).

    A function of the docked topology alone, kept for the last topologies seen: the
    control loop asks every tick and the topology changes only at a dock or undock.
    """
    return _driving_ends(tuple(sorted(links.items())), root)


@lru_cache(maxsize=32)
def _driving_ends(items: tuple[tuple[tuple[str, str], str], ...], root: str | None
                  ) -> frozenset[tuple[str, str]]:
    """:func:`driving_ends` of the links ``items`` (sorted, hashable)."""
    links = dict(items)
    at: dict[str, list[tuple[str, str]]] = {}
    for (strut, end), node in links.items():
        at.setdefault(node, []).append((strut, end))
    ends_of: dict[str, dict[str, str]] = {}
    for (strut, end), node in links.items():
        ends_of.setdefault(strut, {})[end] = node
    driving = {(s, next(iter(e))) for s, e in ends_of.items() if len(e) == 1}
    reached: set[str] = set()
    for start in ([root] if root in at else []) + root_order(set(at), links):
        if start in reached:
            continue
        reached.add(start)
        queue = deque([start])
        while queue:
            node = queue.popleft()
            for strut, end in sorted(at[node]):
                other = ends_of[strut].get("b" if end == "a" else "a")
                if other is not None and other not in reached:
                    reached.add(other)
                    queue.append(other)
                    driving.add((strut, end))
    for strut in bridges(links):
        if all(len(at[node]) > 3 for node in ends_of[strut].values()):
            driving |= {(strut, end) for end in ENDS}
    return frozenset(driving)


def bridges(links: Links) -> set[str]:
    """The struts docked at both ends that lie on no loop of the docked topology (two
    struts between the same two nodes close a loop)."""
    graph = nx.MultiGraph()
    for (strut, end), node in links.items():
        if end == "a" and (strut, "b") in links:
            graph.add_edge(node, links[(strut, "b")], key=strut)
    cut = set(nx.bridges(nx.Graph(graph)))
    return {strut for u, v, strut in graph.edges(keys=True)
            if graph.number_of_edges(u, v) == 1 and ((u, v) in cut or (v, u) in cut)}


def _held(configuration: Configuration, node: str) -> int:
    """How many struts docked at both ends hold ``node`` (a free strut holds nothing)."""
    return sum(not configuration.is_virtual(e.target if e.source == node else e.source)
               for e in configuration.incident(node))


def lone_wheels(configuration: Configuration, wheels: Mapping[str, Mapping[str, float]]
                ) -> dict[tuple[str, str], str]:
    """The wheels of ``wheels`` (per strut, per end ``a``/``b``) that spin a node only
    their own strut holds, the strut's other node held by more: ``(strut, end)`` -> that
    other node (the body node the wheel node swings about). Nothing but the wheel's own
    rolling sets where such a node lies round its body node (a spherical joint holds the
    strut's axis, and the node rolls along the swing)."""
    edges = set(configuration.edge_ids())
    out: dict[tuple[str, str], str] = {}
    for strut, values in wheels.items():
        if strut not in edges:
            continue
        edge = configuration.edge(strut)
        for end in values:
            if end not in ENDS:
                continue
            node, body = (edge.source, edge.target) if end == "a" else (edge.target,
                                                                         edge.source)
            if configuration.is_virtual(node) or configuration.is_virtual(body):
                continue
            if _held(configuration, node) == 1 and _held(configuration, body) > 1:
                out[(strut, end)] = body
    return out


def _reach(configuration: Configuration, strut: str, body: str) -> np.ndarray | None:
    """The horizontal unit direction, shape (2,), from node ``body`` along ``strut``; ``None``
    when the strut has no vector or stands within about 11 deg of the vertical."""
    edge = configuration.edge(strut)
    if edge.z is None or body not in (edge.source, edge.target):
        return None
    out = (edge.z if edge.source == body else -edge.z)[:2]
    size = float(np.linalg.norm(out))
    return out / size if size > 0.2 else None


def lone_wheel_corrections(target: Configuration, current: Configuration,
                           wheels: Mapping[str, Mapping[str, float]], *,
                           gain: float = LONE_WHEEL_GAIN, bound: float = LONE_WHEEL_BOUND,
                           band: float = LONE_WHEEL_BAND,
                           length: float = STRUT.geometry["length"],
                           rolling: float = NODE_ROLLING) -> dict[str, dict[str, float]]:
    """What to add [rad/s] to the behavior wheels of :func:`lone_wheels` so each closes its
    strut's azimuth error about its body node at rate ``gain`` (issue 31, fig. 22(j)).

    Such a node's place round its body node is set by its own rolling; when the wheels'
    commands are no rigid motion of the stance, the difference lands on this strut, the one
    joint that gives, and no connector can drag the node back along the floor. The error
    ``delta`` is the recognized azimuth of the strut from its body node against the
    target's, the target turned onto ``current`` by the eq. 8 yaw over every other strut
    (a rigid turn of the whole is no error). A positive wheel speed turns the node about
    the strut's ``+z`` (end ``a`` to ``b``), rolling it along ``+z x e_z``: a node at end
    ``b`` swings round its body node by ``-rolling / length`` rad per rad of wheel (at
    end ``a``, ``+``), so the correction is ``+/- gain * delta * length / rolling``,
    within ``bound``.

    Args:
        target: the behavior's configuration (its stance). current: recognized now.
        wheels: the behavior's wheel values, per strut, per end (``a``, ``b``).
        gain: [1/s]; 0 corrects nothing. bound: [rad/s]. band: dead band [rad] on
            ``|delta|`` (only the error beyond it is closed). length: strut length [m].
        rolling: [m/rad], :data:`NODE_ROLLING`.

    Returns:
        Per strut, per end, the value to add (only the lone wheels are named).
    """
    lone = lone_wheels(current, wheels)
    if not lone or gain == 0.0:
        return {}
    turned = {strut for strut, _ in lone}
    have = {e.id for e in current.edges() if e.z is not None}
    ids = [e.id for e in target.edges() if e.z is not None and e.id in have
           and e.id not in turned]
    if not ids:
        return {}
    yaw = rot_z(align_yaw(current.vectors(ids), target.vectors(ids)).theta)[:2, :2]
    out: dict[str, dict[str, float]] = {}
    for (strut, end), body in sorted(lone.items()):
        now = _reach(current, strut, body)
        want = _reach(target, strut, body) if strut in set(target.edge_ids()) else None
        if now is None or want is None:
            continue
        want = yaw @ want
        delta = wrap_angle(float(np.arctan2(now[1], now[0]) - np.arctan2(want[1], want[0])))
        delta = float(np.sign(delta)) * max(abs(delta) - band, 0.0)
        sign = 1.0 if end == "b" else -1.0
        value = float(np.clip(sign * gain * delta * length / rolling, -bound, bound))
        out.setdefault(strut, {})[end] = value
    return out


def connector_commands(target: Configuration, reports: Mapping[str, NodeReport | StrutReport],
                       *, yaw: float = 0.0, forward: bool = False,
                       struts: set[str] | None = None,
                       follow_effort: float = FOLLOW_EFFORT,
                       drive_root: str | None = None) -> dict[str, ModuleCommand]:
    """Per-strut commands that drive every docked connector toward ``target``.

    Args:
        target: joint vectors ``z`` (and ``x``) of the struts, root horizontal frame.
        reports: the modules' reports (``observation.sensors``).
        yaw: turn [rad] of ``target`` about the vertical into the recognized frame.
        forward: command the strut's forward vector too (needs ``x`` in ``target``).
        struts: only these struts (default: every strut of ``target``).
        follow_effort: torque fraction of the connectors outside :func:`driving_ends`.
        drive_root: the node :func:`driving_ends` grows from (a behavior's, when it
            names one); default the recognizer's root.

    Raises:
        ExecutionError: ``forward`` and a target strut without ``x``.
    """
    links = links_of(reports)
    heading = node_headings(reports, links)
    driving = driving_ends(links, drive_root)
    turn = rot_z(yaw)
    commands: dict[str, ModuleCommand] = {}
    for edge in target.edges():
        if edge.z is None or (struts is not None and edge.id not in struts) \
                or not isinstance(reports.get(edge.id), StrutReport):
            continue
        if forward and edge.x is None:
            raise ExecutionError(f"strut {edge.id}: the target has no forward vector x")
        joints: dict[str, float] = {}
        for end, sign in END_SIGN.items():
            node = links.get((edge.id, end))
            if node is None:
                continue
            to_node = rot_z(-heading[node]) @ turn
            joints.update(connector_joints(
                end, to_node @ (sign * edge.z),
                to_node @ edge.x if forward and edge.x is not None else None,
                1.0 if (edge.id, end) in driving else follow_effort))
        if joints:
            commands[edge.id] = ModuleCommand(joints=joints)
    return commands


class FreeSNController:
    """The controller of one FreeSN joint mode (registered as ``freesn.<mode>``).

    :meth:`commands` is the low-level translation the executor calls each tick with
    the IK-tracked joint vectors. :meth:`control` (the core
    :class:`~msrr.core.control.Controller` protocol) commands the action's target
    directly, without IK: enough for a move to a nearby configuration.

    Args:
        mode: joint-mode name (``opposite_steering``, ...).
        tolerance: RMS strut angle [rad] under which a phase counts as reached.
        strut_length: for ``Control.errors``, strut angle -> end displacement [m].
        lone_wheel_gain: of :meth:`correct_wheels` [1/s] (0: the behaviors' wheel
            commands as they are).
    """

    def __init__(self, mode: str = "opposite_steering", *, tolerance: float = np.radians(3.0),
                 strut_length: float = 0.2, lone_wheel_gain: float = LONE_WHEEL_GAIN):
        self.mode = mode
        self.name = f"freesn.{mode}"
        self.description = f"FreeSN {mode.replace('_', ' ')} joint controller"
        self.tolerance = tolerance
        self.strut_length = strut_length
        self.forward = mode in FORWARD_MODES
        self.lone_wheel_gain = lone_wheel_gain
        self._recognizer = FreeSNRecognizer()
        self._yaw = 0.0

    def commands(self, target: Configuration, observation: Observation, *,
                 yaw: float | None = None, current: Configuration | None = None,
                 drive_root: str | None = None) -> dict[str, ModuleCommand]:
        """Commands toward ``target`` (joint vectors, root horizontal frame).

        Args:
            yaw: turn [rad] of ``target`` into the recognized frame; when ``None``, the
                eq. 8 alignment with ``current`` (recognized from ``observation`` when
                omitted). Keep it fixed over an action: re-aligning every tick lets a
                blocked strut turn the whole goal.
            drive_root: the node the driving tree grows from (:func:`connector_commands`).
        """
        if yaw is None:
            current = current or self._recognizer.recognize(observation.sensors)
            yaw = skeletal_errors(current, target)[2]
        commands = connector_commands(target, observation.sensors, yaw=yaw,
                                      forward=self.forward, drive_root=drive_root)
        if self.mode in (PLANTED_MODE, SWING_MODE):
            commands = plant_feet(commands, links_of(observation.sensors),
                                  coast=self.mode == SWING_MODE)
        return commands

    def correct_wheels(self, action: Action, configuration: Configuration,
                       wheels: Mapping[str, Mapping[str, float]]
                       ) -> dict[str, dict[str, float]]:
        """``wheels`` with each lone node wheel closing its stance
        (:func:`lone_wheel_corrections` against ``action.target``; the
        :class:`~msrr.core.control.WheelCorrector` protocol)."""
        out = {module: dict(values) for module, values in wheels.items()}
        for strut, added in lone_wheel_corrections(action.target, configuration, wheels,
                                                   gain=self.lone_wheel_gain).items():
            for end, value in added.items():
                out[strut][end] += value
        return out

    def begin(self, action: Action, phase: Phase, observation: Observation) -> None:
        """Fix the yaw of the action's target for this phase (eq. 8 alignment)."""
        current = self._recognizer.recognize(observation.sensors)
        self._yaw = skeletal_errors(current, action.target)[2]

    def control(self, action: Action, phase: Phase, observation: Observation) -> Control:
        """Command ``action.target`` directly; reached under ``tolerance`` RMS."""
        current = self._recognizer.recognize(observation.sensors)
        rms, angles, _ = skeletal_errors(current, action.target)
        ids = [e for e in action.target.edge_ids() if e in set(current.edge_ids())]
        commands = connector_commands(
            action.target, observation.sensors, yaw=self._yaw, forward=self.forward,
            drive_root=action.behavior.drive_root if action.behavior else None)
        errors = {strut: float(a) * self.strut_length for strut, a in zip(ids, angles,
                                                                          strict=True)}
        return Control(commands=commands, errors=errors, reached=rms < self.tolerance)
