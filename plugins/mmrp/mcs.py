"""Maximum common subconfiguration and configuration decomposition (paper section 4.1).

``MCS(v_c, v_g)`` (Definition 3) is found by a DFS from the pair ``(v_c, v_g)`` that
compares docking faces: a neighbour of ``u_c`` on face F, reached through its face
F', is mapped to the neighbour of ``u_g`` on face F if that one is reached through
F' as well. Since a face carries at most one connection, the DFS never branches
and finds the maximum common subconfiguration that maps ``v_c`` to ``v_g``.

``CS(G_c, tau_c, G_g, tau_g)`` subtracts the MCS from both configurations and leaves
subconfigurations (components of two or more modules) and free vertices.
"""

from __future__ import annotations

from collections.abc import Collection, Iterable
from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from .centre import heights, tree_centre
from .representation import FaceLinks

__all__ = [
    "Decomposition",
    "Subconfiguration",
    "common_candidates",
    "components",
    "decompose",
    "largest_common",
    "mcs",
    "subconfiguration",
]


def mcs(links_c: FaceLinks, links_g: FaceLinks, v_c: str, v_g: str, *,
        within_c: Collection[str] | None = None,
        within_g: Collection[str] | None = None) -> dict[str, str]:
    """``MCS(v_c, v_g)`` (Definition 3): the common subconfiguration that maps v_c to v_g.

    Args:
        links_c: face adjacency of the current configuration G_c.
        links_g: face adjacency of the goal configuration G_g.
        v_c: the current module that must map to ``v_g``.
        v_g: the goal module.
        within_c: restrict the search to these current modules (a subconfiguration).
        within_g: restrict the search to these goal modules.

    Returns:
        The vertex mapping f, current id -> goal id, ``v_c`` first; its kept
        connections are the ``len - 1`` tree edges between mapped modules.
    """
    mapping = {v_c: v_g}
    used_g = {v_g}
    stack = [(v_c, v_g)]
    while stack:
        a, b = stack.pop()
        for face, (a2, face2) in sorted(links_c[a].items()):
            if a2 in mapping or (within_c is not None and a2 not in within_c):
                continue
            mate = links_g[b].get(face)
            if mate is None:
                continue
            b2, goal_face2 = mate
            if goal_face2 != face2 or b2 in used_g or (within_g is not None and b2 not in within_g):
                continue
            mapping[a2] = b2
            used_g.add(b2)
            stack.append((a2, b2))
    return mapping


_Typed = dict[tuple[str, str], list[tuple[int, int]]]
"""Connections by face pair ``(F, F')`` (from the T or L end), as index pairs."""


def _typed(links: FaceLinks, order: list[str], index: dict[str, int]) -> _Typed:
    """The connections among ``order`` by face pair, each once from its T or L end."""
    out: _Typed = {}
    for v in order:
        for face, (w, face2) in links[v].items():
            if face in ("T", "L") and w in index:
                out.setdefault((face, face2), []).append((index[v], index[w]))
    return out


def _product_edges(edges_c: _Typed, edges_g: _Typed, size_g: int
                   ) -> tuple[np.ndarray, np.ndarray] | None:
    """The face-product graph's edges, each end the pair key ``i_c * size_g + i_g``;
    None when there are none."""
    sources, targets = [], []
    for key, pairs_c in edges_c.items():
        pairs_g = edges_g.get(key)
        if not pairs_g:
            continue
        ec, eg = np.array(pairs_c), np.array(pairs_g)
        sources.append((ec[:, 0, None] * size_g + eg[None, :, 0]).ravel())
        targets.append((ec[:, 1, None] * size_g + eg[None, :, 1]).ravel())
    if not sources:
        return None
    return np.concatenate(sources), np.concatenate(targets)


