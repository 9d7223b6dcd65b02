"""Tree centre and vertex heights (paper section 3.2, Theorem 1, Fig. 5).

The centre of a tree is the unique vertex, or unique pair of adjacent vertices, whose
removal leaves components of at most half the vertices each (Theorem 1). It serves
as the root tau; the height of a vertex is the length of the longest downward path
from it to a leaf of the rooted tree, so leaves have height 0 and the root the
height of the tree.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping

from msrr.core import Configuration
from msrr.core.errors import ConfigurationError

__all__ = ["Adjacency", "adjacency", "centre", "heights", "parents", "root_of", "tree_centre"]

Adjacency = Mapping[str, Collection[str]]
"""Undirected neighbours of every vertex, in a stable order."""


def adjacency(config: Configuration) -> dict[str, list[str]]:
    """Undirected neighbours of every module of ``config``, in insertion order."""
    adj: dict[str, list[str]] = {v: [] for v in config.vertices()}
    for e in config.edges():
        adj[e.source].append(e.target)
        adj[e.target].append(e.source)
    return adj


def parents(adj: Adjacency, root: str) -> dict[str, str | None]:
    """Parent of every vertex reachable from ``root`` (BFS), the root mapped to ``None``."""
    parent: dict[str, str | None] = {root: None}
    order = [root]
    for u in order:
        for v in adj[u]:
            if v not in parent:
                parent[v] = u
                order.append(v)
    return parent


def tree_centre(adj: Adjacency) -> tuple[str, ...]:
    """The centre of the tree ``adj``: one vertex or two adjacent vertices (Theorem 1).

    A vertex is central iff no component of G - v has more than n/2 vertices; the
    component sizes follow from subtree sizes of one rooted traversal, O(|V|).
    Vertices come back in the order of ``adj``.

    Raises:
        ConfigurationError: ``adj`` is empty, not connected or not a tree.
    """
    vertices = list(adj)
    if not vertices:
        raise ConfigurationError("an empty configuration has no centre")
    n = len(vertices)
    if sum(len(adj[v]) for v in vertices) != 2 * (n - 1):
        raise ConfigurationError("the centre is defined for trees only")
    parent = parents(adj, vertices[0])
    if len(parent) != n:
        raise ConfigurationError("the centre is defined for connected configurations only")
    size = dict.fromkeys(parent, 1)
    for v in reversed(list(parent)):
        if parent[v] is not None:
            size[parent[v]] += size[v]
    central = []
    for v in vertices:
        largest = max([size[c] for c in adj[v] if parent.get(c) == v] + [n - size[v]])
        if 2 * largest <= n:
            central.append(v)
    return tuple(central)


def centre(config: Configuration) -> tuple[str, ...]:
    """The centre of the tree ``config`` (Theorem 1); see :func:`tree_centre`."""
    return tree_centre(adjacency(config))


def root_of(config: Configuration) -> str:
    """The root tau of ``config``: its centre, the first in vertex order for a centre pair."""
    return centre(config)[0]


def heights(adj: Adjacency, root: str) -> dict[str, int]:
    """Height of every vertex of the tree ``adj`` rooted at ``root`` (Fig. 5).

    The height is the length of the longest downward path to a leaf: leaves 0,
    ``root`` the height of the tree.
    """
    parent = parents(adj, root)
    height = dict.fromkeys(parent, 0)
    for v in reversed(list(parent)):
        p = parent[v]
        if p is not None:
            height[p] = max(height[p], height[v] + 1)
    return height
