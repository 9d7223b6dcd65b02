"""The configuration: one object that travels from recognition to execution.

A :class:`Configuration` wraps a networkx ``MultiDiGraph``. Vertices are modules
(for FreeSN, node modules) and *virtual* vertices that stand for free connectors;
edges are connections (for FreeSN, strut modules). Every edge has a unique id (the
multigraph key) and carries:

* ``z`` -- the connection direction vector, unit, in the root horizontal frame,
  numpy float64 of shape (3,), or ``None`` where the robot derives it (MMRP faces);
* ``x`` -- the optional forward direction vector, same frame and shape;
* ``ports`` -- the optional discrete ports ``(source_port, target_port)``;
* ``kind`` -- the module kind when the edge *is* a module (a FreeSN strut).

The *skeletal* view keeps ``z`` only, the *morphology* view ``z`` and ``x``
(FreeSN paper, section 3.1). The :class:`Signature` (module counts per kind and
ordered degrees) indexes the library and rejects non-isomorphic pairs early.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import networkx as nx
import numpy as np

from .errors import ConfigurationError

if TYPE_CHECKING:
    from .robot import RobotSpec

__all__ = ["VIRTUAL", "Configuration", "Edge", "Signature", "unit"]

VIRTUAL = "virtual"
"""Kind of the vertices that stand for free connectors (FreeSN paper, Fig. 4)."""

UNIT_TOLERANCE = 1e-6


def unit(vector: Iterable[float], *, what: str = "vector") -> np.ndarray:
    """``vector`` as a float64 array of shape (3,), checked to be unit length.

    Raises:
        ConfigurationError: wrong shape, non-finite, or norm off 1 by more than 1e-6.
    """
    array = np.asarray(vector, dtype=np.float64)
    if array.shape != (3,) or not np.all(np.isfinite(array)):
        raise ConfigurationError(f"{what} must be 3 finite numbers, got {array.tolist()}")
    norm = float(np.linalg.norm(array))
    if abs(norm - 1.0) > UNIT_TOLERANCE:
        raise ConfigurationError(f"{what} must be a unit vector, its norm is {norm:.6g}")
    return array


@dataclass(frozen=True)
class Edge:
    """A read-only view of one connection of a :class:`Configuration`."""

    id: str
    source: str
    target: str
    kind: str | None
    z: np.ndarray | None
    x: np.ndarray | None
    ports: tuple[str, str] | None


@dataclass(frozen=True, order=True)
class Signature:
    """Module counts per kind and ordered degree sequence per vertex kind.

    Two configurations can only be isomorphic if their signatures are equal
    (FreeSN paper, Alg. 2 lines 1-3).

    Attributes:
        counts: ``(kind, count)`` pairs sorted by kind; virtual vertices excluded.
        degrees: ``(vertex kind, degrees sorted descending)`` pairs sorted by kind,
            virtual vertices included (their degree is part of the shape).
    """

    counts: tuple[tuple[str, int], ...]
    degrees: tuple[tuple[str, tuple[int, ...]], ...]

    def count(self, kind: str) -> int:
        return dict(self.counts).get(kind, 0)

    def label(self, spec: RobotSpec) -> str:
        """Sub-library name such as ``S6N3``: symbol and count per kind, in the spec's order."""
        return "".join(f"{k.symbol}{self.count(k.name)}" for k in spec.module_kinds
                       if self.count(k.name))


