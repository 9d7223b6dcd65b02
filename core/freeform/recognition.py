"""Recognition and control of single-connector freeform modules from their reports.

**Recognition** (FreeSN paper, section 2.1: modules sense their connections and
orientations; the configuration is identified from those readings). Each module
reports the module its connector holds, its IMU tilt ``T_i`` (connector frame in its
own horizontal frame ``H_i``) and, when docked on ``j``, the odometry ``Q_i`` of its
connector frame in ``j``'s connector frame (drive and bearing encoders). With the
connector frames ``R_i = Rz(psi_i) T_i`` in the world,

    T_j Q_i T_i^T = Rz(-psi_j) R_j R_j^T R_i R_i^T Rz(psi_i) = Rz(psi_i - psi_j),

so each connection gives the yaw between the two horizontal frames; headings follow
breadth-first from each group's root (its free module, the MISO sink; else its
smallest id) and the connection vector is the connector axis
``z_{i->j} = Rz(psi_i) T_i e_z`` in the root's horizontal frame.

**Control**: a connection vector in the root frame becomes, for the module that owns
the connector, the same vector in its parent's horizontal frame,
``Rz(-psi_j) Rz(yaw) z`` (the command ``dir_x/y/z``), after the common turn about the
vertical between the goal and the recognized configuration is taken out (eq. 8). A
**flow** (section 4.1; the executor's ``flow`` then ``handover`` phases) of module ``i``
from ``P`` to a neighbour ``Q`` of ``P`` first rolls ``i`` over ``P`` to the place where it
touches both -- the direction ``w`` from ``P``'s centre at 60 degrees from the direction
to ``Q`` (equal spheres: an equilateral triangle), nearest to where ``i`` is -- and then
tells its connector to dock on ``Q`` and leave ``P``, which the world does in one step.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Collection, Mapping, Sequence

import numpy as np

from ..actions import flow_of, topology_diff
from ..alignment import median_yaw, rot_z, wrap_angle
from ..closed_loop import EQ8, ReachMeasure
from ..configuration import Configuration
from ..control import Control
from ..driver import ModuleCommand, Observation
from ..errors import ConfigurationError, ExecutionError
from ..events import Phase
from ..kinematics.rotations import canonical_perpendicular
from ..plan import Action, ActionType
from ..shape import skeletal_errors
from .mujoco import yaws_of
from .piece_way import PieceWay, normalized, plan_piece_way
from .travel import Locator, floor_path, link_vectors, pursue, twist_velocities
from .world import ModuleReport

__all__ = ["BendMeasure", "ContactController", "ContactRecognizer", "Latches", "anchors",
           "bend_error", "bend_errors", "common_turn", "flow_direction", "goal_side",
           "link_headings", "links_of", "module_headings", "piece_turn", "spread_headings"]

Reports = Mapping[str, ModuleReport]
FLOW_ANGLE = np.pi / 3
"""Angle between the directions to the old and the new parent where a flowing sphere
touches both (equal radii)."""


SIDE_TIE = np.radians(5.0)
"""A flowing module within this angle of straight opposite its new parent, with no goal
side, takes the level side on the right (seen from the old parent towards the new one),
not a side that measurement noise picks."""
SIDE_GOAL = 0.1
"""Smallest :func:`goal_side` (unit spacing) that decides a flow's side."""
_EZ = np.array([0.0, 0.0, 1.0])


def links_of(reports: Reports) -> dict[str, str]:
    """``module -> the module its connector holds``, for modules both reporting."""
    return {m: r.attached for m, r in reports.items()
            if r.attached is not None and r.attached in reports and r.relative is not None}


def module_headings(reports: Reports, links: Mapping[str, str] | None = None
                    ) -> dict[str, float]:
    """Heading [rad] of every module's horizontal frame in its group's root frame."""
    links = links_of(reports) if links is None else links
    neighbours: dict[str, list[tuple[str, float]]] = {m: [] for m in reports}
    if links:          # psi_i - psi_j of every link i -> j, all at once
        tilts = np.array([reports[i].tilt for i in links])
        relative = np.array([reports[i].relative for i in links])
        held = np.array([reports[j].tilt for j in links.values()])
        deltas = yaws_of(held @ relative @ tilts.transpose(0, 2, 1)).tolist()
        for (i, j), delta in zip(links.items(), deltas, strict=True):
            neighbours[j].append((i, delta))
            neighbours[i].append((j, -delta))
    sinks = sorted(m for m in reports if m not in links)
    heading, _roots = spread_headings(neighbours, [*sinks, *sorted(reports)])
    return heading


class _HeadingsMemo:
    """:func:`link_headings`' one entry: the reports it was found for (their keys and
    report objects, by identity) and the links and headings, replaced as one pair (a
    reader never pairs one tick's reports with another's headings)."""

    def __init__(self) -> None:
        self.entry: tuple[list[tuple[str, ModuleReport]],
                          tuple[dict[str, str], dict[str, float]]] = ([], ({}, {}))

    def get(self, reports: Reports) -> tuple[dict[str, str], dict[str, float]] | None:
        items, found = self.entry
        if len(items) != len(reports) or any(
                report is not r for (_, report), r in zip(items, reports.values(), strict=True)) \
                or any(m != k for (m, _), k in zip(items, reports, strict=True)):
            return None
        return found


_HEADINGS = _HeadingsMemo()


def link_headings(reports: Reports) -> tuple[dict[str, str], dict[str, float]]:
    """:func:`links_of` and :func:`module_headings` of ``reports``, found once per tick:
    the executor's recognizer and the controller read the same reports (the same report
    objects), and 568 modules' headings cost a walk over every link each time. The
    mappings returned are shared: read them, never change them."""
    found = _HEADINGS.get(reports)
    if found is None:
        links = links_of(reports)
        found = (links, module_headings(reports, links))
        _HEADINGS.entry = (list(reports.items()), found)
    return found


def spread_headings(neighbours: Mapping[str, Sequence[tuple[str, float]]],
                    order: Sequence[str]) -> tuple[dict[str, float], list[str]]:
    """Headings [rad] from measured relative yaws, breadth first over each group.

    ``neighbours[u]`` lists ``(v, psi_v - psi_u)``; each group's root is its first
    module in ``order`` (heading 0). Returns the headings and the roots.
    """
    heading: dict[str, float] = {}
    roots: list[str] = []
    for start in order:
        if start in heading:
            continue
        heading[start] = 0.0
        roots.append(start)
        queue = deque([start])
        while queue:
            u = queue.popleft()
            for v, delta in neighbours[u]:
                if v not in heading:
                    heading[v] = heading[u] + delta
                    queue.append(v)
    return heading, roots


