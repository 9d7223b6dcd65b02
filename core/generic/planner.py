"""The generic reconfiguration planner: the fewest dock and undock actions, exactly.

Any robot gets it from its description alone (module kinds, ports, docking rules),
like the ``bfs``/``astar`` baseline RoFI ships for its own modules. A configuration
is the set of its links (:func:`msrr.core.actions.topology_diff`'s direction-free
``(module, port)`` pairs); one action docks or undocks one link. The planner finds a
shortest sequence by A* with ``h = |links(state) xor links(goal)|``: every action
changes one link, so ``h`` never overestimates and is consistent, and the first goal
popped is optimal (Hart, Nilsson and Raphael 1968). A goal with the start's links whose
connection vectors differ (a shape reached by joint angles) is one moving action to it.
Moving the modules into place for a dock is the controller's job (:class:`~msrr.core.generic.controller.LatchController`);
the plan says only which links change.

**Legality.** A step is legal when every intermediate configuration is: each of its
connected groups (a physically separate robot after an undock) passes the robot's
structural check and docking rules (:meth:`msrr.core.robot.Robot.violations`). A robot
whose rules want one connected system at all times says so in its defaults
(``RobotDefaults(stay_connected=True)``); then intermediate configurations must also be connected. A
port carries one link at a time. Legality is checked lazily, when A* pops a state, so
only states on the optimal frontier are built.

**Candidate docks.** Every pair of free ports of two different modules whose port
pair ``ports_compatible`` accepts (in either direction), plus every link of the goal.
Connections without ports (freeform connectors) can only be docked as the goal has
them (their vector ``z`` is not a discrete choice).

**Module identity.** The goal's module ids are the system's ids: this baseline does
not relabel (modules of a kind are not treated as interchangeable). A goal with other
ids is refused; a robot's own planner (MMRP's MCS hybrid, MISO) finds mappings.

**Size limit.** At most :data:`MAX_MODULES` modules and :data:`MAX_PORTS` ports, and
:data:`MAX_EXPANSIONS` states popped; beyond either a :class:`PlanningError` says so.
The search space grows as the number of link subsets. ``benchmarks/generic_planner.py``
(seed 0, 5 pairs per size) measured: when undocking and docking the differing links is
legal, A* walks straight to the goal (12 MMRP modules, 48 ports: 51 ms median, 136 ms
worst); when every intermediate must stay connected (temporary docks needed), 10
modules take 269 ms median and 1.8 s worst (172 states), 12 modules 0.6 s median --
about 10 ms per state explored, so the expansion limit stops a hopeless search after
roughly 20 s.
"""

from __future__ import annotations

import heapq
import itertools
import time
from collections.abc import Iterable
from dataclasses import dataclass

import networkx as nx
import numpy as np

from ..actions import detect_action
from ..configuration import Configuration
from ..errors import PlanningError
from ..plan import Action, ConnectionKey, Plan, connection_key
from ..robot import Robot

__all__ = ["MAX_EXPANSIONS", "MAX_MODULES", "MAX_PORTS", "GenericPlanner", "Link",
           "links_of", "state_configuration"]

MAX_MODULES = 12
"""Most modules the generic planner accepts."""

MAX_PORTS = 48
"""Most ports (over all modules) the generic planner accepts."""

MAX_EXPANSIONS = 2_000
"""Most configurations A* pops before giving up with a :class:`PlanningError`."""


@dataclass(frozen=True)
class Link:
    """One connection as a plan builds it: ends, ports, vectors and (optional) edge id."""

    source: str
    target: str
    source_port: str | None = None
    target_port: str | None = None
    z: tuple[float, float, float] | None = None
    x: tuple[float, float, float] | None = None
    edge_id: str | None = None

    @property
    def key(self) -> ConnectionKey:
        return connection_key(self.source, self.target, self.source_port, self.target_port)


def _vector(v: Iterable[float] | None) -> tuple[float, float, float] | None:
    return None if v is None else tuple(float(c) for c in v)  # type: ignore[return-value]


def links_of(config: Configuration) -> dict[ConnectionKey, Link]:
    """The links of ``config`` (vertex modules only) by their direction-free key."""
    return {connection_key(e.source, e.target, *(e.ports or (None, None))):
            Link(e.source, e.target, *(e.ports or (None, None)), _vector(e.z), _vector(e.x), e.id)
            for e in config.edges()}