class Configuration:
    """A robot configuration in its own module ids.

    Args:
        robot: name of the robot this configuration belongs to.
        name: optional human-readable name (``"cross"``).
        description: optional one-line description.

    Build with :meth:`add_module`, :meth:`add_virtual` and :meth:`connect`, or read a
    file with :func:`msrr.core.io.load_configuration`.
    """

    def __init__(self, robot: str, *, name: str = "", description: str = ""):
        self.robot = robot
        self.name = name
        self.description = description
        self.graph: nx.MultiDiGraph = nx.MultiDiGraph()
        self._edge_ends: dict[str, tuple[str, str]] = {}

    # -- building -------------------------------------------------------------------

    def add_module(self, module_id: str, kind: str, *, position: Iterable[float] | None = None
                   ) -> None:
        """Add a vertex module of ``kind``; ``position`` [m], shape (3,), is optional."""
        module_id = str(module_id)
        if module_id in self.graph or module_id in self._edge_ends:
            raise ConfigurationError(f"duplicate module id {module_id!r}")
        pos = None if position is None else np.asarray(position, dtype=np.float64).reshape(3)
        self.graph.add_node(module_id, kind=kind, position=pos)

    def add_virtual(self, vertex_id: str) -> None:
        """Add a virtual vertex that stands for a free connector."""
        self.add_module(vertex_id, VIRTUAL)

    def connect(self, source: str, target: str, *, id: str | None = None,
                kind: str | None = None, z: Iterable[float] | None = None,
                x: Iterable[float] | None = None,
                ports: tuple[str, str] | None = None) -> str:
        """Add a connection from ``source`` to ``target`` and return its id.

        Args:
            source: the vertex the connection leaves (parent, or connector owner).
            target: the vertex it reaches.
            id: unique edge id; generated from the ends (and ports) when omitted.
            kind: module kind when the edge is a module (FreeSN ``"strut"``).
            z: unit connection direction vector, shape (3,).
            x: unit forward direction vector, shape (3,).
            ports: discrete ports ``(source_port, target_port)``.
        """
        source, target = str(source), str(target)
        for end in (source, target):
            if end not in self.graph:
                raise ConfigurationError(f"connection end {end!r} is not a module of this "
                                         "configuration")
        if source == target:
            raise ConfigurationError(f"module {source!r} cannot connect to itself")
        edge_id = str(id) if id is not None else self._fresh_edge_id(source, target, ports)
        if edge_id in self._edge_ends or edge_id in self.graph:
            raise ConfigurationError(f"duplicate connection id {edge_id!r}")
        self.graph.add_edge(
            source, target, key=edge_id, kind=kind,
            z=None if z is None else unit(z, what="z"),
            x=None if x is None else unit(x, what="x"),
            ports=None if ports is None else (str(ports[0]), str(ports[1])),
        )
        self._edge_ends[edge_id] = (source, target)
        return edge_id

    def disconnect(self, edge_id: str) -> Edge:
        """Remove a connection and return it as it was."""
        edge = self.edge(edge_id)
        self.graph.remove_edge(edge.source, edge.target, key=edge_id)
        del self._edge_ends[edge_id]
        return edge

    def remove_module(self, module_id: str) -> None:
        """Remove a vertex and every connection that touches it."""
        for edge in self.incident(module_id):
            del self._edge_ends[edge.id]
        self.graph.remove_node(module_id)

    def _fresh_edge_id(self, source: str, target: str, ports: tuple[str, str] | None) -> str:
        base = (f"{source}{ports[0]}-{target}{ports[1]}" if ports else f"{source}-{target}")
        candidate, n = base, 1
        while candidate in self._edge_ends:
            n += 1
            candidate = f"{base}#{n}"
        return candidate

    # -- reading --------------------------------------------------------------------

    def vertices(self, *, virtual: bool = True) -> list[str]:
        """Vertex ids in insertion order, virtual ones included unless ``virtual=False``."""
        return [v for v, kind in self.graph.nodes(data="kind") if virtual or kind != VIRTUAL]

    def kind_of(self, vertex: str) -> str:
        """Kind of vertex ``vertex``."""
        try:
            return self.graph.nodes[vertex]["kind"]
        except KeyError:
            raise ConfigurationError(f"no module {vertex!r} in this configuration") from None

    def is_virtual(self, vertex: str) -> bool:
        return self.kind_of(vertex) == VIRTUAL

    def position(self, vertex: str) -> np.ndarray | None:
        return self.graph.nodes[vertex]["position"]

    def edges(self) -> list[Edge]:
        """All connections, in insertion order."""
        return [self.edge(edge_id) for edge_id in self._edge_ends]

    def edge(self, edge_id: str) -> Edge:
        """The connection with id ``edge_id``."""
        try:
            source, target = self._edge_ends[edge_id]
        except KeyError:
            raise ConfigurationError(f"no connection {edge_id!r} in this configuration") from None
        data = self.graph.edges[source, target, edge_id]
        return Edge(edge_id, source, target, data["kind"], data["z"], data["x"], data["ports"])

    def edge_ids(self) -> list[str]:
        return list(self._edge_ends)

    def incident(self, vertex: str) -> list[Edge]:
        """Connections that touch ``vertex``, outgoing first."""
        out = [self.edge(k) for _, _, k in self.graph.out_edges(vertex, keys=True)]
        return out + [self.edge(k) for _, _, k in self.graph.in_edges(vertex, keys=True)]

    def degree(self, vertex: str) -> int:
        return int(self.graph.degree(vertex))

    def modules(self) -> dict[str, str]:
        """Every physical module id and its kind: vertex modules, then edge modules."""
        found = {v: k for v, k in self.graph.nodes(data="kind") if k != VIRTUAL}
        found.update({e.id: e.kind for e in self.edges() if e.kind is not None})
        return found

    def undirected(self) -> nx.MultiGraph:
        """The topology as an undirected multigraph (keys are edge ids)."""
        return self.graph.to_undirected(as_view=False)

    def is_connected(self) -> bool:
        return len(self.graph) > 0 and nx.is_weakly_connected(self.graph)

    def signature(self) -> Signature:
        """Module counts per kind and ordered degree sequence per vertex kind."""
        counts = Counter(self.modules().values())
        degrees: dict[str, list[int]] = {}
        for vertex, kind in self.graph.nodes(data="kind"):
            degrees.setdefault(kind, []).append(self.degree(vertex))
        return Signature(
            counts=tuple(sorted(counts.items())),
            degrees=tuple(sorted((k, tuple(sorted(d, reverse=True))) for k, d in degrees.items())),
        )

    def vectors(self, edge_ids: Iterable[str] | None = None, attribute: str = "z") -> np.ndarray:
        """Stack ``z`` (or ``x``) of the given edges as columns, shape (3, n)."""
        ids = self.edge_ids() if edge_ids is None else list(edge_ids)
        columns = []
        for edge_id in ids:
            value = getattr(self.edge(edge_id), attribute)
            if value is None:
                raise ConfigurationError(f"connection {edge_id!r} has no {attribute} vector")
            columns.append(value)
        return np.array(columns, dtype=np.float64).T.reshape(3, len(columns))

    # -- derived configurations -----------------------------------------------------

    def copy(self) -> Configuration:
        """A deep copy; vectors are copied, not shared."""
        other = Configuration(self.robot, name=self.name, description=self.description)
        for vertex, data in self.graph.nodes(data=True):
            other.add_module(vertex, data["kind"], position=data["position"])
        for e in self.edges():
            other.connect(e.source, e.target, id=e.id, kind=e.kind, z=e.z, x=e.x, ports=e.ports)
        return other

    def skeletal(self) -> Configuration:
        """The skeletal view: the topology with ``z`` only (section 3.1)."""
        return self.with_vectors(x={})

    def morphology(self) -> Configuration:
        """The morphology view: the topology with ``z`` and ``x`` (a copy)."""
        return self.copy()

    def with_vectors(self, z: Mapping[str, Any] | None = None,
                     x: Mapping[str, Any] | None = None) -> Configuration:
        """A copy whose ``z``/``x`` are replaced from ``{edge id: vector}`` mappings.

        ``x={}`` drops every forward vector; an edge missing from a given mapping keeps
        ``None`` for that attribute. ``None`` for a mapping keeps the current vectors.
        """
        other = Configuration(self.robot, name=self.name, description=self.description)
        for vertex, data in self.graph.nodes(data=True):
            other.add_module(vertex, data["kind"], position=data["position"])
        for e in self.edges():
            new_z = e.z if z is None else z.get(e.id)
            new_x = e.x if x is None else x.get(e.id)
            other.connect(e.source, e.target, id=e.id, kind=e.kind, z=new_z, x=new_x,
                          ports=e.ports)
        return other

    def relabel(self, vertices: Mapping[str, str], edges: Mapping[str, str] | None = None
                ) -> Configuration:
        """A copy with vertex (and edge) ids renamed; unmapped ids stay as they are."""
        edges = edges or {}
        other = Configuration(self.robot, name=self.name, description=self.description)
        for vertex, data in self.graph.nodes(data=True):
            other.add_module(vertices.get(vertex, vertex), data["kind"], position=data["position"])
        for e in self.edges():
            other.connect(vertices.get(e.source, e.source), vertices.get(e.target, e.target),
                          id=edges.get(e.id, e.id), kind=e.kind, z=e.z, x=e.x, ports=e.ports)
        return other

    # -- comparison -----------------------------------------------------------------

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Configuration):
            return NotImplemented
        return (self.robot, self.name, self.description) == (
            other.robot, other.name, other.description
        ) and self._canonical() == other._canonical()

    def _canonical(self) -> tuple:
        def vec(v: np.ndarray | None) -> tuple | None:
            return None if v is None else tuple(float(c) for c in v)

        nodes = sorted((v, d["kind"], vec(d["position"])) for v, d in self.graph.nodes(data=True))
        edges = sorted((e.id, e.source, e.target, e.kind or "", vec(e.z), vec(e.x), e.ports)
                       for e in self.edges())
        return (tuple(nodes), tuple(edges))

    __hash__ = None  # type: ignore[assignment]  # mutable

    def __iter__(self) -> Iterator[str]:
        return iter(self.graph)

    def __len__(self) -> int:
        return len(self.graph)

    def __repr__(self) -> str:
        label = f" {self.name!r}" if self.name else ""
        return (f"<Configuration{label} robot={self.robot} vertices={len(self.graph)} "
                f"connections={len(self._edge_ends)}>")
