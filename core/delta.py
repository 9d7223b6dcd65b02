"""What changes from one configuration to the next, and configurations built from it.

A plan of n modules and k actions holds k target configurations; stored or copied
whole they cost O(n k) (a 1,000-module MMRP plan of 5,000 actions was 916 MB as
JSON). A :class:`ConfigurationDelta` holds only what differs between two
configurations: the vertices and connections removed, and those added or changed,
each whole, with the place of an inserted one in the vertex or connection order when
it is not the end. :func:`difference` finds it, :class:`Draft` applies it, and a
:class:`DerivedConfiguration` is a configuration recorded as its predecessor plus a
delta, built the first time anything reads it (from the nearest predecessor already
built). Plan files store deltas (:mod:`msrr.core.plan`); a delta applied to the
configuration it was taken from gives the other one exactly: the same vertices and
connections, in the same order, with bit-identical vectors and positions.
"""

from __future__ import annotations

import bisect
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .configuration import Configuration, Edge
from .errors import ConfigurationError

__all__ = ["EMPTY", "ConfigurationDelta", "DerivedConfiguration", "Draft", "Vertex",
           "difference"]


@dataclass(frozen=True)
class Vertex:
    """One vertex as a delta records it: id, kind (``"virtual"`` for a free connector)
    and optional position [m], a read-only float64 array of shape (3,)."""

    id: str
    kind: str
    position: np.ndarray | None = None


@dataclass(frozen=True)
class ConfigurationDelta:
    """The changes that take one configuration to another.

    Applied in this order: ``removed_edges``, ``removed_vertices``, then ``vertices``
    and ``edges``: one whose id is present replaces it in its place, a new one is
    appended, or inserted at its index in the new order when one is given. A vertex
    removed (and not written again) must have no connection left at the end.
    ``name`` / ``description``: the new ones, ``None`` when they stay.

    Attributes:
        removed_vertices: ids of vertices removed.
        vertices: ``(vertex, index or None)`` of vertices added or changed.
        removed_edges: ids of connections removed.
        edges: ``(edge, index or None)`` of connections added or changed.
        name: the new name, if it changes.
        description: the new description, if it changes.
    """

    removed_vertices: tuple[str, ...] = ()
    vertices: tuple[tuple[Vertex, int | None], ...] = ()
    removed_edges: tuple[str, ...] = ()
    edges: tuple[tuple[Edge, int | None], ...] = ()
    name: str | None = None
    description: str | None = None

    def __bool__(self) -> bool:
        return bool(self.removed_vertices or self.vertices or self.removed_edges
                    or self.edges or self.name is not None or self.description is not None)

    @property
    def size(self) -> int:
        """Records in the delta (vertices and connections removed, added or changed)."""
        return (len(self.removed_vertices) + len(self.vertices) + len(self.removed_edges)
                + len(self.edges))


EMPTY = ConfigurationDelta()
"""The delta of a configuration to an equal one."""


