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


def common_candidates(links_c: FaceLinks, links_g: FaceLinks, within_c: Collection[str],
                      within_g: Collection[str], *, prefer: tuple[str, str] | None = None,
                      limit: int = 1) -> list[dict[str, str]]:
    """The ``limit`` largest distinct ``MCS(v_c, v_g)`` over all root pairs, largest first.

    The pairs of a common subconfiguration form one component of the face-product
    graph, so every pair is visited once: O(|V_c| |V_g|). Ties go to the component
    that contains ``prefer`` (the centres tau_c, tau_g, as the paper roots the MCS),
    then to the first found.
    """
    order_c, order_g = list(within_c), list(within_g)
    set_c, set_g = set(order_c), set(order_g)
    found: list[dict[str, str]] = []
    seen: set[tuple[str, str]] = set()
    if prefer is not None and prefer[0] in set_c and prefer[1] in set_g:
        first = mcs(links_c, links_g, *prefer, within_c=set_c, within_g=set_g)
        found.append(first)
        seen.update(first.items())
    # a pair with no face-compatible neighbour pair is a one-module MCS: skip it, and
    # start the search only from pairs that share a (face, mating face) signature
    by_face: dict[tuple[str, str], list[str]] = {}
    for b in order_g:
        for face, (w, face2) in sorted(links_g[b].items()):
            if w in set_g:
                by_face.setdefault((face, face2), []).append(b)
    for a in order_c:
        for face, (w, face2) in sorted(links_c[a].items()):
            if w not in set_c:
                continue
            for b in by_face.get((face, face2), ()):
                if (a, b) not in seen:
                    part = mcs(links_c, links_g, a, b, within_c=set_c, within_g=set_g)
                    seen.update(part.items())
                    found.append(part)
    if not found and order_c and order_g:
        found.append({order_c[0]: order_g[0]})
    found.sort(key=len, reverse=True)  # stable: the preferred pair wins ties
    return found[:limit]


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
