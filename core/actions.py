"""Topology diff and action classification: the one place both are defined.

FreeSN paper, section 4.1: comparing the topology graphs of the current and the
target configuration tells the action type. No change is *moving*; one connection
made is a *connection* ("a node and a virtual node are merged"), one broken a
*disconnection*; a leaf module that leaves its parent for one of the parent's
neighbours is a *flow* ("the disconnection and connection happen simultaneously";
:func:`flow_move` states the rule); several changes at once are a *parallel*
connection or disconnection.

Connections are compared by their ends, ``(module, port)`` pairs, regardless of
edge direction and id, so a recognized configuration compares equal to a planned
one with the same physical links. A connection that is itself a module (a FreeSN
strut) is compared end by end instead: each strut end resting on a module is one
link ``{(strut, end), (module, port)}``. An end at a virtual vertex (a free
connector) is no link, so renaming a free connector is no change, a strut whose free
end docks is one connection, and an end that moves from one node to another is a flow.

Breaking and making different connections in one step (say the face swap a-b, c-d
-> a-d, c-b) is a **parallel connection**. The paper's parallel action covers it
word for word: "the topological changes are classified into connections and
disconnections. First, the disconnection commands are sent ... After all
topological disconnection changes are detected, the system moves to the target
configuration without connections. The connection commands are sent ..." (section
4.1, Parallel Connection and Disconnection Action); the executor runs exactly these
phases (release, approach, connect). It is not a flow, which moves one leaf to a
neighbour of its parent and keeps contact throughout (phases ``flow`` and
``handover``, see :mod:`msrr.core.executor`), and
MMRP's undock-then-dock (section 4.4 of the MMRP paper, Table 4) is the same order of
commands, which an MMRP planner emits as separate single actions. The type is
named after the phase that finishes the action; :attr:`TopologyDiff.broken` says
whether it releases first. (A library edge needs one topology to execute in, so the
library builder asks for the intermediate configuration of such a step instead;
that is a rule of the library, not of classification.)
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from .configuration import Configuration
from .errors import PlanningError
from .mapping import ModuleMap, free_vertex_name
from .plan import (
    STRUT_ENDS,
    Action,
    ActionType,
    ConnectionChange,
    ConnectionKey,
    connection_key,
)
from .plan import links as _links

__all__ = [
    "STRUT_ENDS",
    "Flow",
    "TopologyDiff",
    "classify",
    "connection_key",
    "detect_action",
    "detect_actions",
    "flow_move",
    "flow_of",
    "topology_diff",
]

@dataclass(frozen=True)
class TopologyDiff:
    """Connections made and broken going from one configuration to another.

    Attributes:
        made: connections present in the target only (as the target names them).
        broken: connections present in the current configuration only (as the current
            configuration names them, or in the target's ids when a mapping was given).
    """

    made: tuple[ConnectionChange, ...]
    broken: tuple[ConnectionChange, ...]

    def __bool__(self) -> bool:
        return bool(self.made or self.broken)

    def __str__(self) -> str:
        parts = [f"+{c}" for c in self.made] + [f"-{c}" for c in self.broken]
        return " ".join(parts) or "no change"

    def changes(self) -> tuple[ConnectionChange, ...]:
        """The connections broken, then those made."""
        return self.broken + self.made

    def applied_to(self, config: Configuration, *, made: bool = True) -> Configuration:
        """``config`` without the broken connections and (if ``made``) with the made ones.

        Links are found by their direction-free keys, so ``config`` may name its
        connections differently from the configuration the diff was taken from; a
        broken link already gone and a made link already there are left alone. A strut
        end that leaves a module rests on a new virtual vertex; one that docks leaves
        its virtual vertex, which is removed when nothing else touches it.

        Raises:
            ConfigurationError: a change refers to a module ``config`` does not have.
        """
        out = config.copy()
        for change in self.broken:
            link = dict(_links(out)).get(change.key)
            if link is None:
                continue
            if _is_strut_end(change):
                _move_strut_end(out, change, None)
            else:
                out.disconnect(link.edge_id)  # type: ignore[arg-type]
        for change in self.made if made else ():
            if change.key in {key for key, _ in _links(out)}:
                continue
            if _is_strut_end(change):
                _move_strut_end(out, change, change.target)
                continue
            ports = None if change.source_port is None else (change.source_port,
                                                             change.target_port)
            free = change.edge_id is not None and change.edge_id not in out.edge_ids()
            out.connect(change.source, change.target, id=change.edge_id if free else None,
                        ports=ports)  # type: ignore[arg-type]
        return out


def _is_strut_end(change: ConnectionChange) -> bool:
    """Whether ``change`` is one end of a connection that is a module (see :func:`_links`)."""
    return change.source == change.edge_id and change.source_port in STRUT_ENDS


def _move_strut_end(config: Configuration, change: ConnectionChange, vertex: str | None
                    ) -> None:
    """Rest one end of strut ``change.source`` on ``vertex``, or on a new virtual vertex."""
    edge = config.disconnect(change.source)
    at_source = change.source_port == STRUT_ENDS[0]
    old = edge.source if at_source else edge.target
    if vertex is None:
        vertex = free_vertex_name(edge.id, at_source, set(config.vertices()))
        config.add_virtual(vertex)
    ports = None
    if edge.ports is not None or change.target_port is not None:
        ports = list(edge.ports or ("", ""))
        ports[0 if at_source else 1] = change.target_port or ""
    source, target = (vertex, edge.target) if at_source else (edge.source, vertex)
    config.connect(source, target, id=edge.id, kind=edge.kind, z=edge.z, x=edge.x,
                   ports=None if ports is None else (ports[0], ports[1]))
    if config.is_virtual(old) and config.degree(old) == 0:
        config.remove_module(old)


def topology_diff(current: Configuration, target: Configuration,
                  mapping: ModuleMap | None = None) -> TopologyDiff:
    """What connections must be made and broken to turn ``current`` into ``target``.

    Args:
        current: the configuration the step starts from.
        target: the configuration it reaches.
        mapping: ids of ``current`` -> ids of ``target`` (a library edge's module map);
            the same ids on both sides when omitted. With a mapping, ``current`` is
            first expressed in ``target``'s ids (:meth:`ModuleMap.apply`).

    Raises:
        ConfigurationError: ``mapping`` misses a module of ``current``.
    """
    if mapping is not None:
        current = mapping.apply(current)[0]
    have, want = _links(current), _links(target)
    have_keys, want_keys = Counter(k for k, _ in have), Counter(k for k, _ in want)
    return TopologyDiff(_pick(want, want_keys - have_keys), _pick(have, have_keys - want_keys))


def _pick(links: Iterable[tuple[ConnectionKey, ConnectionChange]], surplus: Counter[ConnectionKey]
          ) -> tuple[ConnectionChange, ...]:
    left = Counter(surplus)
    picked = []
    for key, change in links:
        if left[key] > 0:
            left[key] -= 1
            picked.append(change)
    return tuple(picked)


@dataclass(frozen=True)
class Flow:
    """The one move of a flow action: ``leaf`` leaves ``parent`` for ``new_parent``.

    Attributes:
        leaf: the module that moves (a leaf: its one link is ``broken``).
        parent: the module it leaves.
        new_parent: the module it goes to, a neighbour of ``parent``.
        broken: the link ``leaf``-``parent`` (with its ports), broken by the flow.
        made: the link ``leaf``-``new_parent`` (with its ports), made by the flow.
    """

    leaf: str
    parent: str
    new_parent: str
    broken: ConnectionChange
    made: ConnectionChange

    def port(self, change: ConnectionChange, module: str) -> str | None:
        """``module``'s port in ``change`` (``None``: a freeform contact)."""
        return change.source_port if change.source == module else change.target_port

    def __str__(self) -> str:
        return f"{self.leaf}: {self.parent} -> {self.new_parent}"


def _flow(broken: ConnectionChange, made: ConnectionChange) -> Flow | None:
    """The :class:`Flow` of one broken and one made link sharing exactly one module."""
    mover = {made.source, made.target} & {broken.source, broken.target}
    if len(mover) != 1:
        return None
    (leaf,) = mover
    parent = broken.target if broken.source == leaf else broken.source
    new_parent = made.target if made.source == leaf else made.source
    return Flow(leaf, parent, new_parent, broken, made)


def flow_move(current: Configuration, diff: TopologyDiff) -> Flow | None:
    """The flow that ``diff`` is, if it is one (FreeSN paper, section 4.1).

    Section 4.1: "The leaf module [...] can move from its parent module to the
    neighbors of the parent module directly. The disconnection and connection happen
    simultaneously." Read on the *link graph* of :func:`msrr.core.plan.links` (a vertex
    per module, edge modules such as FreeSN struts included; an edge per physical link,
    free connectors excluded), ``diff`` is a flow when

    * it breaks exactly one link ``{L, P}`` and makes exactly one link ``{L, Q}``, the
      two sharing exactly one module ``L`` (so ``Q != P``; a change of ports between
      the same two modules is no flow);
    * ``L`` is a *leaf*: ``{L, P}`` is its only link in ``current`` (so ``{L, Q}`` is
      its only one in the target);
    * ``Q`` is a *neighbour of the parent*: ``P`` and ``Q`` share a link in ``current``
      (the same link is in the target, as only ``L``'s link changes).

    Links are compared by their ends, so the direction of either connection and the
    ports ``L`` uses do not matter. A FreeSN strut end never flows: nodes are joined
    through struts, never directly, so no two nodes are neighbours.
    """
    if len(diff.made) != 1 or len(diff.broken) != 1:
        return None
    flow = _flow(diff.broken[0], diff.made[0])
    if flow is None:
        return None
    graph: dict[str, set[str]] = {}
    for _, link in _links(current):
        graph.setdefault(link.source, set()).add(link.target)
        graph.setdefault(link.target, set()).add(link.source)
    degree = sum(1 for _, link in _links(current) if flow.leaf in (link.source, link.target))
    if degree != 1 or flow.new_parent not in graph.get(flow.parent, set()):
        return None
    return flow


def flow_of(action: Action) -> Flow:
    """The move of a flow ``action`` (what a controller executing it needs).

    Raises:
        PlanningError: ``action`` is not one broken and one made link of one module.
    """
    broken, made = action.broken(), action.made()
    flow = _flow(broken[0], made[0]) if len(broken) == 1 and len(made) == 1 else None
    if flow is None:
        raise PlanningError(f"{action} is not a flow: a flow breaks one link and makes one, "
                            "both of the same module")
    return flow


def _classify(current: Configuration, diff: TopologyDiff) -> ActionType:
    if not diff:
        return ActionType.MOVING
    if flow_move(current, diff) is not None:
        return ActionType.FLOW
    if not diff.made:
        return (ActionType.DISCONNECTION if len(diff.broken) == 1
                else ActionType.PARALLEL_DISCONNECTION)
    if not diff.broken and len(diff.made) == 1:
        return ActionType.CONNECTION
    return ActionType.PARALLEL_CONNECTION


def classify(current: Configuration, target: Configuration,
             mapping: ModuleMap | None = None) -> ActionType:
    """The section 4.1 action type that takes ``current`` to ``target``.

    Args:
        current: the configuration the step starts from.
        target: the configuration it reaches.
        mapping: ids of ``current`` -> ids of ``target``; the same ids when omitted.

    Raises:
        ConfigurationError: ``mapping`` misses a module of ``current``.
    """
    if mapping is not None:
        current = mapping.apply(current)[0]
    return _classify(current, topology_diff(current, target))


def detect_action(current: Configuration, target: Configuration, *,
                  mapping: ModuleMap | None = None, note: str = "") -> Action:
    """The :class:`Action` that takes ``current`` to ``target``.

    ``changes`` lists the connections broken, then those made; ``modules`` every
    module whose connections change. With a ``mapping`` (ids of ``current`` -> ids of
    ``target``) everything is named in ``target``'s ids.

    Raises:
        PlanningError: the two configurations do not have the same modules.
    """
    if mapping is not None:
        current = mapping.apply(current)[0]
    if set(current.modules()) != set(target.modules()):
        raise PlanningError(f"cannot detect an action between {current.name or 'current'} and "
                            f"{target.name or 'target'}: their modules differ")
    diff = topology_diff(current, target)
    changes = diff.changes()
    modules = tuple(dict.fromkeys(m for c in changes for m in (c.source, c.target)))
    return Action(type=_classify(current, diff), target=target.copy(), modules=modules,
                  changes=changes, note=note)


def detect_actions(sequence: Sequence[Configuration]) -> list[Action]:
    """One action per consecutive pair of a configuration sequence."""
    return [detect_action(a, b) for a, b in zip(sequence, sequence[1:], strict=False)]
