"""Graph representation of MMRP configurations (paper section 3.1, Definition 1).

A configuration is a tree whose edges are ``connect(uF_u, vF_v)`` with face labels;
only T-B and L-R pairs are legal. A configuration with closed loops becomes a tree by
turning one edge of every loop into a *virtual connection*, which is reported.
Docked modules share one heading, so every module's planar grid cell and heading
follow from the tree and its faces, the root placed at the origin with heading 0.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass

from msrr.core import Configuration
from msrr.core.errors import ConfigurationError

from .robot import FACES, SPEC
from .rules import LEGAL_PAIRS

__all__ = [
    "FaceLinks",
    "Link",
    "TreeConversion",
    "edge_set",
    "face_links",
    "from_links",
    "grid_cells",
    "layout",
    "overlapping_cells",
    "pitch",
    "to_tree",
]

Link = tuple[str, str, str, str]
"""One connection ``(u, F_u, v, F_v)``: ``connect(uF_u, vF_v)``, u the parent."""

FaceLinks = dict[str, dict[str, tuple[str, str]]]
"""Per module, per connected face: ``(other module, other module's face)``."""

GRID_STEP = {face.name: (round(face.normal[0]), round(face.normal[1])) for face in FACES}
"""Grid offset of the neighbour on each face, in cells of one pitch (module frame)."""


def pitch() -> float:
    """Centre distance of two docked modules [m] (``SPEC`` geometry ``pitch``)."""
    return float(SPEC.module_kinds[0].geometry["pitch"])


def _check_link(link: Link, where: str) -> None:
    u, fu, v, fv = link
    for face in (fu, fv):
        if face not in GRID_STEP:
            raise ConfigurationError(f"{where}: unknown face {face!r} (known: B, L, R, T)")
    if frozenset({fu, fv}) not in LEGAL_PAIRS:
        raise ConfigurationError(f"{where}: faces {fu}-{fv} cannot dock (only T-B and L-R)")
    if u == v:
        raise ConfigurationError(f"{where}: module {u!r} cannot connect to itself")


def face_links(config: Configuration) -> FaceLinks:
    """The face adjacency of ``config``, checking faces are legal and used once.

    Raises:
        ConfigurationError: a connection without ports, an illegal face pair, or a
            face used by two connections; the message names the connection.
    """
    links: FaceLinks = {v: {} for v in config.vertices()}
    for e in config.edges():
        if e.ports is None:
            raise ConfigurationError(f"connection {e.id}: needs ports (source face, target face)")
        link = (e.source, e.ports[0], e.target, e.ports[1])
        _check_link(link, f"connection {e.id}")
        for module, face, other, other_face in (link, (link[2], link[3], link[0], link[1])):
            if face in links[module]:
                raise ConfigurationError(f"connection {e.id}: face {face} of module {module} "
                                         "is already connected")
            links[module][face] = (other, other_face)
    return links


def edge_set(config: Configuration) -> frozenset[frozenset[tuple[str, str]]]:
    """Connections as undirected face pairs ``{(u, F_u), (v, F_v)}``: equality up to direction."""
    return frozenset(frozenset({(e.source, e.ports[0]), (e.target, e.ports[1])})
                     for e in config.edges() if e.ports is not None)


def from_links(modules: Iterable[str], links: Iterable[Link], *, name: str = "",
               description: str = "") -> Configuration:
    """A configuration of kind-``mmrp`` modules from ``(u, F_u, v, F_v)`` connections."""
    config = Configuration(SPEC.name, name=name, description=description)
    for module in modules:
        config.add_module(module, SPEC.module_kinds[0].name)
    for u, fu, v, fv in links:
        config.connect(u, v, ports=(fu, fv))
    return config


@dataclass(frozen=True)
class TreeConversion:
    """A configuration made acyclic (section 3.1).

    Attributes:
        tree: the configuration without its virtual connections.
        virtual: the loop edges turned into virtual connections, ``(u, F_u, v, F_v)``.
    """

    tree: Configuration
    virtual: tuple[Link, ...]


def to_tree(config: Configuration) -> TreeConversion:
    """Turn every closed loop of ``config`` into a tree edge set plus virtual connections.

    Edges are scanned in a canonical order (sorted by their face pairs) and the ones
    that close a loop become virtual, so the result does not depend on edge order.

    Raises:
        ConfigurationError: illegal faces (see :func:`face_links`) or a disconnected
            configuration.
    """
    face_links(config)
    parent = {v: v for v in config.vertices()}

    def find(v: str) -> str:
        while parent[v] != v:
            parent[v] = parent[parent[v]]
            v = parent[v]
        return v

    tree = Configuration(config.robot, name=config.name, description=config.description)
    for v in config.vertices():
        tree.add_module(v, config.kind_of(v), position=config.position(v))
    virtual: list[Link] = []
    for e in sorted(config.edges(), key=lambda e: sorted([(e.source, e.ports[0]),
                                                          (e.target, e.ports[1])])):
        a, b = find(e.source), find(e.target)
        if a == b:
            (u, fu), (v, fv) = sorted([(e.source, e.ports[0]), (e.target, e.ports[1])])
            virtual.append((u, fu, v, fv))
            continue
        parent[a] = b
        tree.connect(e.source, e.target, id=e.id, z=e.z, x=e.x, ports=e.ports)
    if len(config) and not tree.is_connected():
        raise ConfigurationError(f"configuration {config.name or '(unnamed)'} is not connected")
    return TreeConversion(tree, tuple(virtual))


def grid_cells(config: Configuration, root: str | None = None) -> dict[str, tuple[int, int]]:
    """Integer grid cell of every module, ``root`` (default: the tree centre) at (0, 0).

    All docked modules share the root's heading 0, so the neighbour on face F of a
    module sits one pitch along F's normal (T=+x, B=-x, L=+y, R=-y).

    Raises:
        ConfigurationError: the configuration is not one connected tree.
    """
    from .centre import root_of

    links = face_links(config)
    if not len(config):
        return {}
    start = root if root is not None else root_of(config)
    if start not in links:
        raise ConfigurationError(f"layout root {start!r} is not a module of this configuration")
    cells = {start: (0, 0)}
    queue = deque([start])
    while queue:
        u = queue.popleft()
        for face, (v, _) in sorted(links[u].items()):
            if v not in cells:
                dx, dy = GRID_STEP[face]
                cells[v] = (cells[u][0] + dx, cells[u][1] + dy)
                queue.append(v)
    if len(cells) != len(links):
        missing = sorted(set(links) - set(cells))
        raise ConfigurationError(f"modules {', '.join(missing)} are not connected to {start}")
    return cells


def overlapping_cells(cells: dict[str, tuple[int, int]]) -> list[tuple[str, str]]:
    """Pairs of modules placed on the same grid cell (a physically impossible tree)."""
    seen: dict[tuple[int, int], str] = {}
    found = []
    for module, cell in cells.items():
        if cell in seen:
            found.append((seen[cell], module))
        else:
            seen[cell] = module
    return found


def layout(config: Configuration, root: str | None = None) -> dict[str, tuple[float, float, float]]:
    """Planar pose ``(x, y, yaw)`` [m, m, rad] of every module, root at the origin, heading 0.

    Args:
        config: a connected MMRP configuration (a tree).
        root: the module placed at the origin; default the tree centre (Theorem 1,
            the lower id of a centre pair), the paper's root tau.
    """
    step = pitch()
    return {v: (i * step, j * step, 0.0) for v, (i, j) in grid_cells(config, root).items()}
