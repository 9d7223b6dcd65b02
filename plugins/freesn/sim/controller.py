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

from msrr.core.alignment import rot_z
from msrr.core.configuration import Configuration
from msrr.core.control import Control
from msrr.core.driver import ModuleCommand, Observation
from msrr.core.errors import ExecutionError
from msrr.core.events import Phase
from msrr.core.plan import Action
from msrr.core.shape import skeletal_errors

from .commands import ENDS, connector_joints
from .geometry import END_SIGN
from .recognizer import FreeSNRecognizer, Links, links_of, node_headings, root_order
from .world import NodeReport, StrutReport

__all__ = ["FOLLOW_EFFORT", "FORWARD_MODES", "PLANTED_MODE", "SWING_MODE",
           "FreeSNController", "bridges", "connector_commands", "driving_ends", "feet",
           "plant_feet"]

FOLLOW_EFFORT = 0.25
"""Torque fraction of a connector that closes a loop (it follows rather than fights)."""

FORWARD_MODES = frozenset({"differential_spherical", "revolute"})
"""Joint modes whose controllers also command the strut's forward vector."""

PLANTED_MODE = "planted"
"""The leg joint whose foot connector (on a leaf node) is braked."""

SWING_MODE = "swing"
"""The leg joint whose foot connector (on a leaf node) coasts."""


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
    each other. Breadth-first from the root node (each group's
    :func:`~.recognizer.root_order` first, as the recognizer's), the strut that first
    reaches a node is driven from the node it comes from; every other end of a strut
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
    for start in ([root] if root else []) + root_order(set(at), links):
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


def connector_commands(target: Configuration, reports: Mapping[str, NodeReport | StrutReport],
                       *, yaw: float = 0.0, forward: bool = False,
                       struts: set[str] | None = None,
                       follow_effort: float = FOLLOW_EFFORT) -> dict[str, ModuleCommand]:
    """Per-strut commands that drive every docked connector toward ``target``.

    Args:
        target: joint vectors ``z`` (and ``x``) of the struts, root horizontal frame.
        reports: the modules' reports (``observation.sensors``).
        yaw: turn [rad] of ``target`` about the vertical into the recognized frame.
        forward: command the strut's forward vector too (needs ``x`` in ``target``).
        struts: only these struts (default: every strut of ``target``).
        follow_effort: torque fraction of the connectors outside :func:`driving_ends`.

    Raises:
        ExecutionError: ``forward`` and a target strut without ``x``.
    """
    links = links_of(reports)
    heading = node_headings(reports, links)
    driving = driving_ends(links)
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
    """

    def __init__(self, mode: str = "opposite_steering", *, tolerance: float = np.radians(3.0),
                 strut_length: float = 0.2):
        self.mode = mode
        self.name = f"freesn.{mode}"
        self.description = f"FreeSN {mode.replace('_', ' ')} joint controller"
        self.tolerance = tolerance
        self.strut_length = strut_length
        self.forward = mode in FORWARD_MODES
        self._recognizer = FreeSNRecognizer()
        self._yaw = 0.0

    def commands(self, target: Configuration, observation: Observation, *,
                 yaw: float | None = None, current: Configuration | None = None
                 ) -> dict[str, ModuleCommand]:
        """Commands toward ``target`` (joint vectors, root horizontal frame).

        Args:
            yaw: turn [rad] of ``target`` into the recognized frame; when ``None``, the
                eq. 8 alignment with ``current`` (recognized from ``observation`` when
                omitted). Keep it fixed over an action: re-aligning every tick lets a
                blocked strut turn the whole goal.
        """
        if yaw is None:
            current = current or self._recognizer.recognize(observation.sensors)
            yaw = skeletal_errors(current, target)[2]
        commands = connector_commands(target, observation.sensors, yaw=yaw,
                                      forward=self.forward)
        if self.mode in (PLANTED_MODE, SWING_MODE):
            commands = plant_feet(commands, links_of(observation.sensors),
                                  coast=self.mode == SWING_MODE)
        return commands

    def begin(self, action: Action, phase: Phase, observation: Observation) -> None:
        """Fix the yaw of the action's target for this phase (eq. 8 alignment)."""
        current = self._recognizer.recognize(observation.sensors)
        self._yaw = skeletal_errors(current, action.target)[2]

    def control(self, action: Action, phase: Phase, observation: Observation) -> Control:
        """Command ``action.target`` directly; reached under ``tolerance`` RMS."""
        current = self._recognizer.recognize(observation.sensors)
        rms, angles, _ = skeletal_errors(current, action.target)
        ids = [e for e in action.target.edge_ids() if e in set(current.edge_ids())]
        commands = connector_commands(action.target, observation.sensors, yaw=self._yaw,
                                      forward=self.forward)
        errors = {strut: float(a) * self.strut_length for strut, a in zip(ids, angles,
                                                                          strict=True)}
        return Control(commands=commands, errors=errors, reached=rms < self.tolerance)