def state_configuration(template: Configuration, links: Iterable[Link], *,
                        name: str = "") -> Configuration:
    """``template``'s modules (ids, kinds, positions) joined by ``links``, in order.

    A link keeps its edge id unless an earlier link took it.
    """
    out = Configuration(template.robot, name=name)
    for v in template.vertices():
        out.add_module(v, template.kind_of(v), position=template.position(v))
    for link in links:
        free = link.edge_id is not None and link.edge_id not in out.edge_ids()
        ports = None if link.source_port is None else (link.source_port, link.target_port)
        out.connect(link.source, link.target, id=link.edge_id if free else None,
                    z=link.z, x=link.x, ports=ports)  # type: ignore[arg-type]
    return out


class GenericPlanner:
    """Exact A* over dock/undock actions for any robot (see the module docstring).

    Args:
        robot: the robot (spec and docking rules) the configurations belong to.
        max_modules: size limit on modules.
        max_ports: size limit on ports over all modules.
        max_expansions: states A* may pop before it gives up.
    """

    name = "generic"
    description = "exact A* over dock/undock steps (generic runtime, small systems)"
    generic = True

    def __init__(self, robot: Robot, *, max_modules: int = MAX_MODULES,
                 max_ports: int = MAX_PORTS, max_expansions: int = MAX_EXPANSIONS):
        self.robot = robot
        self.max_modules = max_modules
        self.max_ports = max_ports
        self.max_expansions = max_expansions

    # -- public -------------------------------------------------------------------------

    def plan(self, start: Configuration, goal: Configuration, *, seed: int = 0) -> Plan:
        """The fewest dock/undock actions from ``start`` to ``goal`` (same module ids).

        Raises:
            PlanningError: the modules differ, the robot's connections are modules
                (FreeSN struts) and the topology changes, the system is beyond the size
                limit, or no legal sequence exists (or none within ``max_expansions``).
        """
        began = time.perf_counter()
        self._check_modules(start, goal)
        have, want = links_of(start), links_of(goal)
        if have.keys() == want.keys():
            bend = [] if not _bent(have, want) else [detect_action(
                start, goal.derive(), note="move: the goal differs in shape only (joint angles)")]
            return Plan(self.robot.name, self.name, start, goal, bend,
                        stats={"expanded": 0, "time_ms": 0.0})
        self._check_plannable(start, goal)
        path, expanded = self._search(start, have, want)
        actions = self._actions(start, goal, have, want, path)
        return Plan(self.robot.name, self.name, start, goal, actions,
                    notes=["generic planner: exact A* over dock/undock steps, goal ids kept"],
                    stats={"expanded": float(expanded),
                           "time_ms": (time.perf_counter() - began) * 1e3})

    # -- checks -------------------------------------------------------------------------

    def _check_modules(self, start: Configuration, goal: Configuration) -> None:
        for config, what in ((start, "start"), (goal, "goal")):
            if config.robot != self.robot.name:
                raise PlanningError(f"the {what} is a {config.robot!r} configuration, not "
                                    f"{self.robot.name!r}")
        if start.modules() != goal.modules():
            raise PlanningError(
                "the generic planner keeps module ids (no relabelling): the goal's modules "
                f"{sorted(goal.modules())} are not the start's {sorted(start.modules())}")

    def _check_plannable(self, start: Configuration, goal: Configuration) -> None:
        if self.robot.spec.kinds_with_role("edge") or any(
                c.is_virtual(v) for c in (start, goal) for v in c.vertices()):
            raise PlanningError(f"the generic planner docks vertex modules only; robot "
                                f"{self.robot.name!r} has connections that are modules or free "
                                "connectors (register a planner of its own)")
        n = len(start.vertices())
        ports = sum(len(self.robot.spec.kind(start.kind_of(v)).ports) for v in start.vertices())
        if n > self.max_modules or ports > self.max_ports:
            raise PlanningError(f"{n} modules with {ports} ports is beyond the generic planner's "
                                f"limit ({self.max_modules} modules, {self.max_ports} ports)")

    # -- search -------------------------------------------------------------------------

    def _candidates(self, start: Configuration, want: dict[ConnectionKey, Link]
                    ) -> dict[ConnectionKey, Link]:
        """Every link a dock may make: compatible free-port pairs and the goal's links."""
        found: dict[ConnectionKey, Link] = {}
        ends = [(v, p.name) for v in start.vertices()
                for p in self.robot.spec.kind(start.kind_of(v)).ports]
        rules = self.robot.rules
        for (a, pa), (b, pb) in itertools.combinations(ends, 2):
            if a == b:
                continue
            for (s, ps), (t, pt) in (((a, pa), (b, pb)), ((b, pb), (a, pa))):
                if rules.ports_compatible(start.kind_of(s), ps, start.kind_of(t), pt):
                    found[connection_key(s, t, ps, pt)] = Link(s, t, ps, pt)
                    break
        found.update(want)
        return dict(sorted(found.items(), key=lambda item: _order(item[0])))

    def _legal(self, start: Configuration, links: list[Link]) -> bool:
        config = state_configuration(start, links)
        if self.robot.spec.defaults.stay_connected and not config.is_connected():
            return False
        for group in _groups(config):
            part = state_configuration(_only(start, group),
                                       [lk for lk in links if lk.source in group])
            if self.robot.violations(part):
                return False
        return True

    def _search(self, start: Configuration, have: dict[ConnectionKey, Link],
                want: dict[ConnectionKey, Link]) -> tuple[list[frozenset], int]:
        candidates = self._candidates(start, want)
        info = {**candidates, **have}
        goal = frozenset(want)
        first = frozenset(have)
        if not self._legal(start, [info[k] for k in first]):
            raise PlanningError("the start is illegal once split into its connected groups")
        order = itertools.count()
        best: dict[frozenset, int] = {first: 0}
        parent: dict[frozenset, frozenset | None] = {first: None}
        heap = [(len(first ^ goal), 0, next(order), first)]
        closed: set[frozenset] = set()
        expanded = 0
        while heap:
            _, neg_g, _, state = heapq.heappop(heap)
            if state in closed or -neg_g > best.get(state, 1 << 30):
                continue
            closed.add(state)
            if state != first and not self._legal(start, [info[k] for k in sorted(
                    state, key=_order)]):
                continue
            if state == goal:
                path = [state]
                while (previous := parent[path[-1]]) is not None:
                    path.append(previous)
                return path[::-1], expanded
            expanded += 1
            if expanded > self.max_expansions:
                raise PlanningError(
                    f"the generic planner explored {self.max_expansions} configurations "
                    "without reaching the goal (beyond its limit; register a planner of its own)")
            used = {end for key in state for end in key if end[1] is not None}
            g = -neg_g + 1
            for key in itertools.chain(sorted(state, key=_order),
                                       (k for k in candidates if k not in state
                                        and not any(e in used for e in k))):
                child = state ^ {key}
                if child in closed or g >= best.get(child, 1 << 30):
                    continue
                best[child] = g
                parent[child] = state
                heapq.heappush(heap, (g + len(child ^ goal), -g, next(order), child))
        raise PlanningError("no sequence of legal dock and undock steps reaches the goal "
                            "(every intermediate group must satisfy the docking rules)")

    def _actions(self, start: Configuration, goal: Configuration,
                 have: dict[ConnectionKey, Link], want: dict[ConnectionKey, Link],
                 path: list[frozenset]) -> list[Action]:
        info = {**self._candidates(start, want), **have}
        current = start
        actions = []
        for before, after in itertools.pairwise(path):
            if after == path[-1]:
                nxt = goal.derive()
            else:
                kept = [lk for lk in links_of(current).values() if lk.key in after]
                added = [info[k] for k in after - before]
                nxt = state_configuration(start, kept + added, name=goal.name)
            (key,) = before ^ after
            verb = "undock" if key in before else "dock"
            link = info[key]
            actions.append(detect_action(current, nxt, note=f"{verb} {link.source}"
                                         f"{link.source_port or ''}-{link.target}"
                                         f"{link.target_port or ''}"))
            current = nxt
        return actions