class ContactRecognizer:
    """Configuration identification from single-connector module reports.

    Args:
        robot: robot name of the configurations made. kind: their module kind.
    """

    description = "connector contact + IMU tilt + drive odometry -> configuration"

    def __init__(self, robot: str, kind: str):
        self.name = robot
        self.robot = robot
        self.kind = kind

    def recognize(self, observation: Reports, *, seed: int = 0) -> Configuration:
        """The configuration the reports show, in the root's horizontal frame.

        Raises:
            ConfigurationError: a report of another type.
        """
        for module, report in observation.items():
            if not isinstance(report, ModuleReport):
                raise ConfigurationError(f"module {module!r}: not a freeform module report "
                                         f"({type(report).__name__})")
        links, heading = link_headings(observation)
        config = Configuration(self.robot)
        for module in sorted(observation):
            config.add_module(module, self.kind)
        vectors = link_vectors(observation, links, heading)
        for i in sorted(links):
            config.connect(i, links[i], z=vectors[i])
        return config


def _towards(config: Configuration, old: str, new: str) -> np.ndarray | None:
    """The unit vector (3,) from ``old`` to ``new`` along their connection, or ``None``."""
    for e in config.edges():
        if e.z is not None and {e.source, e.target} == {old, new}:
            return np.asarray(e.z) if e.source == old else -np.asarray(e.z)
    return None


def goal_side(goal: Configuration, module: str, old: str, new: str) -> float:
    """On which side of the line from ``old`` to ``new`` ``goal`` puts ``module``, seen
    from above: ``(t x p) . e_z`` with ``t`` the direction from ``old`` to ``new`` and ``p``
    the place of ``module`` from ``old`` (unit spacing); positive: to the left. 0 when
    ``goal`` does not connect the three (a turn about the vertical leaves it unchanged)."""
    t = _towards(goal, old, new)
    on = next((e for e in goal.edges() if e.source == module and e.target == new), None)
    if t is None or on is None or on.z is None:
        return 0.0
    return float(np.cross(t, t - np.asarray(on.z))[2])


def flow_direction(config: Configuration, module: str, old: str, new: str,
                   side: float = 0.0) -> np.ndarray:
    """Where ``module`` must sit on ``old`` to touch ``new`` too: the unit direction (3,)
    from ``old``'s centre, in ``config``'s frame, at :data:`FLOW_ANGLE` from the direction
    to ``new``. Of the circle of such places, the level one on the side ``side`` gives
    (:func:`goal_side`: the side where the module is headed), else the one nearest to
    ``module``'s place; see :data:`SIDE_TIE` when every side is as near.

    Raises:
        ConfigurationError: ``module`` is not on ``old``, or ``new`` is not next to ``old``.
    """
    here = next((e for e in config.edges() if e.source == module and e.target == old), None)
    if here is None or here.z is None:
        raise ConfigurationError(f"flow of {module}: it is not docked on {old}")
    towards = _towards(config, old, new)
    if towards is None:
        raise ConfigurationError(f"flow of {module}: {new} is not next to {old}")
    left = np.cross(_EZ, towards)
    if abs(side) > SIDE_GOAL and np.linalg.norm(left) > 0.5:
        along = np.sign(side) * left / np.linalg.norm(left)
        return np.cos(FLOW_ANGLE) * towards + np.sin(FLOW_ANGLE) * along
    u = -np.asarray(here.z)
    along = u - (u @ towards) * towards
    norm = np.linalg.norm(along)
    if norm < np.sin(SIDE_TIE):   # (nearly) opposite the new parent: stay level
        along = np.cross(towards, _EZ)
        norm = np.linalg.norm(along)
        if norm < 1e-9:
            along, norm = canonical_perpendicular(towards), 1.0
    along = along / norm
    return np.cos(FLOW_ANGLE) * towards + np.sin(FLOW_ANGLE) * along


def common_turn(current: Configuration, target: Configuration) -> float:
    """The turn [rad] about the vertical shared by most connections: the median over the
    connections of both (with a horizontal part) of the yaw from ``target``'s vector to
    ``current``'s (:func:`~msrr.core.alignment.median_yaw`; 0 when none has one). Robust
    where the least-squares yaw of eq. 8 is not: while one module still has far to go,
    the eq. 8 yaw would turn the whole goal part of the way towards it, and every other
    module would start moving the wrong way."""
    ids = [e.id for e in target.edges() if e.z is not None and e.id in current.edge_ids()
           and current.edge(e.id).z is not None]
    turn = median_yaw(current.vectors(ids), target.vectors(ids)) if ids else None
    return 0.0 if turn is None else turn


def sucker_twist(current: Configuration, target: Configuration, module: str) -> float:
    """The turn [rad] of ``module`` about its connection vector (its sucker's axis,
    right-handed about the vector) that brings the connections of the modules on it
    from ``current``'s vectors to ``target``'s (both in one frame): the angle of the
    sum of their rotations, each seen in the plane across the axis. 0 when none is on
    it or ``module`` is free in ``current``."""
    own = _outgoing(current, module)
    if own is None:
        return 0.0
    axis = own / np.linalg.norm(own)
    across = np.eye(3) - np.outer(axis, axis)
    num = den = 0.0
    for e in target.edges():
        have = _vector(current, e.source, module)
        if e.target != module or e.z is None or have is None:
            continue
        a, b = across @ have, across @ np.asarray(e.z)
        num += float(np.cross(a, b) @ axis)
        den += float(a @ b)
    return float(np.arctan2(num, den)) if num or den else 0.0


def _vector(config: Configuration, source: str, target: str) -> np.ndarray | None:
    """The vector ``z`` (3,) of ``config``'s connection ``source -> target``, or ``None``."""
    e = next((e for e in config.edges() if e.source == source and e.target == target), None)
    return None if e is None or e.z is None else np.asarray(e.z, dtype=float)


def _outgoing(config: Configuration, module: str) -> np.ndarray | None:
    """The vector of ``module``'s own connection (its connector's), or ``None``."""
    e = next((e for e in config.edges() if e.source == module and e.z is not None), None)
    return None if e is None else np.asarray(e.z, dtype=float)


def _swinging(links: Mapping[str, str], latched: set[str]) -> set[str]:
    """The modules whose own connection, turned, swings a module of ``latched``: those
    modules and every module ``links`` (module -> the module its connector holds) shows
    carrying one of them, down the chain of connectors toward the sink."""
    out: set[str] = set()
    for m in latched:
        while m in links and m not in out:
            out.add(m)
            m = links[m]
    return out


def anchors(current: Configuration, goal: Configuration, links: Mapping[str, str]
            ) -> dict[str, float]:
    """``module ->`` the turn [rad] about the vertical that lays ``goal`` onto ``current``
    where that module's horizontal frame is: the turn of its own connection (``links``:
    module -> the module its connector holds), or, for a group's root (no connection of
    its own, or one without a horizontal part), the median turn of the connections into
    it (:func:`~msrr.core.alignment.median_yaw`). Missing where neither is known.

    A module's heading is chained over every link from its group's root
    (:func:`module_headings`), so under noise it carries every link's yaw error on the way
    (about 3.5 deg per link: 5-15 deg at the end of a row of twelve). The same error is in
    its own recognized connection, so a goal turned by this anchor is the goal's bend at
    that module: aiming the connections into it there needs only its own readings."""
    into: dict[str, list[str]] = {}
    for source, target in links.items():
        into.setdefault(target, []).append(source)
    out: dict[str, float] = {}
    for module, children in into.items():
        own = [(module, links[module])] if module in links else []
        for pairs in (own, [(c, module) for c in children]):
            have = [(_vector(current, a, b), _vector(goal, a, b)) for a, b in pairs]
            found = [(c, t) for c, t in have if c is not None and t is not None]
            turn = median_yaw(np.array([c for c, _ in found]).T,
                              np.array([t for _, t in found]).T) if found else None
            if turn is not None:
                out[module] = turn
                break
    return out


