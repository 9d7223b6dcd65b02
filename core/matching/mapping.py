"""The result of matching two configurations: a module mapping and its distance.

A :class:`Mapping` sends every vertex of the *system* configuration to a vertex of the
*reference* configuration and every system edge to a reference edge, with an ``inv``
flag for an edge whose direction is reversed (a FreeSN strut seen from its other end:
``z -> -z``, ports swapped). It also carries the eq. 8 distance of the two
configurations under that mapping and the yaw that aligns them (FreeSN paper, Alg. 2
output ``{eps, f_node, f_edge, inv}``).

The helpers express one configuration in the other's ids, so the rest of the platform
works in a single set of module ids (DESIGN.md, section 3).
"""

from __future__ import annotations

from collections.abc import Mapping as MappingABC
from dataclasses import dataclass

import numpy as np

from ..alignment import rot_z
from ..configuration import Configuration, Edge
from ..errors import ConfigurationError

__all__ = ["EdgeImage", "Mapping"]

EdgeImage = tuple[str, bool]
"""Image of a system edge: ``(reference edge id, inv)``."""


@dataclass(frozen=True)
class Mapping:
    """An isomorphism from a system configuration onto a reference configuration.

    Attributes:
        nodes: system vertex -> reference vertex (virtual vertices included).
        edges: system edge -> ``(reference edge, inv)``; ``inv`` is true when the two
            edges point in opposite directions (Alg. 3 line 8).
        distance: eq. 8 cost at the aligned yaw: sum over edges with ``z`` on both sides
            of the squared angle [rad^2] between the system ``z`` and the rotated
            reference ``z`` (negated when ``inv``).
        yaw: ``theta`` [rad] such that ``rot_z(theta) @ z_ref`` matches ``z_sys``.
        rms_angle: root-mean-square of those angles [rad].
    """

    nodes: dict[str, str]
    edges: dict[str, EdgeImage]
    distance: float
    yaw: float = 0.0
    rms_angle: float = 0.0

    def inverse_nodes(self) -> dict[str, str]:
        """Reference vertex -> system vertex."""
        return {r: s for s, r in self.nodes.items()}

    def inverse_edges(self) -> dict[str, EdgeImage]:
        """Reference edge -> ``(system edge, inv)``."""
        return {r: (s, inv) for s, (r, inv) in self.edges.items()}

    def inverted(self) -> list[str]:
        """System edges whose reference image points the other way."""
        return [s for s, (_, inv) in self.edges.items() if inv]

    def reference_in_system_ids(self, reference: Configuration, *, rotate: bool = True
                                ) -> Configuration:
        """``reference`` renamed into system ids, each edge turned to the system's direction.

        Args:
            reference: the reference configuration this mapping points into.
            rotate: also rotate ``z``/``x`` by :attr:`yaw` into the system's horizontal frame.
        """
        rotation = rot_z(self.yaw) if rotate else np.eye(3)
        return _remap(reference, self.inverse_nodes(), self.inverse_edges(), rotation)

    def system_in_reference_ids(self, system: Configuration, *, rotate: bool = False
                                ) -> Configuration:
        """``system`` renamed into reference ids, each edge turned to the reference's direction.

        Args:
            system: the system configuration this mapping starts from.
            rotate: also rotate ``z``/``x`` by ``-yaw`` into the reference's frame (off by
                default: the inverse kinematics estimates the yaw itself).
        """
        rotation = rot_z(-self.yaw) if rotate else np.eye(3)
        return _remap(system, self.nodes, self.edges, rotation)


def _turned(edge: Edge, inv: bool, rotation: np.ndarray) -> tuple:
    """Ends, ``z``, ``x`` and ports of ``edge``, reversed when ``inv``, vectors rotated."""
    z = None if edge.z is None else rotation @ edge.z
    x = None if edge.x is None else rotation @ edge.x
    if not inv:
        return edge.source, edge.target, z, x, edge.ports
    ports = None if edge.ports is None else (edge.ports[1], edge.ports[0])
    return edge.target, edge.source, None if z is None else -z, x, ports


def _remap(config: Configuration, vertices: MappingABC[str, str],
           edges: MappingABC[str, EdgeImage], rotation: np.ndarray) -> Configuration:
    """A copy of ``config`` with ids renamed and the flagged edges reversed."""
    if set(vertices) != set(config.vertices()) or set(edges) != set(config.edge_ids()):
        raise ConfigurationError(f"the mapping does not cover configuration "
                                 f"{config.name or config.robot!r}")
    out = Configuration(config.robot, name=config.name, description=config.description)
    for vertex in config.vertices():
        out.add_module(vertices[vertex], config.kind_of(vertex), position=config.position(vertex))
    for edge in config.edges():
        new_id, inv = edges[edge.id]
        source, target, z, x, ports = _turned(edge, inv, rotation)
        out.connect(vertices[source], vertices[target], id=new_id, kind=edge.kind,
                    z=None if z is None else z / np.linalg.norm(z),
                    x=None if x is None else x / np.linalg.norm(x), ports=ports)
    return out
