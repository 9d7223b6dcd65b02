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

import math
from collections import Counter
from collections.abc import Collection, Iterable, Iterator, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import networkx as nx
import numpy as np

from .errors import ConfigurationError

if TYPE_CHECKING:
    from .robot import RobotSpec

__all__ = ["VIRTUAL", "Configuration", "Edge", "Signature", "VectorLike", "unique_id", "unit"]

VIRTUAL = "virtual"
"""Kind of the vertices that stand for free connectors (FreeSN paper, Fig. 4)."""

UNIT_TOLERANCE = 1e-6
"""Largest accepted deviation of a direction vector's norm from 1."""

VectorLike = Iterable[float]
"""Three numbers: a list, a tuple or a numpy array of shape (3,)."""


def unit(vector: VectorLike, *, what: str = "vector") -> np.ndarray:
    """``vector`` as a new read-only float64 array of shape (3,), checked to be unit length.

    The one unit-vector check of the platform (configuration files use it too).

    Raises:
        ConfigurationError: wrong shape, non-finite, or norm off 1 by more than 1e-6.
    """
    array = np.array(vector, dtype=np.float64)
    values = array.tolist()    # plain floats: the checks cost a third (every recognized link)
    if array.shape != (3,) or not all(map(math.isfinite, values)):
        raise ConfigurationError(f"{what} must be 3 finite numbers, got {values}")
    norm = math.hypot(*values)  # no overflow for huge components (1e300)
    if abs(norm - 1.0) > UNIT_TOLERANCE:
        raise ConfigurationError(f"{what} must be a unit vector, its norm is {norm:.6g}")
    array.flags.writeable = False
    return array


def _frozen_position(position: VectorLike | None) -> np.ndarray | None:
    if position is None:
        return None
    array = np.array(position, dtype=np.float64).reshape(3)
    array.flags.writeable = False
    return array


def _read_only(array: np.ndarray) -> np.ndarray:
    array.flags.writeable = False
    return array


def _close(a: tuple | None, b: tuple | None, tolerance: float) -> bool:
    """Whether two optional number tuples are both absent, or agree within ``tolerance``
    in every component."""
    if a is None or b is None:
        return a is b
    return a == b or all(abs(u - v) <= tolerance for u, v in zip(a, b, strict=True))


def _optional_unit(vector: VectorLike | None, what: str) -> np.ndarray | None:
    """``vector`` checked by :func:`unit`; a read-only unit float64 array is shared as it is."""
    if vector is None:
        return None
    if (isinstance(vector, np.ndarray) and not vector.flags.writeable
            and vector.dtype == np.float64 and vector.shape == (3,)):
        x, y, z = vector.tolist()  # the cheap path for vectors of other configurations
        if abs(x * x + y * y + z * z - 1.0) <= 2 * UNIT_TOLERANCE:
            return vector
    return unit(vector, what=what)


def _rotate(rotation: np.ndarray, edges: list[dict]) -> None:
    """Rotate ``z`` and ``x`` of every edge attribute dict in place, all in one product.

    The results are rows of one read-only array, renormalised against round-off.
    """
    slots = [(data, key) for data in edges for key in ("z", "x") if data[key] is not None]
    if not slots:
        return
    turned = np.array([data[key] for data, key in slots]) @ np.asarray(rotation).T
    turned /= np.linalg.norm(turned, axis=1, keepdims=True)
    turned.flags.writeable = False
    for (data, key), row in zip(slots, turned, strict=True):
        data[key] = row


def unique_id(base: str, taken: Collection[str]) -> str:
    """``base``, or ``base#2``, ``base#3``... the first that is not ``taken``."""
    candidate, n = base, 1
    while candidate in taken:
        n += 1
        candidate = f"{base}#{n}"
    return candidate