def _links(config: Configuration) -> dict[str, str]:
    """``module -> the module its connector holds`` in ``config`` (its edges with a vector
    run from the connector's owner)."""
    return {e.source: e.target for e in config.edges() if e.z is not None}


def bend_errors(current: Configuration, goal: Configuration, *,
                held: Collection[str] = ()) -> tuple[float, np.ndarray]:
    """How far ``current``'s bends are from ``goal``'s: ``(rms, per-connection angles
    (n,))`` [rad], each connection ``i -> j`` of both (with a vector) compared with the
    goal's turned about the vertical by ``j``'s :func:`anchors` (where ``j`` has none,
    by the connections' common turn, :func:`common_turn`); ``(0, [])`` when they share
    none. It is what :meth:`ContactController.commands` aims at, so what its moves are
    reached by: eq. 8's distance after one yaw alignment of the whole carries the
    headings' chained errors, which no command takes out. The connection of a module
    of ``held`` within ``_LATCH_HOLD`` is left out: the controller holds it (a latched
    piece's, :meth:`ContactController.commands`) and does not move it."""
    links = _links(current)
    anchor = anchors(current, goal, links)
    common = common_turn(current, goal)
    angles = []
    for e in goal.edges():
        have = _vector(current, e.source, e.target)
        if e.z is None or have is None or links.get(e.source) != e.target:
            continue
        aim = rot_z(anchor.get(e.target, common)) @ np.asarray(e.z, dtype=float)
        angle = _angle(have, aim)
        if e.source not in held or angle >= _LATCH_HOLD:
            angles.append(angle)
    if not angles:
        return 0.0, np.zeros(0)
    out = np.array(angles)
    return float(np.sqrt(np.mean(out**2))), out


def bend_error(current: Configuration, goal: Configuration) -> float:
    """RMS angle [rad] of :func:`bend_errors`."""
    return bend_errors(current, goal)[0]


def _angle(a: np.ndarray | None, b: np.ndarray | None) -> float:
    """The angle [rad] between two vectors (3,), ``inf`` when either is ``None``."""
    if a is None or b is None:
        return float("inf")
    cos = float(np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b)))
    return float(np.arccos(np.clip(cos, -1.0, 1.0)))


_LATCH_HOLD = np.radians(20.0)
"""A latched piece's connection within this of its target is held
(:meth:`ContactController.commands`): under 2 deg of angle noise the recognition reads a
latched connection up to 10 deg off from tick to tick (pieces-to-tree, seed 12, the final
move's first ticks: 1.0-10.0 deg), so a smaller band chased the noise."""


class Latches:
    """What the controllers of one robot know of the pieces that travelled and latched,
    shared by all of them (one per joint mode; :class:`BendMeasure` compares by it).

    Attributes:
        modules: the modules of those pieces (held within ``_LATCH_HOLD``).
        pieces: root -> (the module it latched on, the piece's modules).
        swing: root -> its piece's turn error [rad] low-passed (:func:`piece_turn`).
        began: root -> driver time [s] its swing began.
        settled: the roots whose swing is done (held from then on).
        read: root -> driver time [s] its turn was last read (once a tick, whichever of
            the robot's controllers reads it).
    """

    def __init__(self) -> None:
        self.modules: set[str] = set()
        self.pieces: dict[str, tuple[str, tuple[str, ...]]] = {}
        self.swing: dict[str, float] = {}
        self.began: dict[str, float] = {}
        self.settled: set[str] = set()
        self.read: dict[str, float] = {}

    def clear(self) -> None:
        """Forget every latch (a new run)."""
        for known in (self.modules, self.pieces, self.swing, self.began, self.settled,
                      self.read):
            known.clear()

    def latch(self, root: str, target: str, piece: Collection[str]) -> None:
        """``root``'s piece ``piece`` latched on ``target``."""
        self.modules.update(piece)
        self.pieces[root] = (target, tuple(sorted(piece)))
        for known in (self.swing, self.began, self.read):
            known.pop(root, None)
        self.settled.discard(root)

    def swinging(self, links: Mapping[str, str]) -> dict[str, tuple[str, tuple[str, ...]]]:
        """The latched pieces still to be swung onto their goal (root -> (target, piece)),
        those whose root still holds its target in ``links``."""
        return {r: p for r, p in self.pieces.items()
                if r not in self.settled and links.get(r) == p[0]}


def piece_turn(current: Configuration, goal: Configuration, links: Mapping[str, str],
               target: str, piece: Collection[str]) -> float | None:
    """The turn [rad] about the vertical of a piece latched on ``target`` from its goal:
    the mean signed yaw of its connections (its own and the latch, ``links``) against
    ``goal``'s turned by ``target``'s :func:`anchors` (its goal's place at ``target``,
    free of the headings' chained errors). A turn of the whole piece about ``target``'s
    centre turns each of them by as much, so it takes this out at best (eq. 8 over
    them). ``None`` when ``target`` has no anchor or none of them lies horizontal."""
    turn = anchors(current, goal, links).get(target)
    if turn is None:
        return None
    out = []
    for m in piece:
        have, want = _vector(current, m, links.get(m, "")), _vector(goal, m, links.get(m, ""))
        if have is None or want is None:
            continue
        want = rot_z(turn) @ want
        if np.hypot(*have[:2]) < _LEVEL or np.hypot(*want[:2]) < _LEVEL:
            continue
        out.append(wrap_angle(np.arctan2(have[1], have[0]) - np.arctan2(want[1], want[0])))
    return float(np.mean(out)) if out else None


_LEVEL = 0.5
"""Smallest horizontal part of a unit connection vector whose yaw :func:`piece_turn` reads."""


class BendMeasure:
    """The reach measure of controllers that aim at the bends (:func:`bend_errors`, RMS):
    the connections they hold (a latched piece's within ``_LATCH_HOLD``) left out; while a
    latched piece is still being swung, at least its turn (:func:`piece_turn`) times
    ``_SWING_WEIGHT``, so a move does not end before the swing: in the RMS over the
    bends, a row's turn of 3.6 deg was diluted under the move's 3 deg and the final move
    ended within 0.1-1.4 s, the swing not begun or cut short (pieces-to-tree at 2 deg).

    Named (``name``) and compared by its :class:`Latches`: the controllers of one robot
    share theirs, so every one of its joint modes gives the same measure
    (:func:`~msrr.core.closed_loop.reach_measure`)."""

    name = "bends"

    def __init__(self, latches: Latches):
        self.latches = latches

    def __eq__(self, other: object) -> bool:
        return isinstance(other, BendMeasure) and other.latches is self.latches

    def __hash__(self) -> int:
        return hash((self.name, id(self.latches)))

    def __repr__(self) -> str:
        return f"BendMeasure(latches={id(self.latches):#x})"

    def __call__(self, current: Configuration, goal: Configuration) -> float:
        links = _links(current)
        rms, _ = bend_errors(current, goal, held=_swinging(links, self.latches.modules))
        turns = [piece_turn(current, goal, links, target, piece)
                 for target, piece in self.latches.swinging(links).values()]
        # a piece turned _LATCH_HOLD or more is moved by its connections; in their RMS over
        # a large robot its few weigh little (3 of 560 connections 60 deg off: 4.4 deg), so
        # its turn counts as it is
        pending = [abs(t) for t in turns if t is not None]
        return max([rms] + [_SWING_WEIGHT * t if t < _LATCH_HOLD else t for t in pending])


