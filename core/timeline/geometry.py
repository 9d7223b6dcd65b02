"""What the timeline draws, as pure functions (no rerun): bodies, colours, layouts.

The drawing contract of a module kind (``docs/writing-a-plugin.md``, section 2) is read
from its ``geometry`` by :func:`body_of`:

* an ``edge`` kind (a module that joins two others) with a ``length`` is a *capsule*
  of ``radius`` along its body's ``z`` axis, its two ends ``length / 2`` from the body
  centre: its first port (FreeSN ``a``) at ``-z``, its second at ``+z``;
* a kind with ``length``, ``width`` or ``height`` is a *box*
  (:func:`msrr.core.robot.body_half_size`);
* a kind with ``radius`` alone is a *sphere*;
* a kind with none of these is a cube of edge ``2 * DEFAULT_HALF_SIZE``.
"""

from __future__ import annotations

import colorsys
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Literal

import networkx as nx
import numpy as np

from ..configuration import Configuration
from ..robot import ModuleKind, body_half_size
from ..shape import fit_planar

__all__ = ["Body", "body_of", "capsule_between", "graph_layout", "label_node", "palette",
           "place_on", "vector_layout"]

Shape = Literal["box", "sphere", "capsule"]

_TAB10 = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189),
          (140, 86, 75), (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207)]


@dataclass(frozen=True)
class Body:
    """How one module kind is drawn.

    Attributes:
        shape: ``"box"``, ``"sphere"`` or ``"capsule"``.
        half_size: box half extents [m], shape (3,); a sphere's ``(r, r, r)``; a
            capsule's bounding box ``(r, r, length / 2)``.
        radius: sphere or capsule radius [m] (boxes: the largest half extent).
        length: capsule end to end along body ``z`` [m]; 0 for other shapes.
    """

    shape: Shape
    half_size: tuple[float, float, float]
    radius: float
    length: float = 0.0

    def ends(self, inset: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """A capsule's two end points in the body frame [m]: first port, second port,
        each moved ``inset`` toward the centre (drawn outside the spheres they dock to)."""
        half = max(self.length / 2 - inset, self.radius)
        return np.array([0.0, 0.0, -half]), np.array([0.0, 0.0, half])


def body_of(kind: ModuleKind) -> Body:
    """The drawn body of ``kind`` (the contract in the module docstring)."""
    g = kind.geometry
    if kind.role == "edge" and "length" in g:
        length = float(g["length"])
        radius = float(g.get("radius", 0.1 * length))
        return Body("capsule", (radius, radius, length / 2), radius, length)
    half = body_half_size(kind)
    if "radius" in g and not ({"length", "width", "height"} & set(g)):
        return Body("sphere", half, half[0])
    return Body("box", half, max(half))


def palette(count: int) -> list[tuple[int, int, int]]:
    """``count`` distinct RGB colours: matplotlib's ten, then golden-angle hues."""
    colors = list(_TAB10[:count])
    for i in range(len(colors), count):
        hue = (i * 0.618033988749895) % 1.0
        r, g, b = colorsys.hsv_to_rgb(hue, 0.65 if i % 2 else 0.9, 0.85 if i % 3 else 0.65)
        colors.append((round(r * 255), round(g * 255), round(b * 255)))
    return colors


def label_node(edge_id: str) -> str:
    """Graph node id of the label drawn on the middle of edge ``edge_id``."""
    return f"edge:{edge_id}"


def graph_layout(configs: Iterable[Configuration], scale: float = 70.0
                 ) -> dict[str, tuple[float, float]]:
    """One 2-D position per vertex of any of ``configs`` (graph-view units).

    Computed once over the union of their topologies (spring layout, fixed seed), so a
    module keeps its place in every graph logged from these configurations.
    """
    union = nx.Graph()
    for config in configs:
        union.add_nodes_from(config.vertices())
        union.add_edges_from((e.source, e.target) for e in config.edges())
    if not union:
        return {}
    k = 1.0 / math.sqrt(len(union))
    pos = nx.spring_layout(union, seed=0, k=2 * k, iterations=200)
    size = scale * max(1.0, math.sqrt(len(union)))
    return {str(v): (float(p[0]) * size, float(p[1]) * size) for v, p in pos.items()}


def vector_layout(config: Configuration, lengths: Mapping[str, float],
                  default: float = 1.0) -> dict[str, np.ndarray]:
    """Vertex positions [m] from the connection vectors: each edge's target sits
    ``length * z`` from its source (``z``: unit vector source -> target, in the
    configuration's frame); each connected part starts at its first vertex at 0.

    Args:
        config: a configuration whose edges carry ``z`` (edges without are skipped).
        lengths: per edge kind, centre-to-centre distance [m] (``None`` kind: key ``""``).
        default: length of kinds not in ``lengths`` [m].
    """
    graph = nx.Graph()
    graph.add_nodes_from(config.vertices())
    for e in config.edges():
        if e.z is not None:
            step = lengths.get(e.kind or "", default) * np.asarray(e.z, dtype=float)
            graph.add_edge(e.source, e.target, step={e.source: step, e.target: -step})
    positions: dict[str, np.ndarray] = {}
    for root in config.vertices():
        if root in positions:
            continue
        positions[root] = np.zeros(3)
        for parent, child in nx.bfs_edges(graph, root):
            positions[child] = positions[parent] + graph.edges[parent, child]["step"][parent]
    return positions


def place_on(layout: Mapping[str, np.ndarray], world: Mapping[str, np.ndarray]
             ) -> dict[str, np.ndarray]:
    """``layout`` moved onto ``world`` by the planar rigid motion (turn about ``z`` and
    shift, :func:`msrr.core.shape.fit_planar`) that best fits the vertices both name,
    and lifted so their mean heights agree. Unchanged when they share no vertex."""
    shared = [v for v in layout if v in world]
    if not shared:
        return dict(layout)
    p = np.array([layout[v][:2] for v in shared], dtype=float)
    q = np.array([world[v][:2] for v in shared], dtype=float)
    if len(shared) == 1:
        theta, t = 0.0, q[0] - p[0]
    else:
        theta, t = fit_planar(p, q)
    c, s = math.cos(theta), math.sin(theta)
    turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    lift = float(np.mean([world[v][2] - layout[v][2] for v in shared]))
    shift = np.array([t[0], t[1], lift])
    return {v: turn @ np.asarray(x, dtype=float) + shift for v, x in layout.items()}


def capsule_between(start: np.ndarray, end: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, float]:
    """``(translation, quaternion xyzw, length)`` of a capsule from ``start`` to ``end``
    (rerun's capsules run along their local ``+z`` from the translation)."""
    start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    axis = end - start
    length = float(np.linalg.norm(axis))
    if length < 1e-12:
        return start, np.array([0.0, 0.0, 0.0, 1.0]), 0.0
    d = axis / length
    cross = np.cross([0.0, 0.0, 1.0], d)
    dot = float(d[2])
    if np.linalg.norm(cross) < 1e-12:
        quat = np.array([0.0, 0.0, 0.0, 1.0]) if dot > 0 else np.array([1.0, 0.0, 0.0, 0.0])
    else:
        quat = np.append(cross, 1.0 + dot)
        quat /= np.linalg.norm(quat)
    return start, quat, length