def _bent(have: dict[ConnectionKey, Link], want: dict[ConnectionKey, Link]) -> bool:
    """Whether a link of ``want`` points another way (``z`` or ``x``, direction-free)
    than the same link of ``have``: the goal differs in shape (joint angles)."""
    for key, goal in want.items():
        now = have[key]
        sign = 1.0 if (now.source, now.source_port) == (goal.source, goal.source_port) else -1.0
        for a, b, flip in ((now.z, goal.z, sign), (now.x, goal.x, 1.0)):
            if b is not None and (a is None or not np.allclose(np.multiply(a, flip), b,
                                                               atol=1e-6)):
                return True
    return False


def _order(key: ConnectionKey) -> list[str]:
    """A total order on link keys (ports may be ``None``): their ends as text, sorted."""
    return sorted(str(end) for end in key)


def _groups(config: Configuration) -> list[set[str]]:
    """Vertex sets of the connected groups, in vertex order of their first member."""
    return sorted((set(c) for c in nx.weakly_connected_components(config.graph)),
                  key=lambda c: min(config.vertices().index(v) for v in c))


def _only(config: Configuration, vertices: set[str]) -> Configuration:
    out = Configuration(config.robot, name=config.name)
    for v in config.vertices():
        if v in vertices:
            out.add_module(v, config.kind_of(v), position=config.position(v))
    return out