def _direction(vector: np.ndarray) -> dict[str, float]:
    return {f"dir_{a}": float(c) for a, c in zip("xyz", vector, strict=True)}


class ContactController:
    """Controller of one single-connector joint mode (registered as its ``controller``).

    :meth:`commands` turns IK joint vectors into each module's connection vector in its
    parent's horizontal frame (the executor's tracking path); :meth:`control` runs the
    phases without IK: flows, releases, docks, and a move straight to the target.

    Args:
        name: registered name (the joint mode's ``controller``).
        recognizer: the robot's recognizer (same frames as the commands).
        sucker: engage the sucker of every commanded module (sucker-revolute mode).
        tolerance: RMS angle [rad] under which a direct move is reached
            (:attr:`reach_measure`, on the recognized vectors low-passed by ``smoothing``,
            the newest tick's weight).
        flow_tolerance: angle [rad] from the place touching the new parent under which a
            flow's rolling is reached.
        spacing: centre distance of two docked modules [m] (the dead reckoning's scale).
        ground_speed: fastest travel of a free module over the floor [m/s].
        arrive: distance [m] from the docking spot under which an approach is reached.
        bends: aim each connection at its goal's bend at its parent and reach the moves
            on those bends (:func:`anchors`, :attr:`reach_measure`; FreeBOT), else in the
            root's frame, reached on eq. 8's distance (SnailBot: with the bends its exact
            ``pieces-to-tree`` ended 7.4 deg off, not diagnosed). Never with ``sucker``.
        piece_speed: fastest centre of a piece travelling over the floor [m/s], or 0: a
            module that carries others does not travel (its connector is rigid with the
            shell its tracks hold: SnailBot).
        layout: how the modules of a start configuration are laid out (their centres
            (3,) [m] and connector frames (3, 3), one frame), as a lab places them from
            the start file (:func:`~msrr.core.freeform.world.place`); ``None``: not known.
    """

    def __init__(self, name: str, recognizer: ContactRecognizer, *, sucker: bool = False,
                 tolerance: float = np.radians(3.0), flow_tolerance: float = np.radians(2.0),
                 spacing: float = 0.1, ground_speed: float = 0.04, arrive: float = 0.005,
                 piece_speed: float = 0.0, smoothing: float = 0.5, bends: bool = False,
                 latches: Latches | None = None,
                 layout: Callable[[Configuration], tuple[Mapping[str, np.ndarray],
                                                         Mapping[str, np.ndarray]]] | None = None):
        self.name = name
        self.description = (f"{recognizer.robot} connection vectors -> drive commands"
                             + (" (sucker engaged)" if sucker else ""))
        self.recognizer = recognizer
        self.sucker = sucker
        self.tolerance = tolerance
        self.flow_tolerance = flow_tolerance
        self.smoothing = smoothing
        self.bends = bends and not sucker
        self.ground_speed = ground_speed
        self.arrive = arrive
        self.locator = Locator(spacing)
        self._yaw = 0.0
        self.piece_speed = piece_speed
        self._ways: dict[str, tuple[str, np.ndarray, np.ndarray]] = {}
        """module -> (target, its way, the target's centre): odometry frame ``O``."""
        self._pieces: dict[str, tuple[PieceWay, int]] = {}
        """root -> (its piece's way, the leg it is on)."""
        self._still: dict[str, tuple[float, np.ndarray]] = {}
        """module -> (driver time [s], odometry (2,)) since which it has not moved."""
        self._stopped: set[str] = set()
        """Modules whose approach was blocked near its end (:meth:`_blocked`)."""
        self._aims: dict[str, tuple[int, float, float, float, bool]] = {}
        """root -> a straight piece's drive re-aim (:meth:`_aim`): (its stage, the angle
        low-passed [rad], driver time [s], the turn rate since, turning)."""
        self._layout = layout
        self._planned: Configuration | None = None
        """The plan's configuration before the action being run (``None``: not known)."""
        self._acting: Action | None = None
        self.latches = Latches() if latches is None else latches
        """The pieces that travelled and latched (:meth:`commands`), shared with the
        robot's other controllers."""
        self._seen: dict[str, np.ndarray] = {}
        """Edge id -> its vector low-passed over a move's ticks (:meth:`_smoothed`)."""

    @property
    def reach_measure(self) -> ReachMeasure:
        """How far a recognized configuration is from a goal [rad], as this controller's
        commands see it: with ``bends``, the bends it aims at (:class:`BendMeasure`: those
        it holds left out, as they keep the latch's error; a latched piece it still swings
        counted by its turn), else eq. 8's RMS angle after one yaw alignment
        (:data:`~msrr.core.closed_loop.EQ8`). Its moves are reached on it, and the
        executor's tracking judges the phases it drives on it
        (:attr:`~msrr.core.closed_loop.PhaseTracker.error`). Pieces-to-tree under 2 deg
        of noise, the final move: 18 of 19 connections held, the move stalled on their
        errors when they were counted."""
        return BendMeasure(self.latches) if self.bends else EQ8

    def start(self, configuration: Configuration) -> None:
        """The run starts from ``configuration``: the locator learns where its modules
        were laid (``layout``), so separate start pieces are related on its map
        (:meth:`~msrr.core.freeform.travel.Locator.start`)."""
        self.locator = Locator(self.locator.spacing)
        self._ways, self._pieces = {}, {}
        self._planned, self._acting = None, None   # the plan may start from a recognition
        self.latches.clear()
        if self._layout is not None:
            centres, frames = self._layout(configuration)
            self.locator.start({m: (centres[m], frames[m]) for m in centres})

    def commands(self, target: Configuration, observation: Observation, *,
                 yaw: float | None = None, current: Configuration | None = None,
                 drive_root: str | None = None) -> dict[str, ModuleCommand]:
        """Commands toward ``target``'s vectors (root horizontal frame); every connection
        is driven alike, so ``drive_root`` is not used.

        ``yaw`` [rad] turns them into the recognized frame; on top of it, the common turn
        about the vertical that is left between them and the recognized configuration is
        removed (:func:`common_turn`): turning every module about its parent by the same
        yaw would only spin the whole robot on the ground, and the reaction on the free
        root would make the IK's yaw-aligned goal chase it round. Each connection's goal
        is then turned about the vertical onto where its parent's own connection is
        recognized (:func:`anchors`), so the command is the goal's bend at the parent, free
        of the heading errors chained from the group's root: under 2 deg of noise the
        absolute aims swung a resting row of twelve 5-15 deg every tick and broke four
        connections within 3.2 s (pieces-to-tree, seed 17, the move after the releases).
        The moves are reached on the same bends (:func:`bend_error`).

        A connection that would swing a piece that travelled and latched -- owned by one
        of its modules, or by a module that carries it (:func:`_swinging`) -- is held (no
        command: the driver brakes it) while the target's vector is within
        ``_LATCH_HOLD`` of where it is: the piece travelled into the goal's shape, and
        what is left is the map's error at the latch and the recognition's noise. Moving
        it would swing the piece over the floor on braked shells, dragging it: under
        2 deg of noise pieces-to-tree's final move so broke F2-F3 (F2 carries F1 and the
        latched F13-F16; 7 N on F2-F3 within the move's first 0.1 s).
        Such a piece a few degrees off its goal's place is swung onto it instead, rolling
        about the module it latched on (:meth:`_swing`), then held."""
        reports = observation.sensors
        current = current or self.recognizer.recognize(reports)
        yaw = (yaw or 0.0)
        yaw += common_turn(current, target.derive(rotation=rot_z(yaw)))
        links, heading = link_headings(reports)
        turn = rot_z(yaw)
        turned = target.derive(rotation=turn)
        out: dict[str, ModuleCommand] = {}
        swings = _swinging(links, self.latches.modules)
        anchor = anchors(current, turned, links) if self.bends else {}
        swung = self._swing(current, turned, links, observation) if self.bends else {}
        out.update(swung)
        for e in target.edges():
            if e.z is None or links.get(e.source) != e.target or e.source in swung:
                continue
            aim = rot_z(anchor.get(e.target, 0.0)) @ turn @ np.asarray(e.z)
            if e.source in swings and _angle(_vector(current, e.source, e.target), aim) \
                    < _LATCH_HOLD:
                continue
            if self.sucker:   # anchored: only a turn about the sucker's axis
                joints = {"sucker": 1.0, "twist": sucker_twist(current, turned, e.source)}
            else:
                joints = _direction(rot_z(-heading[e.target]) @ aim)
            out[e.source] = ModuleCommand(joints=joints)
        return out

    def _swing(self, current: Configuration, goal: Configuration, links: Mapping[str, str],
               observation: Observation) -> dict[str, ModuleCommand]:
        """The commands that swing each latched piece onto its goal about the centre of the
        module it latched on, rolling (:meth:`~msrr.core.freeform.world.FreeformWorld.command_travel`:
        one rigid twist turning about that centre; its shells roll, nothing drags).

        A latch lands where the piece's root touches its target, which the map has
        centimetres off under noise, so the piece lies a few degrees off its goal's place
        there (pieces-to-tree at 2 deg, seed 18: both rows latched, the true shape 5.04 deg
        off, and the held rows kept it). Its turn (:func:`piece_turn`, low-passed:
        ``_SWING_SMOOTHING``) is read for ``_SWING_LOOK`` ticks, then taken out at
        ``_SWING_GAIN`` per second, at most ``_SWING_RATE``, until it is under
        ``_SWING_DONE`` or ``_SWING_TIME`` has passed; from then on the piece is held
        (:attr:`Latches.settled`). A piece turned ``_LATCH_HOLD`` or more is moved by its
        connections' own commands, as before."""
        latches, out = self.latches, {}
        pieces = latches.swinging(links)
        if not pieces or not self.piece_speed:
            return out
        self._locate(observation.sensors)
        for root, (target, piece) in pieces.items():
            if latches.read.get(root) != observation.time:   # read once a tick
                turn = piece_turn(current, goal, links, target, piece)
                if turn is None:
                    continue
                old, a = latches.swing.get(root), _SWING_SMOOTHING
                latches.swing[root] = turn if old is None else (1 - a) * old + a * turn
                latches.read[root] = observation.time
            error = latches.swing[root]
            began = latches.began.setdefault(root, observation.time)
            looked = observation.time - began >= _SWING_LOOK - 1e-9
            if abs(error) >= _LATCH_HOLD or not looked:
                continue
            if abs(error) < _SWING_DONE or observation.time - began > _SWING_TIME:
                latches.settled.add(root)
                continue
            rate = float(np.clip(-_SWING_GAIN * error, -_SWING_RATE, _SWING_RATE))
            centres = {m: self.locator.pose(m)[0] for m in piece}
            headings = {m: self.locator.pose(m)[1] for m in piece}
            velocities, w = twist_velocities(centres, headings, np.zeros(2), rate,
                                             self.locator.pose(target)[0][:2],
                                             speed=self.piece_speed)
            out.update({m: ModuleCommand(joints={"roll_x": float(v[0]), "roll_y": float(v[1]),
                                                 "turn": w}) for m, v in velocities.items()})
        return out

    def begin(self, action: Action, phase: Phase, observation: Observation) -> float | None:
        """Fix the yaw of the action's target for this phase (eq. 8 alignment); for an
        approach, find the way of each free module to the module it docks on, and return
        the driver time [s] the longest way takes at its speed (a lone module's at
        ``ground_speed``, a piece's farthest module's at ``piece_speed``,
        :meth:`~msrr.core.freeform.piece_way.PieceWay.travel`)."""
        if action is not self._acting:
            if self._acting is not None:
                self._planned = self._acting.target
            self._acting = action
        reports = observation.sensors
        self._locate(reports)
        current = self.recognizer.recognize(reports)
        if phase is Phase.APPROACH:
            self._ways, self._pieces = self._plan_ways(current, action, reports)
            self._still, self._stopped, self._aims = {}, set(), {}
            lone = [float(np.sum(np.linalg.norm(np.diff(way, axis=0), axis=1)))
                    / self.ground_speed for _, way, _ in self._ways.values()]
            pieces = [way.travel() / self.piece_speed for way, _ in self._pieces.values()]
            return max(lone + pieces, default=0.0)
        if phase is Phase.CONNECT and (self._ways or self._pieces):
            return None
        self._ways, self._pieces = {}, {}
        self._yaw = skeletal_errors(current, action.target)[2]
        self._seen = {}
        return None

    def _locate(self, reports: Reports) -> None:
        """Give the locator this tick's reports."""
        self.locator.update(reports, *link_headings(reports))

    def _plan_ways(self, current: Configuration, action: Action, reports: Reports
                   ) -> tuple[dict[str, tuple[str, np.ndarray, np.ndarray]],
                              dict[str, tuple[PieceWay, int]]]:
        """The way over the floor (points (n, 2) in its odometry frame) of each module the
        action docks while it is free and alone, and its target's centre (2,) in that
        frame: it travels alone to a spot touching its target; and the
        :class:`~msrr.core.freeform.travel.PieceWay` of each such module that carries
        others (its piece travels as one rigid body to the place the action's target
        gives it).

        Raises:
            ExecutionError: no way is free (:func:`~msrr.core.freeform.travel.floor_path`,
                :func:`~msrr.core.freeform.travel.plan_piece_way`), or a piece is to
                travel but the robot's pieces do not (``piece_speed`` 0).
        """
        ways, pieces = {}, {}
        goal: dict[str, np.ndarray] | None = None
        for change in topology_diff(current, action.target).made:
            module, target = change.source, change.target
            if _joined(current, module, target):
                continue
            if not self.locator.alone(module):
                if not self.piece_speed:
                    raise ExecutionError(f"module {module} is to dock on {target} but carries "
                                         f"other modules: a {self.recognizer.robot} travels "
                                         "over the floor only alone")
                goal = goal or _layout(action.target, self.locator.spacing)
                pieces[module] = (plan_piece_way(self.locator, module, target, goal), 0)
                continue
            others = self.locator.relative(module)
            way = floor_path(others, target, self.locator.spacing)
            odometry = reports[module].odometry
            into = rot_z(float(odometry[2]))[:2, :2]
            ways[module] = (target, odometry[:2] + np.array(way) @ into.T,
                            odometry[:2] + into @ others[target][:2])
        return ways, pieces

    def _travel_pieces(self, phase: Phase, reports: Reports, time: float) -> Control:
        """One tick of the pieces' travel (approach: leg by leg, see
        :class:`~msrr.core.freeform.piece_way.PieceWay`), or of their guarded push onto
        the target with the root's connector armed (connect): a twist of each piece from
        its pose on the map (:meth:`Locator.pose`, the centroid of its modules), sent to
        each module as the velocity of its own centre
        (:func:`~msrr.core.freeform.travel.twist_velocities`). A turn holds the centroid;
        a bent piece's drive holds the leg's heading and its line, a straight piece's
        drives straight on (it cannot roll across its line, so it cannot steer).

        A piece whose root reports the latch on its target travels no more: it is dropped
        from the ways and given no command (the driver holds a module dropped from the
        commands). Before, it was told to travel again on the tick that saw the latch,
        and that travel outlived the dock: the world's hold at the latch was undone, and
        under 2 deg of noise the piece kept rolling into the tree through the plan's final
        move until a connection broke (pieces-to-tree, seed 12, F11-F12 at 10.2 N).

        The push aims at the target where the map has it on this tick, not where the way
        was planned: a piece at rest rolls on once pushed (nothing brakes a sphere rolling
        on the floor), and in ``chains-to-tree`` the row F1-F4, pressed by the piece that
        drove out beside it, rolled 9 cm across while that piece travelled; the push
        stopped at the planned place, 9 cm short, and the dock never latched."""
        commands, errors = {}, {}
        for root, (way, stage) in list(self._pieces.items()):
            if phase is Phase.CONNECT and reports[root].attached == way.target:
                del self._pieces[root]
                self.latches.latch(root, way.target, way.piece)
                continue
            centres = {m: self.locator.pose(m)[0] for m in way.piece}
            headings = {m: self.locator.pose(m)[1] for m in way.piece}
            middle = np.mean([c[:2] for c in centres.values()], axis=0)
            heading = way.heading_of(centres)
            if phase is Phase.CONNECT:   # toward the target where the map has it now
                toward = self.locator.pose(way.target)[0][:2] - self.locator.pose(root)[0][:2]
                velocity = 0.5 * self.piece_speed * (float(toward @ way.push) > 0) * way.push
                left = max(0.0, float(np.linalg.norm(toward)) - self.locator.spacing)
                turn = float(np.clip(_YAW_GAIN * wrap_angle(way.legs[-1].heading - heading), -1, 1))
            else:
                while stage < len(way.legs) and self._leg_done(way, stage, middle, heading):
                    stage += 1
                self._pieces[root] = (way, stage)
                velocity, turn, left = self._leg_twist(way, stage, middle, heading, time)
            if way.line is not None:      # a straight piece moves along its line only
                along = rot_z(heading)[:2, :2] @ way.line
                velocity = float(velocity @ along) * along
            velocities, w = twist_velocities(centres, headings, velocity, turn, middle,
                                             speed=self.piece_speed)
            for m, v in velocities.items():
                dock = (f"@{way.target}",) if phase is Phase.CONNECT and m == root else ()
                commands[m] = ModuleCommand(joints={"roll_x": float(v[0]), "roll_y": float(v[1]),
                                                    "turn": w}, dock=dock)
            errors[root] = left
        return Control(commands=commands, errors=errors,
                       reached=all(e < self.arrive for e in errors.values()))

    def _leg_done(self, way: PieceWay, stage: int, middle: np.ndarray, heading: float) -> bool:
        """Whether the piece at centroid ``middle`` (2,) and root heading ``heading`` has
        done leg ``stage`` of ``way`` (a turn within ``_YAW_DONE``, a drive within
        ``arrive`` of its end, or past it)."""
        leg = way.legs[stage]
        if leg.kind == "turn":
            return abs(wrap_angle(leg.heading - heading)) < _YAW_DONE
        return float((leg.to - middle) @ way.direction(stage)) < self.arrive

    def _leg_twist(self, way: PieceWay, stage: int, middle: np.ndarray, heading: float,
                   time: float) -> tuple[np.ndarray, float, float]:
        """The twist (velocity (2,) [m/s] of the centroid, turn [rad/s]) for leg
        ``stage`` of ``way`` at driver ``time`` [s], and the travel left [m] (the
        farthest module's, to the way's end; 0 when every leg is done)."""
        if stage >= len(way.legs):
            return np.zeros(2), 0.0, 0.0
        reach = max(float(np.max(np.linalg.norm(
            np.array([self.locator.pose(m)[0][:2] for m in way.piece]) - middle, axis=1))),
            self.locator.spacing)
        leg = way.legs[stage]
        left = sum(float(np.linalg.norm(b.to - a.to)) + reach * abs(wrap_angle(b.heading - a.heading))
                   for a, b in zip(way.legs[stage:], way.legs[stage + 1:], strict=False))
        if leg.kind == "turn":
            off = wrap_angle(leg.heading - heading)     # about the leg's pivot, held
            return 0.5 * (leg.to - middle), float(np.clip(_YAW_GAIN * off, -1.0, 1.0)), \
                left + reach * abs(off) + self.arrive
        direction = way.direction(stage)
        ahead = float((leg.to - middle) @ direction)
        across = float(np.cross(direction, middle - leg.to))   # left of the leg's line
        velocity = min(self.piece_speed, max(ahead, 0.0) + 0.002) * direction
        # a bent piece holds the leg's heading and moves back onto the leg's line across it
        if way.line is not None:
            # a straight piece does not steer while it drives: nothing grips the floor
            # across its line, so turning it as it moves leaves its velocity behind and
            # it rolls sideways (about its own line) -- 1 mm/s per second at 0.018 m/s
            # and 0.06 rad/s, measured -- and keeps rolling once stopped; its turns are
            # in place, and so are its re-aims (:meth:`_aim`)
            turn = self._aim(way.root, stage, leg.to - middle,
                             rot_z(heading)[:2, :2] @ way.line, time)
            if turn is not None:
                return np.zeros(2), float(np.clip(turn, -1.0, 1.0)), \
                    left + max(ahead, 0.0) + self.arrive
            return velocity, 0.0, left + max(ahead, 0.0) + self.arrive
        steer = float(np.clip(-_STEER_GAIN * across, -_STEER, _STEER))
        velocity = velocity + steer * self.piece_speed * np.array([-direction[1], direction[0]])
        turn = float(np.clip(_YAW_GAIN * wrap_angle(leg.heading - heading), -1.0, 1.0))
        return velocity, turn, left + max(ahead, 0.0) + self.arrive

    def _aim(self, root: str, stage: int, to: np.ndarray, along: np.ndarray,
             time: float) -> float | None:
        """The turn rate [rad/s] in place that points a straight piece's line ``along``
        (unit (2,), map) at the end of its drive ``stage``, ``to`` (2,) [m] from its
        centroid, when the piece led by ``root`` is to stop and make it; ``None``: it
        drives on.

        Its line points where its last turn left it, within ``_YAW_DONE`` and the map's
        error, and it cannot steer back onto the drive's line: in the human example 1.5 deg
        over a 3.5 m drive put a piece 50 mm across its line (action 5), its push then
        latched 19 deg off its goal place, that place took the next pieces' goal places
        (actions 7-8 latched 52 deg off theirs), and action 9 found no place free. So the
        piece re-aims at the drive's end when its line is ``_AIM`` off the bearing there,
        turning until it is within ``_AIM_DONE``; within ``_AIM_NEAR`` of the end it drives
        on (the bearing swings as it arrives). The angle is low-passed
        (``_AIM_SMOOTHING``, predicted by the turn commanded): a piece's heading on the
        map jitters by degrees from tick to tick under 2 deg of angle noise, and re-aimed
        on each reading pieces-to-tree's pieces stopped 355 times (seed 11)."""
        distance = float(np.linalg.norm(to))
        if distance < _AIM_NEAR:
            self._aims.pop(root, None)
            return None
        if along @ to < 0:     # it drives backwards along its line
            along = -along
        seen = wrap_angle(float(np.arctan2(to[1], to[0]) - np.arctan2(along[1], along[0])))
        state = self._aims.get(root)
        if state is None or state[0] != stage:   # a new drive: read it before acting
            self._aims[root] = (stage, seen, time, 0.0, False)
            return None
        _, off, then, rate, turning = state
        off -= rate * (time - then)              # the turn made since
        off = wrap_angle(off + _AIM_SMOOTHING * wrap_angle(seen - off))
        turning = abs(off) > _AIM or (turning and abs(off) > _AIM_DONE)
        rate = float(np.sign(off)) * max(_AIM_RATE, _YAW_GAIN * abs(off)) if turning else 0.0
        self._aims[root] = (stage, off, time, rate, turning)
        return rate if turning else None

    def _travel(self, phase: Phase, reports: Reports, time: float) -> Control:
        """One tick of the free modules' travel (approach), or of their last push onto
        the target with the connector armed (connect): a guarded move toward the
        target's estimated centre at half the travel speed until the connector reports
        the latch (dead reckoning is centimetres off after a long way; the shells
        touching stop the push). A module whose approach is blocked near its way's end
        (:meth:`_blocked`) has done its approach and waits, still, for the push."""
        commands, errors = {}, {}
        for module, (target, way, centre) in self._ways.items():
            odometry = reports[module].odometry
            if phase is Phase.CONNECT:
                toward = centre - odometry[:2]
                velocity = 0.5 * self.ground_speed * normalized(toward)
                left = max(0.0, float(np.linalg.norm(toward)) - self.locator.spacing)
            else:
                velocity, left = pursue(way, odometry[:2], speed=self.ground_speed)
                if module in self._stopped or self._blocked(module, odometry[:2], time, left):
                    velocity, left = np.zeros(2), 0.0
            v = rot_z(-float(odometry[2]))[:2, :2] @ velocity
            dock = (f"@{target}",) if phase is Phase.CONNECT else ()
            commands[module] = ModuleCommand(joints={"roll_x": float(v[0]),
                                                     "roll_y": float(v[1])}, dock=dock)
            errors[module] = left
        return Control(commands=commands, errors=errors,
                       reached=all(e < self.arrive for e in errors.values()))

    def _blocked(self, module: str, place: np.ndarray, time: float, left: float) -> bool:
        """Whether ``module``'s approach is blocked near its end: its tracks' odometry
        ``place`` (2,) [m] has moved less than :data:`_STALL_MOVE` for :data:`_STALL_TIME`
        of driver ``time`` [s] while the way ``left`` [m] is under :data:`_STALL_NEAR`
        spacings. Its spot was laid from the map, whose estimate of the target's place
        is centimetres off under noise (1-7 cm at 2 degrees in ``forest-to-tree`` and
        ``pieces-to-tree``), so
        the spot may lie inside the target's shell or the neighbour's beside it, which
        stops the module short of it, next to its target: the push that follows goes
        straight for the target's centre and latches on touching it. Once blocked, it
        stays stopped for the rest of the approach."""
        since, where = self._still.get(module, (time, place))
        if float(np.linalg.norm(place - where)) > _STALL_MOVE:
            since, where = time, place
        self._still[module] = (since, where)
        if time - since >= _STALL_TIME and left < _STALL_NEAR * self.locator.spacing:
            self._stopped.add(module)
            return True
        return False

    def control(self, action: Action, phase: Phase, observation: Observation) -> Control:
        """One tick of ``phase`` without IK (the executor's flow contract for flows).

        * ``flow``: roll the leaf over its parent to where it touches the new parent
          (:func:`flow_direction`); reached within ``flow_tolerance``;
        * ``handover``: hold, and tell the leaf's connector to dock on the new parent and
          leave the old (the world switches both in one step);
        * ``release``/``connect``: undock or arm the links the action breaks or makes;
        * ``move``: drive every connector straight to the target (reached under
          ``tolerance`` RMS of :attr:`reach_measure`, the low-passed bends).

        Raises:
            ExecutionError: a flow whose leaf is not the owner of both links' connector.
        """
        reports = observation.sensors
        self._locate(reports)
        if (self._ways or self._pieces) and phase in (Phase.APPROACH, Phase.CONNECT):
            lone = self._travel(phase, reports, observation.time)
            pieces = self._travel_pieces(phase, reports, observation.time)
            return Control(commands={**lone.commands, **pieces.commands},
                           errors={**lone.errors, **pieces.errors},
                           reached=lone.reached and pieces.reached)
        if action.type is ActionType.FLOW and phase in (Phase.FLOW, Phase.HANDOVER):
            flow = flow_of(action)
            if flow.broken.source != flow.leaf or flow.made.source != flow.leaf:
                raise ExecutionError(f"flow {flow}: a {self.recognizer.robot} moves by its own "
                                     f"connector, but {flow.leaf} is not the source of both links")
            if phase is Phase.HANDOVER:
                return Control(commands={flow.leaf: ModuleCommand(
                    dock=(f"@{flow.new_parent}",), undock=(f"@{flow.parent}",))})
            current = self.recognizer.recognize(reports)
            w = flow_direction(current, flow.leaf, flow.parent, flow.new_parent,
                               goal_side(action.target, flow.leaf, flow.parent,
                                         flow.new_parent))
            u = -np.asarray(current.edge(_edge_id(current, flow.leaf, flow.parent)).z)
            angle = float(np.arccos(np.clip(u @ w, -1.0, 1.0)))
            heading = link_headings(reports)[1]
            command = ModuleCommand(joints=_direction(rot_z(-heading[flow.parent]) @ -w))
            return Control(commands={flow.leaf: command}, errors={flow.leaf: angle},
                           reached=angle < self.flow_tolerance)
        current = self.recognizer.recognize(reports)
        diff = topology_diff(current, action.target)
        commands: dict[str, ModuleCommand] = {}
        if phase is Phase.RELEASE:
            if not self.piece_speed:
                _refuse_carried_travel(current, action)
            commands = {c.source: ModuleCommand(undock=(f"@{c.target}",)) for c in diff.broken}
        elif phase is Phase.CONNECT:
            commands = {c.source: ModuleCommand(dock=(f"@{c.target}",)) for c in diff.made}
        reached = False
        if phase is Phase.MOVE and not diff and _only_lets_go(self._planned, action):
            return Control(reached=True)
        if phase is Phase.MOVE and not diff:
            commands = self.commands(action.target, observation, yaw=self._yaw,
                                     current=current)
            seen = self._smoothed(current) if self.bends else current
            reached = self.reach_measure(seen, action.target) < self.tolerance
        return Control(commands=commands, reached=reached)

    def _smoothed(self, current: Configuration) -> Configuration:
        """``current`` with each connection's vector low-passed over the move's ticks
        (weight ``smoothing`` on the newest, as the executor's tracking,
        :class:`~msrr.core.closed_loop.TrackingOptions`): a reading's white noise, about
        4 deg on one bend under 2 deg per reported angle, averages out of the reaching
        test, which otherwise never passes."""
        a = self.smoothing
        z = {}
        for e in current.edges():
            if e.z is None:
                continue
            old = self._seen.get(e.id)
            v = np.asarray(e.z, dtype=float) if old is None else (1 - a) * old + a * e.z
            z[e.id] = v / np.linalg.norm(v)
        self._seen = z
        return current.with_vectors(z=z)


