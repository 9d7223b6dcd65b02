"""Action type of a library edge, detected from the topology diff (FreeSN paper, section 4.1).

The types are compared connector end by connector end, not by vertex id, so a free
connector renamed between two configurations is not a change:

* an end that goes from a virtual vertex to a module is a *connection*;
* an end that goes from a module to a virtual vertex is a *disconnection*;
* an end that goes from one module to another is a *flow* (the connector slides);
* an edge only in ``after`` is a connection, one only in ``before`` a disconnection.

Several connections (or disconnections) at once make a *parallel* action. One action
that both connects and disconnects different connectors is refused: record the
intermediate configuration between them (section 6.2, Fig. 14(c)).
"""

from __future__ import annotations

from dataclasses import dataclass

from ..configuration import Configuration
from ..errors import ConfigurationError
from ..plan import ActionType
from .mapping import ModuleMap, end_vertex

__all__ = ["TopologyChanges", "action_type", "topology_changes"]


@dataclass(frozen=True)
class TopologyChanges:
    """Connector ends that change between two configurations (``before`` edge ids).

    Each entry is ``(edge id, at_source)`` for one connector end.
    """

    connections: tuple[tuple[str, bool], ...] = ()
    disconnections: tuple[tuple[str, bool], ...] = ()
    flows: tuple[tuple[str, bool], ...] = ()

    def __bool__(self) -> bool:
        return bool(self.connections or self.disconnections or self.flows)


def topology_changes(before: Configuration, after: Configuration,
                     mapping: ModuleMap | None = None) -> TopologyChanges:
    """The connector-end changes from ``before`` to ``after``.

    Args:
        before: the configuration the action starts from.
        after: the configuration it reaches.
        mapping: ids of ``before`` -> ids of ``after``; identity when omitted.
    """
    mapping = mapping or ModuleMap.identity(before)
    nodes = dict(mapping.nodes)
    after_edges = set(after.edge_ids())
    connections, disconnections, flows = [], [], []
    mapped_images = set()
    for edge_id in before.edge_ids():
        image, inv = mapping.edges.get(edge_id, (edge_id, False))
        if image not in after_edges:
            disconnections.append((edge_id, True))
            continue
        mapped_images.add(image)
        for at_source in (True, False):
            old = end_vertex(before, edge_id, at_source)
            new = end_vertex(after, image, at_source != inv)
            old_free, new_free = before.is_virtual(old), after.is_virtual(new)
            if old_free and not new_free:
                connections.append((edge_id, at_source))
            elif new_free and not old_free:
                disconnections.append((edge_id, at_source))
            elif not old_free and nodes.get(old, old) != new:
                flows.append((edge_id, at_source))
    connections += [(e, True) for e in after.edge_ids() if e not in mapped_images]
    return TopologyChanges(tuple(connections), tuple(disconnections), tuple(flows))


def action_type(before: Configuration, after: Configuration,
                mapping: ModuleMap | None = None) -> ActionType:
    """The section 4.1 action type that takes ``before`` to ``after``.

    Raises:
        ConfigurationError: the step both connects and disconnects different connectors.
    """
    changes = topology_changes(before, after, mapping)
    if changes.flows:
        if changes.connections or changes.disconnections:
            raise ConfigurationError("a flow cannot be combined with other topology changes "
                                     "in one action")
        return ActionType.FLOW
    if changes.connections and changes.disconnections:
        raise ConfigurationError("one action both connects and disconnects "
                                 f"({len(changes.connections)} connection(s), "
                                 f"{len(changes.disconnections)} disconnection(s)); record the "
                                 "intermediate configuration between them")
    if changes.connections:
        return (ActionType.CONNECTION if len(changes.connections) == 1
                else ActionType.PARALLEL_CONNECTION)
    if changes.disconnections:
        return (ActionType.DISCONNECTION if len(changes.disconnections) == 1
                else ActionType.PARALLEL_DISCONNECTION)
    return ActionType.MOVING