def _connected(src: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """The graph's vertices (sorted keys), the component label of each, and the count."""
    nodes, inverse = np.unique(np.concatenate([src, dst]), return_inverse=True)
    if len(src) < 4096:  # small: a Python union-find beats building a sparse matrix
        root = list(range(len(nodes)))

        def find(v: int) -> int:
            while root[v] != v:
                root[v] = root[root[v]]
                v = root[v]
            return v

        half = len(src)
        for a, b in zip(inverse[:half].tolist(), inverse[half:].tolist(), strict=True):
            ra, rb = find(a), find(b)
            if ra != rb:
                root[max(ra, rb)] = min(ra, rb)
        _, labels = np.unique([find(v) for v in range(len(nodes))], return_inverse=True)
        return nodes, labels, int(labels.max()) + 1
    graph = coo_matrix((np.ones(len(src)), (inverse[:len(src)], inverse[len(src):])),
                       shape=(len(nodes), len(nodes)))
    count, labels = connected_components(graph, directed=False)
    return nodes, labels, count


def _largest(nodes: np.ndarray, labels: np.ndarray, count: int, prefer_key: int | None,
             limit: int) -> list[tuple[int, np.ndarray]]:
    """The ``limit`` largest components, ties to the one holding ``prefer_key``, then to the
    first pair: each as its lead key (``prefer_key`` if held, else its first) and members."""
    sizes = np.bincount(labels, minlength=count)
    first = np.full(count, np.iinfo(np.int64).max)
    np.minimum.at(first, labels, nodes)  # nodes are sorted: the first pair in order
    holds = np.zeros(count, dtype=bool)
    if prefer_key is not None:
        at = np.searchsorted(nodes, prefer_key)
        if at < len(nodes) and nodes[at] == prefer_key:
            holds[labels[at]] = True
    out = []
    for label in np.lexsort((first, ~holds, -sizes))[:limit]:
        members = nodes[labels == label]
        out.append((prefer_key if holds[label] else int(members[0]), members))
    return out


def common_candidates(links_c: FaceLinks, links_g: FaceLinks, within_c: Collection[str],
                      within_g: Collection[str], *, prefer: tuple[str, str] | None = None,
                      limit: int = 1) -> list[dict[str, str]]:
    """The ``limit`` largest distinct ``MCS(v_c, v_g)`` over all root pairs, largest first.

    The pairs of a common subconfiguration form one component of the face-product
    graph, whose vertices are pairs (v_c, v_g) and whose edges join
    ``(u_c, u_g)``-``(w_c, w_g)`` when ``connect(u_c F, w_c F')`` and
    ``connect(u_g F, w_g F')`` are both connections. Every component is found at
    once (``scipy.sparse.csgraph.connected_components`` over the product edges,
    O(|E_c| |E_g|)), so this equals running :func:`mcs` from every root pair. Ties go
    to the component that contains ``prefer`` (the centres tau_c, tau_g, as the
    paper roots the MCS), then to the one with the first pair in (``within_c``,
    ``within_g``) order. A mapping starts with ``prefer`` if it holds it, else with
    its first pair.
    """
    order_c, order_g = list(within_c), list(within_g)
    index_c = {v: i for i, v in enumerate(order_c)}
    index_g = {v: i for i, v in enumerate(order_g)}
    size_g = len(order_g)
    edges = _product_edges(_typed(links_c, order_c, index_c), _typed(links_g, order_g, index_g),
                           size_g)
    prefer_key = (index_c[prefer[0]] * size_g + index_g[prefer[1]]
                  if prefer is not None and prefer[0] in index_c and prefer[1] in index_g
                  else None)
    found: list[dict[str, str]] = []
    if edges is not None:
        for lead, members in _largest(*_connected(*edges), prefer_key, limit):
            mapping = {order_c[lead // size_g]: order_g[lead % size_g]}
            for key in members.tolist():
                mapping.setdefault(order_c[key // size_g], order_g[key % size_g])
            found.append(mapping)
    if len(found) < limit and order_c and order_g:
        taken = {(a, b) for part in found for a, b in part.items()}
        single = prefer if prefer_key is not None else (order_c[0], order_g[0])
        if single not in taken:
            found.append({single[0]: single[1]})
    return found[:max(limit, 1)]


def largest_common(links_c: FaceLinks, links_g: FaceLinks, within_c: Collection[str],
                   within_g: Collection[str], *, prefer: tuple[str, str] | None = None
                   ) -> dict[str, str]:
    """The largest ``MCS(v_c, v_g)`` over all root pairs; see :func:`common_candidates`."""
    return common_candidates(links_c, links_g, within_c, within_g, prefer=prefer)[0]


def components(links: FaceLinks, vertices: Iterable[str]) -> list[list[str]]:
    """Connected components of ``links`` restricted to ``vertices``, in input order."""
    remaining = list(vertices)
    allowed = set(remaining)
    seen: set[str] = set()
    found = []
    for v in remaining:
        if v in seen:
            continue
        part = [v]
        seen.add(v)
        for u in part:
            for w, _ in links[u].values():
                if w in allowed and w not in seen:
                    seen.add(w)
                    part.append(w)
        found.append(part)
    return found


@dataclass(frozen=True)
class Subconfiguration:
    """A connected remainder of a decomposition, rooted at its centre (section 4.2).

    Attributes:
        vertices: its modules.
        root: its centre tilde-tau (first of a centre pair).
        height: h(tilde-tau), the height of the tree rooted at its centre.
    """

    vertices: tuple[str, ...]
    root: str
    height: int


def subconfiguration(links: FaceLinks, vertices: Iterable[str]) -> Subconfiguration:
    """The :class:`Subconfiguration` of the connected module set ``vertices``."""
    members = tuple(vertices)
    allowed = set(members)
    adj = {v: [w for w, _ in links[v].values() if w in allowed] for v in members}
    root = tree_centre(adj)[0]
    return Subconfiguration(members, root, heights(adj, root)[root])


@dataclass(frozen=True)
class Decomposition:
    """``CS(G_c, tau_c, G_g, tau_g)`` (section 4.1).

    Attributes:
        roots: the pair the common subconfiguration was rooted at.
        common: the mapping f of the MCS, current id -> goal id.
        current: remaining subconfigurations tilde-G_c of the current side.
        goal: remaining subconfigurations tilde-G_g of the goal side.
        free_current: free vertices hat-V_c (single modules left over).
        free_goal: free vertices hat-V_g.
    """

    roots: tuple[str, str]
    common: dict[str, str]
    current: tuple[Subconfiguration, ...]
    goal: tuple[Subconfiguration, ...]
    free_current: tuple[str, ...]
    free_goal: tuple[str, ...]

    @property
    def kept(self) -> int:
        """Connections the common subconfiguration keeps."""
        return max(len(self.common) - 1, 0)


def decompose(links_c: FaceLinks, links_g: FaceLinks, within_c: Collection[str],
              within_g: Collection[str], common: dict[str, str]) -> Decomposition:
    """Split both sides into ``common``, subconfigurations and free vertices.

    Args:
        links_c: face adjacency of G_c.
        links_g: face adjacency of G_g.
        within_c: the current modules being decomposed (all of G_c, or one tilde-G_c).
        within_g: the goal modules being decomposed.
        common: an MCS between them (current id -> goal id), non-empty.
    """
    used_g = set(common.values())
    rest_c = [v for v in within_c if v not in common]
    rest_g = [v for v in within_g if v not in used_g]
    parts_c = components(links_c, rest_c)
    parts_g = components(links_g, rest_g)
    root = next(iter(common.items()))
    return Decomposition(
        roots=root, common=dict(common),
        current=tuple(subconfiguration(links_c, p) for p in parts_c if len(p) > 1),
        goal=tuple(subconfiguration(links_g, p) for p in parts_g if len(p) > 1),
        free_current=tuple(p[0] for p in parts_c if len(p) == 1),
        free_goal=tuple(p[0] for p in parts_g if len(p) == 1),
    )