_SAME = 1e-3
"""Two connection vectors of the plan closer than this (each component) are one."""


def _only_lets_go(before: Configuration | None, action: Action) -> bool:
    """Whether ``action`` only lets go: it breaks connections and makes none, has no pose
    goals, and every connection it keeps keeps the vector it has in ``before``, the
    plan's configuration before it (``None``: not known, the run's first action, whose
    plan may start from a recognition of where the modules were laid). Then its move
    has nothing to do: the drives already hold that shape, and re-aiming them at a target
    built from the reports' noisy angles drags the pieces resting on the floor until a
    connection breaks (pieces-to-tree under 2 degrees of noise, 5 of 5 seeds)."""
    if action.type not in (ActionType.DISCONNECTION, ActionType.PARALLEL_DISCONNECTION) \
            or action.goals:
        return False
    if before is None:
        return True
    kept = {(e.source, e.target): e.z for e in before.edges()}
    for e in action.target.edges():
        z = kept.get((e.source, e.target))
        if z is None or e.z is None or not np.allclose(z, e.z, atol=_SAME):
            return False
    return True


def _refuse_carried_travel(current: Configuration, action: Action) -> None:
    """Refuse, before anything is released, an action whose module must travel over the
    floor to its new parent while others sit on it: a group has no floor locomotion (one
    module's drive cannot drag the others' floor friction).

    Raises:
        ExecutionError: naming the module, its target and what it carries.
    """
    diff = topology_diff(current, action.target)
    after = current.copy()
    for change in diff.broken:
        after.disconnect(_edge_id(after, change.source, change.target))
    on: dict[str, list[str]] = {}
    for e in after.edges():
        on.setdefault(e.target, []).append(e.source)
    for change in diff.made:
        module = change.source
        seen, todo = {module}, list(on.get(module, ()))
        while todo:   # its in-tree: whatever sits on it, directly or not (cycles too)
            m = todo.pop()
            if m not in seen:
                seen.add(m)
                todo.extend(on.get(m, ()))
        carried = sorted(seen - {module})
        if carried and not _joined(after, module, change.target):
            raise ExecutionError(
                f"module {module} is to dock on {change.target} over the floor but carries "
                f"{len(carried)} module(s) ({', '.join(carried[:3])}"
                f"{', ...' if len(carried) > 3 else ''}): only a module alone travels over "
                "the floor")


