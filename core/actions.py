"""Action detection from the topology difference of two configurations.

FreeSN paper, section 4.1: comparing the topology graphs of the current and the
target configuration tells the action type. No change is *moving*; one connection
made is a *connection*, one broken a *disconnection*; a leaf module that leaves its
parent for one of the parent's neighbours is a *flow*; several changes at once are
a *parallel* connection (if anything is made) or disconnection.

Connections are compared by their ends, ``(module, port)`` pairs, regardless of
edge direction and id, so a recognized configuration compares equal to a planned
one with the same physical links. A connection that is itself a module (a FreeSN
strut) is compared end by end instead: each strut end resting on a module is one
link ``{(strut, end), (module, None)}``, and a free end (a virtual vertex) is none,
so a strut whose free end docks is one connection, and an end that moves from one
node to another is a flow.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from .configuration import Configuration
from .errors import PlanningError
from .plan import Action, ActionType, ConnectionChange

__all__ = [
    "TopologyDiff",
    "classify",
    "connection_key",
    "detect_action",
    "detect_actions",
    "topology_diff",
]

End = tuple[str, str | None]
Key = frozenset[End]


def connection_key(source: str, target: str, source_port: str | None = None,
                   target_port: str | None = None) -> Key:
    """The direction-free identity of a connection: its two ``(module, port)`` ends."""
    return frozenset({(source, source_port), (target, target_port)})


STRUT_ENDS = ("a", "b")
"""Names of the source and target end of a connection that is a module."""


def _links(config: Configuration) -> list[tuple[Key, ConnectionChange]]:
    """Every physical link of ``config`` with its direction-free key."""
    links = []
    for edge in config.edges():
        ports = edge.ports or (None, None)
        if edge.kind is None:
            links.append((connection_key(edge.source, edge.target, ports[0], ports[1]),
                          ConnectionChange(edge.source, edge.target, ports[0], ports[1],
                                           edge.id)))
            continue
        for end, vertex, port in zip(STRUT_ENDS, (edge.source, edge.target), ports, strict=True):
            if not config.is_virtual(vertex):
                links.append((connection_key(edge.id, vertex, end, port),
                              ConnectionChange(edge.id, vertex, end, port, edge.id)))
    return links


def _keyed(config: Configuration) -> Counter[Key]:
    return Counter(key for key, _ in _links(config))


@dataclass(frozen=True)
class TopologyDiff:
    """Connections made and broken going from one configuration to another.

    Attributes:
        made: connections present in the target only (as the target names them).
        broken: connections present in the current configuration only.
    """

    made: tuple[ConnectionChange, ...]
    broken: tuple[ConnectionChange, ...]

    def __bool__(self) -> bool:
        return bool(self.made or self.broken)

    def __str__(self) -> str:
        parts = [f"+{c}" for c in self.made] + [f"-{c}" for c in self.broken]
        return " ".join(parts) or "no change"


def topology_diff(current: Configuration, target: Configuration) -> TopologyDiff:
    """What connections must be made and broken to turn ``current`` into ``target``."""
    have, want = _keyed(current), _keyed(target)
    made = _pick(_links(target), want - have)
    broken = _pick(_links(current), have - want)
    return TopologyDiff(made, broken)


def _pick(links: Iterable[tuple[Key, ConnectionChange]], surplus: Counter[Key]
          ) -> tuple[ConnectionChange, ...]:
    left = Counter(surplus)
    picked = []
    for key, change in links:
        if left[key] > 0:
            left[key] -= 1
            picked.append(change)
    return tuple(picked)


def _is_flow(current: Configuration, diff: TopologyDiff) -> bool:
    if len(diff.made) != 1 or len(diff.broken) != 1:
        return False
    made, broken = diff.made[0], diff.broken[0]
    if made.source_port in STRUT_ENDS and (made.source, made.source_port) == (
            broken.source, broken.source_port):
        return True  # a strut end slides from one node to another
    mover = {made.source, made.target} & {broken.source, broken.target}
    if len(mover) != 1:
        return False
    (leaf,) = mover
    old_parent = broken.target if broken.source == leaf else broken.source
    new_parent = made.target if made.source == leaf else made.source
    return (current.degree(leaf) == 1
            and current.graph.to_undirected(as_view=True).has_edge(old_parent, new_parent))


def classify(current: Configuration, target: Configuration) -> ActionType:
    """The action type that takes ``current`` to ``target`` (FreeSN section 4.1)."""
    diff = topology_diff(current, target)
    if not diff:
        return ActionType.MOVING
    if _is_flow(current, diff):
        return ActionType.FLOW
    if not diff.made:
        return (ActionType.DISCONNECTION if len(diff.broken) == 1
                else ActionType.PARALLEL_DISCONNECTION)
    if not diff.broken and len(diff.made) == 1:
        return ActionType.CONNECTION
    return ActionType.PARALLEL_CONNECTION


def detect_action(current: Configuration, target: Configuration, *, note: str = "") -> Action:
    """The :class:`Action` that takes ``current`` to ``target``.

    ``changes`` lists the connections broken, then those made; ``modules`` every
    module whose connections change.
    """
    if set(current.modules()) != set(target.modules()):
        raise PlanningError(f"cannot detect an action between {current.name or 'current'} and "
                            f"{target.name or 'target'}: their modules differ")
    diff = topology_diff(current, target)
    changes = diff.broken + diff.made
    modules = tuple(dict.fromkeys(m for c in changes for m in (c.source, c.target)))
    return Action(type=classify(current, target), target=target.copy(), modules=modules,
                  changes=changes, note=note)


def detect_actions(sequence: Sequence[Configuration]) -> list[Action]:
    """One action per consecutive pair of a configuration sequence."""
    return [detect_action(a, b) for a, b in zip(sequence, sequence[1:], strict=False)]
