"""IK tracking inside the executor's closed loop (FreeSN paper, section 4.1, Figs. 8-10).

For robots whose actions carry a kinematic tree (or whose joint modes give a default
one), every control tick of a moving phase is

    recognize -> IK tracking from the last solution -> joint vectors -> controller -> driver

:class:`PhaseTracker` holds the tracking state of one phase: the phase goal (the target,
``S_conn`` or ``S_extr``), the tree bound to the phase's topology and an
:class:`~msrr.core.kinematics.IKTracker` warm-started from the last tick's solution,
its yaw held (:func:`~msrr.core.kinematics.tracker.held_yaw`: no drift along a free yaw).
Exploration runs when tracking is *stuck* (the residual has not improved for
``stuck_ticks`` ticks): one sampled start every ``stuck_ticks`` ticks, optimised on the latest
configuration, handed over when it beats the tracked solution (section 3.4). It runs
in the control thread, so a run is reproducible from its seed.

The edges of the tree's fixed nodes (no joints: the root's rigid part, loops) are
commanded at the *goal's* shape (turned about the vertical onto the solution's heading
of those edges), not at the recognized vectors: a "hold where you are seen" command
follows recognition noise and the structure's own sag, so the held part random-walks
(under 2 deg of noise S12N6's ring folded 40 deg in 10 s) instead of staying put.

The phase goals (pure functions, :func:`connection_goal` and :func:`extruded`):

* ``S_conn`` -- the target's vectors on the topology the system has now (no new
  connection), Fig. 9;
* ``S_extr`` -- ``S_conn`` with the cycle each new connection closes shortened: the
  chain of edges between the two nodes being merged is bent so that their distance is
  ``1 - shrink`` strut lengths, so the connector presses ``shrink`` lengths into the
  node ("reducing the length of the edges connecting the merged nodes in the upcoming
  cycle to guarantee a robust connection").

Reaching (section 4.1, "the controllers are terminated if the current system
configuration is close to the target by monitoring the estimated motion costs"): a
phase is reached when the distance cost of eq. 8 -- the RMS angle between the
recognized vectors (low-passed over the ticks) and the goal vectors after yaw
alignment, :func:`~msrr.core.shape.skeletal_error` -- is under ``reach_tolerance``; or
on the measure the controllers of the tree's nodes give, when they aim each connection
relative to its parent (:func:`reach_measure`: FreeBOT's bends, whose
recognized absolute shape carries the headings' chained errors, which no command takes
out). The IK's own motion cost (eqs. 3-5) is not used for this: its
steering terms stay near 0.1 rad per joint under 2 deg of recognition noise even when
the shape is within 1 deg, so no fixed threshold on it separates reached from not.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import networkx as nx
import numpy as np

from .actions import STRUT_ENDS, topology_diff
from .alignment import align_yaw, rot_z
from .configuration import Configuration
from .driver import ModuleCommand, Observation
from .errors import PlanningError
from .kinematics import (
    FixedNode,
    GroundModel,
    IKOptions,
    IKSolution,
    IKTracker,
    KinematicTree,
    default_tree,
)
from .plan import ConnectionChange
from .shape import skeletal_error

__all__ = ["EQ8", "DockCycle", "JointController", "Measure", "PhaseTracker", "ReachMeasure",
           "SkeletalMeasure", "TrackingOptions", "aimed", "connection_goal", "extruded",
           "reach_measure", "tree_for", "turned_goal"]


@runtime_checkable
class JointController(Protocol):
    """A controller that turns joint vectors (the IK result) into module commands.

    ``commands(joint, observation, yaw=..., drive_root=...)``: ``joint`` holds the joint
    vectors ``z`` (and ``x``) of every edge in the root horizontal frame of the
    recognized configuration; ``yaw`` [rad] turns them into that frame (0: already in
    it); ``drive_root`` is the node a running behavior is driven from
    (:attr:`~msrr.core.plan.BehaviorCall.drive_root`), for a controller that drives
    from one node (FreeSN's driving tree), ``None`` for its own choice; a controller
    that drives every joint alike ignores it.
    """

    name: str

    def commands(self, target: Configuration, observation: Observation, *,
                 yaw: float | None = None, drive_root: str | None = None
                 ) -> Mapping[str, ModuleCommand]: ...


@dataclass(frozen=True)
class TrackingOptions:
    """How IK tracking runs in the executor.

    Attributes:
        reach_tolerance: a phase is reached when the recognized configuration is this
            close to its goal (RMS angle after yaw alignment) [rad].
        shrink: ``S_extr`` brings the merged nodes this fraction of a strut length closer.
        press_time: a connect phase presses toward ``S_extr`` this long [s] before it
            backs off and re-aims (:class:`DockCycle`).
        back_time: how long it then holds the connector off the node [s].
        stand_off: ... this fraction of a strut length farther than ``S_conn``.
        max_iterations: L-BFGS-B iterations of one tracking step (bounds the tick's time
            without a wall-clock budget, so runs are reproducible).
        ftol: L-BFGS-B relative objective tolerance of a tracking step. A tracking step
            starts at last tick's optimum, so at 1e-12 most of its iterations polish
            below the recognition noise with failing line searches (~3 evaluations per
            iteration); 1e-7 (an eq. 6 change of 1e-7 rad^2, 0.02 deg RMS) cuts the
            evaluations per tick by 3x with the same library checks.
        initial_restarts: sampled starts of a phase's first solve.
        stuck_ticks: while the residual has not improved for this many ticks, one
            exploration run every this many ticks.
        smoothing: weight of the newest tick in the low-passed vectors of the reaching
            test (1: no smoothing).
        ground: solve with the three-point ground model (a floating base settles on its
            lowest contacts, so the root's tilt is predicted rather than held).
    """

    reach_tolerance: float = float(np.radians(3.0))
    shrink: float = 0.1
    press_time: float = 4.0
    back_time: float = 2.0
    stand_off: float = 0.05
    max_iterations: int = 30
    ftol: float = 1e-7
    initial_restarts: int = 8
    stuck_ticks: int = 5
    ground: bool = True
    smoothing: float = 0.5


def connection_goal(topology: Configuration, target: Configuration) -> Configuration:
    """``S_conn``: ``target``'s vectors on ``topology`` (edges matched by id, Fig. 9)."""
    ids = set(topology.edge_ids())
    z = {e.id: e.z for e in target.edges() if e.id in ids and e.z is not None}
    x = {e.id: e.x for e in target.edges() if e.id in ids and e.x is not None}
    return topology.with_vectors(z=z, x=x or None)


def turned_goal(goal: Configuration, tree: KinematicTree, turn: float,
                ground: GroundModel | None = None) -> Configuration:
    """``goal`` with the body turned by ``turn`` [rad] about the vertical relative to its
    planted feet (a sequence gait's heading loop, issue 31:
    :class:`~msrr.core.executor.GaitLoop`).

    The yaw of a tracking step is held where the root's edges are (eq. 7: they cannot
    move; :func:`~msrr.core.kinematics.tracker.held_yaw`), so a turn of the whole goal
    changes nothing; the planted legs turned against the rest pivot the body on the feet
    that grip the ground. With one planted node
    (:attr:`~msrr.core.kinematics.KinematicNode.planted`) its vectors, and those of the
    nodes hanging from it, are turned by ``-turn``: the body pivots on that foot. With
    two or more (the S12N6 trot's diagonal pair) the body turns rigidly about the
    middle of their feet (:func:`_turned_on_feet`). Bending the part the step moves
    instead (the squirm's free half about its middle node) steers little and slips: in
    the squirm the held half, whose raised middle node has no grip, turned back against
    it. A tree whose root holds no edge leaves the yaw to the others and one without a
    planted node has nothing to turn about: ``goal`` is returned as it is.

    Args:
        ground: the edges' lengths for the feet's places (:class:`GroundModel`; unit
            lengths when ``None``); read with two or more planted nodes only.
    """
    planted = [i for i, node in enumerate(tree.nodes) if node.planted]
    if not turn or not tree.root.edges or not planted:
        return goal
    feet: set[int] = set()
    for i, node in enumerate(tree.nodes[1:], start=1):
        if node.planted or tree.parents[i] in feet:
            feet.add(i)
    if len(planted) > 1:
        return _turned_on_feet(goal, tree, feet, turn, ground or GroundModel())
    turned = {e for i in feet for e in tree.nodes[i].edges}
    if not turned:
        return goal
    back = rot_z(-turn)
    z = {e.id: back @ e.z if e.id in turned else e.z for e in goal.edges() if e.z is not None}
    x = {e.id: back @ e.x if e.id in turned else e.x for e in goal.edges() if e.x is not None}
    return goal.with_vectors(z=z, x=x or None)


def _places(goal: Configuration, start: str, ground: GroundModel) -> dict[str, np.ndarray]:
    """Every vertex's place [m] (3,) from ``start`` along ``goal``'s edges (their ``z``
    times their length, breadth first; a loop's closing edge is not read)."""
    places = {start: np.zeros(3)}
    queue = [start]
    graph = goal.graph
    while queue:
        here = queue.pop(0)
        for u, w, key in list(graph.out_edges(here, keys=True)) + \
                list(graph.in_edges(here, keys=True)):
            other = w if u == here else u
            if other in places:
                continue
            step = goal.edge(key).z * ground.lengths.get(key, ground.default_length)
            places[other] = places[here] + (step if u == here else -step)
            queue.append(other)
    return places


def _turned_on_feet(goal: Configuration, tree: KinematicTree, feet: set[int], turn: float,
                    ground: GroundModel) -> Configuration:
    """``goal`` with the body turned by ``turn`` [rad] about the vertical through the middle
    of its planted feet, the feet kept where they stand: each planted leg (a planted node
    of one edge hanging from the body) aimed from its hip at its foot's place turned by
    ``-turn`` about that middle in the body's frame, its length kept by its height (a
    foot moves by about ``turn`` times its distance from the middle, its height by that
    times its leg's lean: the S12N6 trot's feet 10 mm and 2-3 mm at 5 deg), its forward
    vector turned by ``-turn`` and kept square to it; what hangs from a foot turned by
    ``-turn``. Turning each leg about its own hip instead puts the feet off a rigid turn
    of the body by ``turn`` times the hip's distance from the middle (the S12N6 trot
    stalled with it, body 102 deg off). ``goal`` as it is when a planted node is not a
    single edge to its foot, or a vector is missing."""
    legs = [i for i in sorted(feet) if tree.nodes[i].planted and tree.parents[i] not in feet]
    ends: list[tuple[str, str, str]] = []   # (edge, hip, foot)
    for i in legs:
        node = tree.nodes[i]
        if len(node.edges) != 1:
            return goal
        edge = goal.edge(node.edges[0])
        if edge.z is None or (edge.target in node.vertices) == (edge.source in node.vertices):
            return goal
        foot = edge.target if edge.target in node.vertices else edge.source
        ends.append((edge.id, edge.source if foot == edge.target else edge.target, foot))
    if any(e.z is None for e in goal.edges()):
        return goal
    places = _places(goal, ends[0][1], ground)
    middle = np.mean([places[foot] for _, _, foot in ends], axis=0)
    back = rot_z(-turn)
    z = {e.id: e.z for e in goal.edges()}
    x = {e.id: e.x for e in goal.edges() if e.x is not None}
    for i in feet:
        for e in tree.nodes[i].edges:
            z[e] = back @ z[e]
            if e in x:
                x[e] = back @ x[e]
    for edge, hip, foot in ends:
        length = ground.lengths.get(edge, ground.default_length)
        moved = middle + back @ (places[foot] - middle)
        flat = (moved - places[hip])[:2]
        reach = min(float(np.linalg.norm(flat)), length)
        flat = flat * (reach / max(float(np.linalg.norm(flat)), 1e-12))
        down = places[foot][2] - places[hip][2]
        leg = np.array([*flat, math.copysign(math.sqrt(length**2 - reach**2), down)]) / length
        z[edge] = leg if goal.edge(edge).target == foot else -leg
        if edge in x:   # square to the new z again
            square = x[edge] - (x[edge] @ z[edge]) * z[edge]
            x[edge] = square / np.linalg.norm(square)
    return goal.with_vectors(z=z, x=x or None)


def _without(config: Configuration, strut: str, end: str) -> tuple[nx.MultiGraph, str]:
    """The graph of ``config`` without ``strut``, and the strut's other end's node."""
    edge = config.edge(strut)
    base = edge.target if end == STRUT_ENDS[0] else edge.source
    graph = nx.MultiGraph()
    for e in config.edges():
        if e.id != strut:
            graph.add_edge(e.source, e.target, key=e.id)
    return graph, base


def _signed(config: Configuration, graph: nx.MultiGraph, path: list[str]
            ) -> list[tuple[str, float]]:
    """The edges along ``path`` (the first of parallel ones) with the sign of their ``z``."""
    out = []
    for u, w in zip(path, path[1:], strict=False):
        key = min(graph[u][w])
        out.append((key, 1.0 if config.edge(key).source == u else -1.0))
    return out


def _chain(config: Configuration, strut: str, end: str, node: str
           ) -> list[tuple[str, float]] | None:
    """Edges (with the sign of their ``z`` along the way) from the strut's other end to
    ``node``, avoiding the strut; ``None`` when there is no such path."""
    graph, base = _without(config, strut, end)
    if base not in graph or node not in graph:
        return None
    try:
        path = nx.shortest_path(graph, base, node)
    except nx.NetworkXNoPath:
        return None
    return _signed(config, graph, path)


def _chains(config: Configuration, strut: str, end: str, node: str
            ) -> list[list[tuple[str, float]]]:
    """Every shortest chain of :func:`_chain`."""
    graph, base = _without(config, strut, end)
    if base not in graph or node not in graph or not nx.has_path(graph, base, node):
        return []
    return [_signed(config, graph, path) for path in nx.all_shortest_paths(graph, base, node)]


def _bent(vectors: np.ndarray, axis: np.ndarray, lam: float, *, total: bool = True
          ) -> np.ndarray:
    """Chain vectors ``normalise(z_i - lam axis)`` (n, 3), or their sum (3,) if ``total``."""
    moved = vectors - lam * axis
    moved /= np.linalg.norm(moved, axis=1, keepdims=True)
    return moved.sum(axis=0) if total else moved


def extruded(conn: Configuration, made: tuple[ConnectionChange, ...], shrink: float
             ) -> Configuration:
    """``S_extr``: ``conn`` with each new connection's cycle shortened (section 4.1).

    For a strut end that docks at ``node``, the chain of edges from the strut's other
    end to ``node`` sums (unit lengths) to ``D``. Each chain vector becomes
    ``normalise(z_i - lambda D/|D|)`` with ``lambda`` found by bisection so the chain's
    reach along ``D`` is ``|D| - shrink``: the merged nodes come ``shrink`` strut lengths
    closer and the connector is pushed into the node. A negative ``shrink`` lengthens the
    chain instead (the connector held off the node: :class:`DockCycle`'s back-off). A
    chain of one edge cannot shorten and is left as it is. Changes that are not strut
    ends are ignored.
    """
    z = {e.id: np.array(e.z) for e in conn.edges() if e.z is not None}
    for change in made:
        if change.source_port not in STRUT_ENDS or change.source not in z:
            continue
        chain = _chain(conn, change.source, change.source_port, change.target)
        if not chain or len(chain) < 2:
            continue
        vectors = np.array([s * z[e] for e, s in chain])
        reach = vectors.sum(axis=0)
        length = float(np.linalg.norm(reach))
        if length < 1e-9:
            continue
        axis = reach / length
        goal = length - shrink

        # below 1: a chain vector along D must not vanish; a negative shrink lengthens
        lo, hi = (0.0, 0.95) if shrink >= 0 else (-0.95, 0.0)
        if _bent(vectors, axis, hi) @ axis > goal \
                or (shrink < 0 and _bent(vectors, axis, lo) @ axis < goal):
            continue
        for _ in range(50):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if _bent(vectors, axis, mid) @ axis > goal else (lo, mid)
        moved = _bent(vectors, axis, hi if shrink >= 0 else lo, total=False)
        for (e, s), v in zip(chain, moved, strict=True):
            z[e] = s * v
    return conn.with_vectors(z=z)


def aimed(goal: Configuration, seen: Configuration, made: tuple[ConnectionChange, ...]
          ) -> Configuration:
    """``goal`` with each strut that docks aimed at its node's place in ``seen``.

    The node's place is the sum of ``seen``'s chain from the strut's other end to the
    node (unit struts, as :func:`extruded`), averaged over every shortest chain (in a
    closed structure they differ by the recognition's errors only), turned into ``goal``'s frame by the yaw that
    aligns ``seen`` with ``goal`` over the other edges (eq. 8). A structure that sits a few
    degrees off the library shape moves the node off the goal's strut direction, and at a
    strut length that is millimetres: enough to land the magnet askew on the shell.
    """
    docking = {c.source for c in made if c.source_port in STRUT_ENDS}
    rest = [e.id for e in goal.edges()
            if e.id not in docking and e.z is not None and seen.edge(e.id).z is not None]
    if not docking or not rest:
        return goal
    back = rot_z(-align_yaw(seen.vectors(rest), goal.vectors(rest)).theta)
    z = {e.id: np.array(e.z) for e in goal.edges() if e.z is not None}
    for change in made:
        if change.source_port not in STRUT_ENDS or change.source not in z:
            continue
        chains = _chains(seen, change.source, change.source_port, change.target)
        if not chains:
            continue
        reach = np.mean([sum(s * np.asarray(seen.edge(e).z) for e, s in chain)
                         for chain in chains], axis=0)
        length = float(np.linalg.norm(reach))
        if length > 1e-9:   # z runs from the strut's a end to its b end
            sign = 1.0 if change.source_port == STRUT_ENDS[1] else -1.0
            z[change.source] = sign * back @ (reach / length)
    return goal.with_vectors(z=z)


class DockCycle:
    """The goals of a connect phase over time: press, and back off to re-aim when no dock
    came (section 4.1's ``S_extr``, with a retry loop the paper leaves to the hardware).

    The phase presses toward ``S_extr`` (``extruded(conn, made, shrink)``) for
    ``press_time``. A magnet that landed askew does not dock, and pressing an end onto a
    sphere off its centre only slides it farther off (fig22's R6 under noise: 12 deg askew
    at 16 N, then 35 deg). Then it backs off for ``back_time``: the chain lengthened by
    ``stand_off`` (the end clear of the shell) and the strut aimed at the node's measured
    place (:func:`aimed`, on the recognized configuration), and presses again, aimed the
    same way; and so on until the phase ends. The magnets stay armed throughout: a dock
    may come on the way in or out. A phase that docks within ``press_time`` never sees
    anything but ``S_extr``, and one that docks no strut end (nothing to extrude or
    aim: FreeBOT's and SnailBot's contacts) only ``S_conn``.

    Args:
        conn: ``S_conn`` of the phase.
        made: the connections the phase makes.
        options: ``shrink``, ``press_time``, ``back_time``, ``stand_off``.
        start: driver time the phase began [s].
    """

    def __init__(self, conn: Configuration, made: tuple[ConnectionChange, ...],
                 options: TrackingOptions, start: float):
        self.conn, self.made, self.options = conn, made, options
        self.struts = any(c.source_port in STRUT_ENDS for c in made)
        self.pressing = True
        self.since = start
        self.backoffs = 0

    @property
    def goal(self) -> Configuration:
        """The phase's first goal, ``S_extr``."""
        return extruded(self.conn, self.made, self.options.shrink)

    def update(self, now: float, seen: Configuration) -> Configuration | None:
        """The new goal when the cycle turns at ``now`` [s], else ``None``; ``seen`` is
        the recognized configuration (the aim)."""
        o = self.options
        if not self.struts or \
                now - self.since < (o.press_time if self.pressing else o.back_time) - 1e-9:
            return None
        self.pressing = not self.pressing
        self.since = now
        self.backoffs += not self.pressing
        shrink = o.shrink if self.pressing else -o.stand_off
        return aimed(extruded(self.conn, self.made, shrink), seen, self.made)


Measure = Callable[[Configuration, Configuration], float]
"""A distance [rad] of a recognized configuration (first) from a goal (second)."""


@runtime_checkable
class ReachMeasure(Protocol):
    """A named :data:`Measure` that a controller reaches its phases on
    (``controller.reach_measure``); two measures are the same when they compare equal, so
    a robot's controllers that aim alike give equal ones (not a bound method each)."""

    name: str

    def __call__(self, current: Configuration, goal: Configuration) -> float: ...


@dataclass(frozen=True)
class SkeletalMeasure:
    """Eq. 8's distance: the RMS angle after one yaw alignment
    (:func:`~msrr.core.shape.skeletal_error`)."""

    name: str = "eq8"

    def __call__(self, current: Configuration, goal: Configuration) -> float:
        return skeletal_error(current, goal)


EQ8 = SkeletalMeasure()
"""Eq. 8's distance, what a controller that names no measure is reached on."""


def reach_measure(tree: KinematicTree, controller_for: Callable[[str], object]
                  ) -> ReachMeasure:
    """The distance a tracked phase on ``tree`` is reached on: the ``reach_measure`` the
    controllers of its nodes that move connections give (``controller_for``: a node's
    ``controller`` name -> the controller; a controller that names none gives eq. 8's,
    :data:`EQ8`; a node without edges commands nothing and has no say). FreeBOT's
    controllers aim each connection relative to its parent and are reached on those
    bends.

    Raises:
        PlanningError: the nodes' controllers give different measures (each node named
            with its edges and its measure): no one distance says the phase is reached.
    """
    found: dict[ReachMeasure, list[str]] = {}
    for node in tree.nodes:
        if not node.edges:
            continue
        measure = getattr(controller_for(node.controller), "reach_measure", EQ8)
        found.setdefault(measure, []).append(f"{node.name} {'+'.join(node.edges)}")
    if len(found) > 1:
        said = "; ".join(f"{getattr(m, 'name', m)!s}: {', '.join(nodes[:3])}"
                         + (f" and {len(nodes) - 3} more" if len(nodes) > 3 else "")
                         for m, nodes in found.items())
        raise PlanningError(f"the kinematic tree's controllers are reached on different "
                            f"measures ({said}): a tracked phase needs one")
    return next(iter(found), EQ8)


def tree_for(topology: Configuration, given: object, joint_mode: type | None
             ) -> KinematicTree | None:
    """The kinematic tree for a phase on ``topology``: ``given`` when it is a tree over the
    same edges and links (free-end names may differ: the IK reads vectors by edge id),
    else the default tree of ``joint_mode``; ``None`` when neither applies (no joint
    mode, or ``topology`` is not one connected system)."""
    if isinstance(given, KinematicTree) and set(given.edges) == set(topology.edge_ids()) \
            and not topology_diff(given.configuration, topology):
        return given
    if joint_mode is None or not topology.is_connected():
        return None
    return default_tree(topology, joint_mode)


class PhaseTracker:
    """IK tracking toward one phase goal (section 3.4 tracking, section 4.1 control).

    Args:
        tree: kinematic tree over the phase's topology.
        goal: the phase goal (same edge ids).
        options: tracking options.
        seed: seed of the first solve and of exploration.
        ground: the ground model of the robot (``GroundModel.for_configuration``); used
            when ``options.ground``.
        median_yaw: hold the yaw at the edges' median turn
            (:attr:`~msrr.core.robot.RobotDefaults.median_yaw`).
        measure: the distance [rad] of a (low-passed) recognized configuration from the
            goal that the phase is reached and watched on: that of the controllers the
            tree's nodes use where they give one (:func:`reach_measure`), else eq. 8's
            RMS angle after one yaw alignment (:func:`~msrr.core.shape.skeletal_error`).
    """

    def __init__(self, tree: KinematicTree, goal: Configuration, options: TrackingOptions,
                 seed: int = 0, ground: GroundModel | None = None, median_yaw: bool = False,
                 measure: Measure = EQ8):
        self.tree = tree
        self.goal = goal
        self.options = options
        self.measure = measure
        ik = IKOptions(max_iterations=options.max_iterations, ftol=options.ftol,
                       max_restarts=options.initial_restarts, seed=seed,
                       ground=ground if options.ground else None)
        self._tracker = IKTracker(tree, goal, ik, tick_budget=None, explore=False,
                                  median_yaw=median_yaw)
        self._held = [e for node in tree.nodes if isinstance(node, FixedNode)
                      for e in node.edges]
        self._best = np.inf
        self._since = 0
        self._error = np.inf
        self._z: dict[str, np.ndarray] = {}
        self.seen: Configuration | None = None
        self.last: IKSolution | None = None
        self.explorations = 0

    def step(self, current: Configuration) -> Configuration:
        """Track one tick; the joint configuration (``current`` moved by the solution,
        the recognized root horizontal frame)."""
        solution = self._tracker.step(current)
        self.last = solution
        joint = solution.configuration
        if self._held:
            joint = self._hold(joint)
        self._error = self.measure(self._smoothed(current), self.goal)
        if solution.rms_angle < self._best - 1e-4:
            self._best, self._since = solution.rms_angle, 0
        else:
            self._since += 1
        if self._since >= self.options.stuck_ticks and solution.rms_angle > \
                self.options.reach_tolerance and self._since % self.options.stuck_ticks == 0:
            self._tracker.explore_once()   # one sampled start every stuck_ticks ticks
            self.explorations += 1
        return joint

    def _hold(self, joint: Configuration) -> Configuration:
        """``joint`` with the fixed nodes' edges at the goal's shape, turned about the
        vertical onto where the solution has them (eq. 8 over those edges alone).

        The solution carries them where they are recognized (a fixed node has no joint),
        and commanding "stay where you are seen" lets recognition noise and the
        structure's own sag random-walk the held part (S12N6 4.3 -> 4.1 folded 40 deg
        under 2 deg of noise). Their heading stays the solution's: taking the IK's yaw
        instead would turn the held part after a drifting yaw (a one-strut root spins).
        """
        held = [e for e in self._held if self.goal.edge(e).z is not None]
        if not held:
            return joint
        goal = np.array([self.goal.edge(e).z for e in held]).T
        turn = rot_z(align_yaw(joint.vectors(held), goal).theta)
        z = {e.id: e.z for e in joint.edges()}
        z.update({e: turn @ goal[:, i] for i, e in enumerate(held)})
        return joint.with_vectors(z=z)

    def _smoothed(self, current: Configuration) -> Configuration:
        """``current`` with each edge's ``z`` low-passed over the ticks (factor
        ``smoothing``): white recognition noise averages out of the reaching test, which
        otherwise never passes at 18 modules under 2 deg of noise. Kept as :attr:`seen`."""
        a = self.options.smoothing
        z = {}
        for e in current.edges():
            if e.z is None:
                continue
            old = self._z.get(e.id)
            v = e.z if old is None else (1 - a) * old + a * e.z
            flat = v.ravel(order="K")   # np.linalg.norm's own arithmetic, its layers aside
            z[e.id] = v / math.sqrt(flat.dot(flat))
        self._z = z
        self.seen = current.with_vectors(z=z)
        return self.seen

    @property
    def error(self) -> float:
        """The low-passed recognized configuration's distance from the goal [rad]
        (``measure``: by default the RMS angle after yaw alignment), as of the last
        :meth:`step` (``inf`` before it)."""
        return float(self._error)

    @property
    def reached(self) -> bool:
        """The recognized configuration is within ``reach_tolerance`` of the goal by
        ``measure`` (checked on the configuration of the last :meth:`step`)."""
        return self._error < self.options.reach_tolerance

    def set_goal(self, goal: Configuration) -> None:
        """Switch the goal (``S_conn`` -> ``S_extr``); the warm start is kept."""
        self.goal = goal
        self._tracker.set_target(goal)
        self._best, self._since = np.inf, 0