def _fresh_id(source: str, target: str, ports: tuple[str, str] | None,
              taken: Collection[str]) -> str:
    """An edge id made from the ends (and ports), numbered when taken."""
    return unique_id(f"{source}{ports[0]}-{target}{ports[1]}" if ports else f"{source}-{target}",
                     taken)


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
    file with :func:`msrr.core.io.load_configuration`; derive changed configurations
    with :meth:`derive`. Vectors and positions are stored as read-only arrays, so
    derived configurations share them safely.
    """

    def __init__(self, robot: str, *, name: str = "", description: str = ""):
        self.robot = robot
        self.name = name
        self.description = description
        self.graph: nx.MultiDiGraph = nx.MultiDiGraph()
        self._edge_ends: dict[str, tuple[str, str]] = {}

    # -- building -------------------------------------------------------------------

    def add_module(self, module_id: str, kind: str, *, position: VectorLike | None = None
                   ) -> None:
        """Add a vertex module of ``kind``; ``position`` [m], shape (3,), is optional."""
        module_id = str(module_id)
        if module_id in self.graph or module_id in self._edge_ends:
            raise ConfigurationError(f"duplicate module id {module_id!r}")
        self.graph.add_node(module_id, kind=kind, position=_frozen_position(position))

    def add_virtual(self, vertex_id: str) -> None:
        """Add a virtual vertex that stands for a free connector."""
        self.add_module(vertex_id, VIRTUAL)

    def connect(self, source: str, target: str, *, id: str | None = None,
                kind: str | None = None, z: VectorLike | None = None,
                x: VectorLike | None = None,
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
        return _fresh_id(source, target, ports, self._edge_ends)

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

    def derive(self, *, vertices: Mapping[str, str] | None = None,
               edges: Mapping[str, str] | None = None, reverse: Collection[str] = (),
               z: Mapping[str, VectorLike | None] | None = None,
               x: Mapping[str, VectorLike | None] | None = None,
               rotation: np.ndarray | None = None, name: str | None = None,
               description: str | None = None) -> Configuration:
        """A new configuration derived from this one, which stays unchanged.

        The one way to build a changed configuration: copies, views, relabellings,
        module mappings and vector updates all come through here. Vectors and positions
        are read-only arrays, so they are shared, not copied; only what changes is new.
        The steps, in order, all keyed by *this* configuration's ids:

        1. ``z`` / ``x`` replace vectors: ``{edge id: vector or None}``; an edge missing
           from a given mapping gets ``None`` (``x={}`` drops every forward vector),
           ``None`` for the mapping keeps the current vectors;
        2. every edge in ``reverse`` is turned around: ends and ports swapped, ``z``
           negated, ``x`` kept (the connection direction runs from source to target, the
           forward vector belongs to the module body; FreeSN paper, Alg. 3 lines 12-13);
        3. ``rotation`` (shape (3, 3), orthonormal) rotates every ``z`` and ``x``, e.g. a
           yaw (positions stay where they are);
        4. ``vertices`` / ``edges`` rename ids; unmapped ids stay as they are.

        Args:
            vertices: vertex id -> new vertex id.
            edges: edge id -> new edge id.
            reverse: edge ids to turn around.
            z: replacement connection direction vectors, unit, shape (3,).
            x: replacement forward direction vectors, unit, shape (3,).
            rotation: rotation matrix applied to every vector, shape (3, 3).
            name: the new configuration's name; this one's when omitted.
            description: its description; this one's when omitted.

        Raises:
            ConfigurationError: a replacement vector is not unit, the renaming sends two
                ids to one, or ``reverse`` names an unknown edge.
        """
        reverse = frozenset(reverse)
        if not reverse <= self._edge_ends.keys():
            unknown = sorted(reverse - self._edge_ends.keys())
            raise ConfigurationError(f"cannot reverse unknown connection(s) {unknown}")
        rename = vertices.get if vertices else None
        nodes = [(rename(v, v) if rename else v, data["kind"], data["position"])
                 for v, data in self.graph.nodes(data=True)]
        new_edges = []
        adjacency = self.graph._succ  # plain dicts: the views cost a third of a copy
        for edge_id, (source, target) in self._edge_ends.items():
            data = adjacency[source][target][edge_id]
            ez = data["z"] if z is None else _optional_unit(z.get(edge_id), f"z of {edge_id}")
            ex = data["x"] if x is None else _optional_unit(x.get(edge_id), f"x of {edge_id}")
            ports = data["ports"]
            if edge_id in reverse:
                source, target = target, source
                ports = None if ports is None else (ports[1], ports[0])
                ez = None if ez is None else _read_only(-ez)
            if rename:
                source, target = rename(source, source), rename(target, target)
            new_edges.append((edges.get(edge_id, edge_id) if edges else edge_id, source, target,
                              {"kind": data["kind"], "z": ez, "x": ex, "ports": ports}))
        if rotation is not None:
            _rotate(rotation, [data for *_, data in new_edges])
        return Configuration._assemble(
            self.robot, self.name if name is None else name,
            self.description if description is None else description, nodes, new_edges)

    @classmethod
    def union(cls, parts: Iterable[Configuration], *, robot: str, name: str = "",
              description: str = "") -> Configuration:
        """The disjoint union of ``parts`` (say, separately recognized groups).

        Edge ids are kept; one already taken by an earlier part is regenerated from its
        ends (:meth:`connect` without ``id``).

        Raises:
            ConfigurationError: two parts share a vertex id.
        """
        nodes, edges, taken = [], [], set()
        for part in parts:
            nodes += [(v, d["kind"], d["position"]) for v, d in part.graph.nodes(data=True)]
            for edge_id, (source, target) in part._edge_ends.items():
                data = part.graph._succ[source][target][edge_id]
                if edge_id in taken:
                    edge_id = _fresh_id(source, target, data["ports"], taken)
                taken.add(edge_id)
                edges.append((edge_id, source, target, dict(data)))
        return cls._assemble(robot, name, description, nodes, edges)

    @classmethod
    def _assemble(cls, robot: str, name: str, description: str,
                  nodes: list[tuple[str, str, np.ndarray | None]],
                  edges: list[tuple[str, str, str, dict]]) -> Configuration:
        """A configuration from checked parts: ``(id, kind, position)`` vertices and
        ``(id, source, target, attributes)`` edges whose vectors are read-only unit arrays."""
        out = cls(robot, name=name, description=description)
        # Filled the way MultiDiGraph.add_node/add_edge fill them (networkx >= 3.6), without
        # their per-call checks: the parts are checked here, and this is the hot path of
        # every derived configuration.
        graph = out.graph
        node, succ, pred = graph._node, graph._succ, graph._pred
        for vertex, kind, position in nodes:
            node[vertex] = {"kind": kind, "position": position}
            succ[vertex], pred[vertex] = {}, {}
        out._edge_ends = {edge_id: (source, target) for edge_id, source, target, _ in edges}
        if len(node) != len(nodes) or len(out._edge_ends) != len(edges) or (
                out._edge_ends.keys() & node.keys()):
            counts = Counter([v for v, _, _ in nodes] + [e[0] for e in edges])
            raise ConfigurationError(f"duplicate module id(s) "
                                     f"{sorted(k for k, n in counts.items() if n > 1)}")
        for edge_id, source, target, data in edges:
            if source not in node or target not in node:
                raise ConfigurationError(f"connection {edge_id!r} ends outside the configuration")
            keyed = succ[source].get(target)
            if keyed is None:
                keyed = succ[source][target] = pred[target][source] = {}
            keyed[edge_id] = data
        return out

    def copy(self) -> Configuration:
        """An equal configuration that can be changed independently (:meth:`derive`)."""
        return self.derive()

    def skeletal(self) -> Configuration:
        """The skeletal view: the topology with ``z`` only (section 3.1)."""
        return self.derive(x={})

    def morphology(self) -> Configuration:
        """The morphology view: the topology with ``z`` and ``x`` (a copy)."""
        return self.derive()

    def with_vectors(self, z: Mapping[str, VectorLike | None] | None = None,
                     x: Mapping[str, VectorLike | None] | None = None) -> Configuration:
        """Shorthand for :meth:`derive` with ``z`` and ``x`` only."""
        return self.derive(z=z, x=x)

    def relabel(self, vertices: Mapping[str, str], edges: Mapping[str, str] | None = None
                ) -> Configuration:
        """Shorthand for :meth:`derive` with ``vertices`` and ``edges`` only."""
        return self.derive(vertices=vertices, edges=edges)

    # -- comparison -----------------------------------------------------------------

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Configuration):
            return NotImplemented
        return (self.robot, self.name, self.description) == (
            other.robot, other.name, other.description
        ) and self._canonical() == other._canonical()

    def same_state(self, other: Configuration, *, tolerance: float = 0.0,
                   positions: bool = True) -> bool:
        """Whether ``other`` describes the same modules in the same state: the same ids,
        kinds and positions, and the same connections with the same vectors; only what
        labels a connection may differ (its id, and its direction when it carries no
        vectors). Numbers agree within ``tolerance`` (absolute, per component; 0: exactly,
        so a plan made from one starts from the state the other describes); without
        ``positions`` the modules' positions are left out (a recognizer that reads
        connections never sees where the lab put the modules)."""
        (nodes, edges), (other_nodes, other_edges) = (
            c._canonical(edge_labels=False, positions=positions) for c in (self, other))
        if self.robot != other.robot or len(nodes) != len(other_nodes) \
                or len(edges) != len(other_edges):
            return False
        return all(a[:-1] == b[:-1] and _close(a[-1], b[-1], tolerance)
                   for a, b in zip(nodes, other_nodes, strict=True)) \
            and all(a[:2] == b[:2] and _close(a[2], b[2], tolerance)
                    and _close(a[3], b[3], tolerance)
                    for a, b in zip(edges, other_edges, strict=True))

    def _canonical(self, *, edge_labels: bool = True, positions: bool = True) -> tuple:
        def vec(v: np.ndarray | None) -> tuple | None:
            return None if v is None else tuple(float(c) for c in v)

        nodes = sorted((v, d["kind"], vec(d["position"]) if positions else None)
                       for v, d in self.graph.nodes(data=True))
        if edge_labels:
            edges = sorted((e.id, e.source, e.target, e.kind or "", vec(e.z), vec(e.x), e.ports)
                           for e in self.edges())
        else:  # a vector-free connection by its two ends, whichever is the source
            edges = sorted(
                (tuple(sorted([(e.source, ports[0] or ""), (e.target, ports[1] or "")]))
                 if e.z is None and e.x is None else ((e.source, ports[0] or ""),
                                                      (e.target, ports[1] or "")),
                 e.kind or "", vec(e.z), vec(e.x))
                for e in self.edges() for ports in [e.ports or (None, None)])
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