_STALL_TIME = 1.0            # a lone module still this long [s] ...
_STALL_MOVE = 0.002          # ... moving less than this [m] ...
_STALL_NEAR = 1.0            # ... within this many spacings of its way's end is blocked
_SWING_LOOK = 0.5            # a latched piece's turn read this long [s] before a swing
_SWING_SMOOTHING = 0.2       # its low-pass, the newest tick's weight
_SWING_GAIN = 0.5            # its swing per turn error [1/s]
_SWING_RATE = 0.05           # its fastest swing [rad/s]
_SWING_DONE = np.radians(0.75)   # the turn under which its swing is done
_SWING_TIME = 15.0           # the longest swing [s]
_SWING_WEIGHT = 4.0          # a swinging piece's turn in the reach measure: under 3 deg at
                             # _SWING_DONE, the executor's reach tolerance
_YAW_GAIN = 1.0              # a travelling piece's turn per heading error [1/s]
_YAW_DONE = np.radians(1.0)  # heading error under which its turn in place is done
_AIM = np.radians(1.0)       # a straight piece's line this far off its drive's bearing re-aims
_AIM_DONE = np.radians(0.25)  # ... in place, until within this
_AIM_NEAR = 0.1              # ... while farther than this from the drive's end [m]
_AIM_RATE = 0.03             # its slowest turn [rad/s] (0.17 deg a tick: a re-aim in under a second)
_AIM_SMOOTHING = 0.1         # the angle's low-pass, the newest tick's weight
_STEER_GAIN = 10.0           # a straight piece's steer per metre off its leg's line [rad/m]
_STEER = 0.2                 # its largest steer [rad]


def _layout(config: Configuration, spacing: float) -> dict[str, np.ndarray]:
    """Centres (3,) [m] of ``config``'s modules, each connected piece from its first
    module (:func:`~msrr.core.freeform.travel.lay_out_pieces`)."""
    from .travel import lay_out_pieces

    adjacent: dict[str, list[tuple[str, np.ndarray]]] = {m: [] for m in config.modules()}
    for e in config.edges():
        if e.z is not None:
            z = np.asarray(e.z, dtype=float)
            adjacent[e.source].append((e.target, z))
            adjacent[e.target].append((e.source, -z))
    return {m: p for piece in lay_out_pieces(adjacent, sorted(adjacent), spacing)
            for m, p in piece.items()}


def _joined(config: Configuration, a: str, b: str) -> bool:
    """Whether modules ``a`` and ``b`` are in one connected group of ``config``."""
    import networkx as nx

    graph = nx.Graph()
    graph.add_nodes_from(config.modules())
    graph.add_edges_from((e.source, e.target) for e in config.edges())
    return nx.has_path(graph, a, b)


def _edge_id(config: Configuration, source: str, target: str) -> str:
    return next(e.id for e in config.edges() if e.source == source and e.target == target)