def _same_array(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    """Bit-identical vectors (``-0.0`` differs from ``0.0``: a round trip keeps both)."""
    if a is b:
        return True
    return a is not None and b is not None and a.tobytes() == b.tobytes()


def _increasing_subset(keys: list[str], order: list[int]) -> set[str]:
    """The keys of a longest strictly increasing subsequence of ``order`` (patience
    sorting, O(n log n)): the items that can stay where they are."""
    tails: list[int] = []     # tails[k]: position of the smallest tail of length k + 1
    values: list[int] = []    # order[tails[k]]
    previous = [-1] * len(order)
    for i, value in enumerate(order):
        k = bisect.bisect_left(values, value)
        if k:
            previous[i] = tails[k - 1]
        if k == len(tails):
            tails.append(i)
            values.append(value)
        else:
            tails[k], values[k] = i, value
    kept, i = set(), tails[-1] if tails else -1
    while i >= 0:
        kept.add(keys[i])
        i = previous[i]
    return kept


def _placement(before: Sequence[str], after: Sequence[str], changed: set[str]
               ) -> tuple[list[str], list[tuple[str, int | None]]]:
    """The ids to remove and those to write, with their index unless appended, so that
    ``before`` becomes ``after`` (ids in ``changed`` are rewritten in place)."""
    index = {k: i for i, k in enumerate(before)}
    common = [k for k in after if k in index]
    order = [index[k] for k in common]
    moved: set[str] = set()
    if any(a > b for a, b in zip(order, order[1:], strict=False)):
        moved = set(common) - _increasing_subset(common, order)
    after_set = set(after)
    removed = [k for k in before if k not in after_set or k in moved]
    present = len(common) - len(moved)
    written: list[tuple[str, int | None]] = []
    for i, k in enumerate(after):
        if k not in index or k in moved:
            written.append((k, None if i == present else i))
            present += 1
        elif k in changed:
            written.append((k, None))
    return removed, written


def difference(before: Configuration, after: Configuration) -> ConfigurationDelta:
    """The delta that takes ``before`` to ``after`` (:meth:`Draft.apply`).

    O(1) when ``after`` is ``before`` or a :class:`DerivedConfiguration` of it; else
    one pass over both (O(n)).
    """
    if after is before:
        return EMPTY
    origin = after.__dict__.get("_origin")
    if origin is not None and origin[0] is before:
        return origin[1]
    bn, an = before.graph._node, after.graph._node
    changed_v = {v for v, d in an.items() if (b := bn.get(v)) is not None and (
        b["kind"] != d["kind"] or not _same_array(b["position"], d["position"]))}
    if bn.keys() == an.keys() and list(bn) == list(an):
        removed_v: list[str] = []
        vertices = [(v, None) for v in an if v in changed_v]
    else:
        removed_v, vertices = _placement(list(bn), list(an), changed_v)
    be, ae = before._edge_ends, after._edge_ends
    badj, aadj = before.graph._adj, after.graph._adj
    changed_e = set()
    for e, ends in ae.items():  # the graphs' own edge data: no Edge built per connection
        if e not in be:
            continue
        if be[e] != ends:
            changed_e.add(e)
            continue
        b, a = badj[ends[0]][ends[1]][e], aadj[ends[0]][ends[1]][e]
        if a is not b and (a["kind"] != b["kind"] or a["ports"] != b["ports"]
                           or not _same_array(a["z"], b["z"])
                           or not _same_array(a["x"], b["x"])):
            changed_e.add(e)
    if be.keys() == ae.keys() and list(be) == list(ae):
        removed_e: list[str] = []
        edges: list[tuple[str, int | None]] = [(e, None) for e in ae if e in changed_e]
    else:
        removed_e, edges = _placement(list(be), list(ae), changed_e)
    return ConfigurationDelta(
        removed_vertices=tuple(removed_v),
        vertices=tuple((Vertex(v, an[v]["kind"], an[v]["position"]), at) for v, at in vertices),
        removed_edges=tuple(removed_e),
        edges=tuple((after.edge(e), at) for e, at in edges),
        name=None if after.name == before.name else after.name,
        description=None if after.description == before.description else after.description)


def _insert(items: dict, at: int, key: str, value: Any, what: str, field: str) -> dict:
    """``items`` with ``key`` inserted at index ``at`` (a new dict)."""
    if not 0 <= at <= len(items):
        raise ConfigurationError(f"index {at} is outside the {len(items)} {what} there are",
                                 field=field)
    pairs = list(items.items())
    pairs.insert(at, (key, value))
    return dict(pairs)


class Draft:
    """A configuration being changed by deltas: its vertices and connections as plain
    dicts, in order, with each vertex's connections; :meth:`build` makes the
    :class:`Configuration`.

    Args:
        config: the configuration to start from (read, never changed).
    """

    def __init__(self, config: Configuration):
        self.robot, self.name, self.description = config.robot, config.name, config.description
        self.vertices: dict[str, Vertex] = {
            v: Vertex(v, d["kind"], d["position"]) for v, d in config.graph._node.items()}
        succ = config.graph._succ  # plain dicts: Configuration.edge's views cost 5x
        self.edges: dict[str, Edge] = {
            e: Edge(e, s, t, d["kind"], d["z"], d["x"], d["ports"])
            for e, (s, t) in config._edge_ends.items() for d in (succ[s][t][e],)}
        self.incident: dict[str, set[str]] = {v: set() for v in self.vertices}
        for edge in self.edges.values():
            self.incident[edge.source].add(edge.id)
            self.incident[edge.target].add(edge.id)

    def apply(self, delta: ConfigurationDelta) -> None:
        """Apply ``delta`` in place (see :class:`ConfigurationDelta` for the order).

        Raises:
            ConfigurationError: an id to remove that is not there, an id written twice,
                a vertex removed with connections left, an index out of range or given
                for an id that is there, a connection whose end is not a vertex, an id
                both a vertex and a connection; the field names the delta's list and item
                (``removed_connections[2]``, ``connections[0].source``).
        """
        for i, edge_id in enumerate(delta.removed_edges):
            edge = self.edges.pop(edge_id, None)
            if edge is None:
                raise ConfigurationError(f"no connection {edge_id!r} to remove",
                                         field=f"removed_connections[{i}]")
            self.incident[edge.source].discard(edge_id)
            self.incident[edge.target].discard(edge_id)
        for i, vertex_id in enumerate(delta.removed_vertices):
            if self.vertices.pop(vertex_id, None) is None:
                raise ConfigurationError(f"no module {vertex_id!r} to remove",
                                         field=f"removed_modules[{i}]")
        for what, written in (("modules", delta.vertices), ("connections", delta.edges)):
            seen: set[str] = set()
            for i, (item, _) in enumerate(written):
                if item.id in seen:
                    raise ConfigurationError(f"{item.id!r} is written twice",
                                             field=f"{what}[{i}].id")
                seen.add(item.id)
        for i, (vertex, at) in enumerate(delta.vertices):
            self._write_vertex(vertex, at, f"modules[{i}]")
        for i, (edge, at) in enumerate(delta.edges):
            self._write_edge(edge, at, f"connections[{i}]")
        for i, vertex_id in enumerate(delta.removed_vertices):  # gone, or back in its place
            if vertex_id in self.vertices:
                continue
            if self.incident[vertex_id]:
                raise ConfigurationError(
                    f"module {vertex_id!r} is removed but keeps connection(s) "
                    f"{', '.join(sorted(self.incident[vertex_id]))}",
                    field=f"removed_modules[{i}]")
            del self.incident[vertex_id]
        if delta.name is not None:
            self.name = delta.name
        if delta.description is not None:
            self.description = delta.description

    def _write_vertex(self, vertex: Vertex, at: int | None, field: str) -> None:
        if vertex.id in self.edges:
            raise ConfigurationError(f"duplicate module id {vertex.id!r} (a connection's)",
                                     field=f"{field}.id")
        if at is None or vertex.id in self.vertices:
            if at is not None:
                raise ConfigurationError(f"module {vertex.id!r} is there: it takes no index",
                                         field=f"{field}.at")
            self.vertices[vertex.id] = vertex
        else:
            self.vertices = _insert(self.vertices, at, vertex.id, vertex, "modules",
                                    f"{field}.at")
        self.incident.setdefault(vertex.id, set())

    def _write_edge(self, edge: Edge, at: int | None, field: str) -> None:
        for end, name in ((edge.source, "source"), (edge.target, "target")):
            if end not in self.vertices:
                raise ConfigurationError(f"connection end {end!r} is not a module there",
                                         field=f"{field}.{name}")
        if edge.source == edge.target:
            raise ConfigurationError(f"module {edge.source!r} cannot connect to itself",
                                     field=f"{field}.target")
        if edge.id in self.vertices:
            raise ConfigurationError(f"duplicate connection id {edge.id!r} (a module's)",
                                     field=f"{field}.id")
        old = self.edges.get(edge.id)
        if old is not None:
            if at is not None:
                raise ConfigurationError(f"connection {edge.id!r} is there: it takes no "
                                         "index", field=f"{field}.at")
            self.incident[old.source].discard(edge.id)
            self.incident[old.target].discard(edge.id)
            self.edges[edge.id] = edge
        elif at is None:
            self.edges[edge.id] = edge
        else:
            self.edges = _insert(self.edges, at, edge.id, edge, "connections", f"{field}.at")
        self.incident[edge.source].add(edge.id)
        self.incident[edge.target].add(edge.id)

    def build(self) -> Configuration:
        """The configuration (a new one; vectors and positions shared)."""
        return Configuration._assemble(
            self.robot, self.name, self.description,
            [(v.id, v.kind, v.position) for v in self.vertices.values()],
            [(e.id, e.source, e.target, {"kind": e.kind, "z": e.z, "x": e.x, "ports": e.ports})
             for e in self.edges.values()])


_BUILDING = ("add_module", "add_virtual", "connect", "disconnect", "remove_module")
"""Methods that change a configuration in place: after one, a derived configuration is
no longer its predecessor plus its delta."""


class DerivedConfiguration(Configuration):
    """``parent`` plus ``delta``, built on first use (a :class:`Configuration` then).

    It builds itself from the nearest predecessor already built and the deltas since,
    so reading the targets of a plan in order builds each once, from the one before
    it. :func:`difference` from ``parent`` is ``delta`` at no cost, built or not, until
    the configuration is changed in place; setting ``name`` or ``description`` updates
    the delta. Pickled as the plain configuration it stands for.

    Args:
        parent: the configuration before this one (plain or derived).
        delta: what changes (applied to ``parent`` it must succeed; :class:`Draft`).
    """

    def __init__(self, parent: Configuration, delta: ConfigurationDelta = EMPTY):  # noqa: D107
        # no super().__init__(): every attribute of a Configuration appears when built
        self.__dict__["_origin"] = (parent, delta)
        self.__dict__["_pending"] = True

    def __getattr__(self, name: str) -> Any:
        # only called for attributes not set yet, i.e. before the configuration is built
        if not self.__dict__.get("_pending") or name.startswith("__"):
            raise AttributeError(name)
        self._build()
        return getattr(self, name)

    def __setattr__(self, name: str, value: Any) -> None:
        origin = self.__dict__.get("_origin")
        if origin is not None and name in ("name", "description"):
            self.__dict__["_origin"] = (origin[0], replace(origin[1], **{name: value}))
        object.__setattr__(self, name, value)

    @property
    def delta(self) -> ConfigurationDelta | None:
        """Its delta from ``parent`` while it still describes it (None once the
        configuration has been changed in place)."""
        origin = self.__dict__.get("_origin")
        return None if origin is None else origin[1]

    def _build(self) -> None:
        chain: list[ConfigurationDelta] = []
        node: Configuration = self
        while node.__dict__.get("_pending"):
            parent, delta = node.__dict__["_origin"]
            chain.append(delta)
            node = parent
        draft = Draft(node)
        for delta in reversed(chain):
            draft.apply(delta)
        built = draft.build()
        del self.__dict__["_pending"]
        for key, value in built.__dict__.items():  # a name set before the build wins
            self.__dict__.setdefault(key, value)

    def _forget_origin(self) -> None:
        if self.__dict__.get("_pending"):
            self._build()
        self.__dict__.pop("_origin", None)

    def __reduce_ex__(self, protocol: int) -> Any:
        if self.__dict__.get("_pending"):
            self._build()
        return _plain, (Configuration.derive(self),)


def _in_place(name: str) -> Any:
    method = getattr(Configuration, name)

    def changed(self: DerivedConfiguration, *args: Any, **kwargs: Any) -> Any:
        self._forget_origin()
        return method(self, *args, **kwargs)

    changed.__name__, changed.__doc__ = name, method.__doc__
    return changed


for _name in _BUILDING:
    setattr(DerivedConfiguration, _name, _in_place(_name))


def _plain(config: Configuration) -> Configuration:
    """Unpickle a derived configuration as the plain one it stands for."""
    return config
