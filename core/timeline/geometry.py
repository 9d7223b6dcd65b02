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

A target configuration is drawn at the robot's scale by :func:`shape_layout` (each
connection placed as the generic runtime places it: ports face to face, bodies touching
along the connection vector, an edge module's length between its ends) and put where the
robot is by :func:`fit_layout` (the best planar rigid motion onto the modules' poses).
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
from ..errors import ExecutionError
from ..generic.geometry import BodyPose, contact_reach, place_for_ports, rotate_z
from ..robot import ModuleKind, body_half_size
from ..shape import fit_planar

__all__ = ["Body", "BodyPose", "body_of", "capsule_between", "fit_layout", "graph_layout",
           "label_node", "palette", "place_on", "shape_layout", "vector_layout"]

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


def _reach(kind: ModuleKind | None, yaw: float, direction: np.ndarray) -> float:
    """Centre to surface [m] of a body of ``kind`` turned by ``yaw`` along the world unit
    ``direction``; 0 for a vertex with no body (a free connector)."""
    return 0.0 if kind is None else contact_reach(kind, rotate_z(direction, -yaw))


def _step(config: Configuration, edge_id: str, parent: str, at: BodyPose,
          kinds: Mapping[str, ModuleKind]) -> BodyPose:
    """Where the other end of connection ``edge_id`` sits when ``parent`` is at ``at``."""
    e = config.edge(edge_id)
    forward = e.source == parent
    child = e.target if forward else e.source
    sign = 1.0 if forward else -1.0
    z = None if e.z is None else np.asarray(e.z, dtype=float) / np.linalg.norm(e.z)
    edge_kind = kinds.get(e.kind) if e.kind is not None else None
    if edge_kind is not None:  # an edge module: its ends ``length`` apart along z
        length = float(edge_kind.geometry.get("length", 2 * max(body_half_size(edge_kind))))
        direction = z if z is not None else rotate_z(np.array([1.0, 0.0, 0.0]), at.yaw)
        return BodyPose(at.position + sign * length * direction, at.yaw)
    pk = None if config.is_virtual(parent) else kinds.get(config.kind_of(parent))
    ck = None if config.is_virtual(child) else kinds.get(config.kind_of(child))
    ports = e.ports or (None, None)
    mine, theirs = (ports[0], ports[1]) if forward else (ports[1], ports[0])
    if pk is not None and ck is not None and mine is not None and theirs is not None:
        try:
            return place_for_ports(pk, mine, at, ck, theirs, at.yaw)
        except (ExecutionError, KeyError, LookupError):
            pass  # a port without a normal (or unknown): the bodies touch along z
    direction = sign * z if z is not None else rotate_z(np.array([sign, 0.0, 0.0]), at.yaw)
    distance = _reach(pk, at.yaw, direction) + _reach(ck, at.yaw, -direction)
    return BodyPose(at.position + distance * direction, at.yaw)


def shape_layout(config: Configuration, kinds: Mapping[str, ModuleKind]
                 ) -> dict[str, BodyPose]:
    """Every vertex of ``config`` at the robot's scale, in the configuration's own frame.

    Each connected part is grown breadth-first from its first vertex at the origin, each
    connection placed as the generic runtime places it
    (:mod:`msrr.core.generic.geometry`): two ports with normals face to face
    (:func:`~msrr.core.generic.geometry.place_for_ports`, ``geometry["pitch"]`` included);
    else the two bodies touch along the connection vector ``z`` (sphere: its radius,
    box: where the ray leaves it); an edge module (a FreeSN strut) puts its ends its
    kind's ``length`` apart along ``z``. Body sizes come from each kind's ``geometry``.
    Positions the configuration's vertices carry are not used: a plan's targets keep
    their start's (FreeSN's scenarios), which are not the target's shape.

    Args:
        config: the configuration (a plan's target).
        kinds: module kinds by name (the robot spec's).

    Returns:
        per vertex (virtual ones included: a free end of an edge module) its pose [m, rad].
    """
    vertices = config.vertices()
    graph = nx.MultiGraph()
    graph.add_nodes_from(vertices)
    graph.add_edges_from((e.source, e.target, e.id) for e in config.edges())
    poses: dict[str, BodyPose] = {}
    for root in vertices:
        if root in poses:
            continue
        poses[root] = BodyPose(np.zeros(3))
        for parent, child in nx.bfs_edges(graph, root):
            edge_id = next(iter(graph.get_edge_data(parent, child)))
            poses[child] = _step(config, edge_id, parent, poses[parent], kinds)
    return poses


def _rigid_fit(layout: Mapping[str, BodyPose], poses: Mapping[str, BodyPose],
               shared: list[str], turn: float | None) -> tuple[float, np.ndarray]:
    """``(theta, shift (3,))`` of the planar rigid motion that best maps ``shared``'s
    layout onto their poses (least squares; with the turn ``turn`` when given), lifted so
    the mean heights agree."""
    p = np.array([layout[v].position[:2] for v in shared], dtype=float)
    q = np.array([poses[v].position[:2] for v in shared], dtype=float)
    if turn is None:
        theta, t = fit_planar(p, q, np.array([layout[v].yaw for v in shared]),
                              np.array([poses[v].yaw for v in shared]))
    else:
        theta = turn
        t = q.mean(axis=0) - rotate_z(np.append(p.mean(axis=0), 0.0), theta)[:2]
    lift = float(np.mean([poses[v].position[2] - layout[v].position[2] for v in shared]))
    return theta, np.array([t[0], t[1], lift])


def _common_turn(layout: Mapping[str, BodyPose], poses: Mapping[str, BodyPose],
                 oriented: list[str]) -> float | None:
    """The turn [rad] that gives the ``oriented`` vertices (bodies whose heading shows)
    their headings, when they agree on one (mean resultant length over 0.9)."""
    if not oriented:
        return None
    diff = np.array([poses[v].yaw - layout[v].yaw for v in oriented])
    c, s = float(np.mean(np.cos(diff))), float(np.mean(np.sin(diff)))
    return math.atan2(s, c) if math.hypot(c, s) > 0.9 else None


def _trimmed_fit(layout: Mapping[str, BodyPose], poses: Mapping[str, BodyPose],
                 shared: list[str], tolerance: float, turn: float | None
                 ) -> tuple[float, np.ndarray]:
    """The fit of :func:`_rigid_fit`, made again without the vertex that fits worst
    while one is off by more than ``tolerance`` [m] and over half of them (and two)
    remain: the target sits on the part of the robot already in place, and the
    modules that still have to move show where they go."""
    keep = list(shared)
    theta, shift = _rigid_fit(layout, poses, keep, turn)
    while len(keep) > max(2, math.ceil(len(shared) / 2)):
        off = {v: float(np.linalg.norm((rotate_z(layout[v].position, theta) + shift
                                        - poses[v].position)[:2])) for v in keep}
        worst = max(keep, key=off.__getitem__)
        if off[worst] <= tolerance:
            break
        keep.remove(worst)
        theta, shift = _rigid_fit(layout, poses, keep, turn)
    return theta, shift


def fit_layout(config: Configuration, layout: Mapping[str, BodyPose],
               poses: Mapping[str, BodyPose], tolerance: float = 0.0,
               oriented: Iterable[str] = ()) -> dict[str, BodyPose]:
    """``layout`` put where the robot is: each connected part of ``config`` moved by the
    planar rigid motion (turn about ``z`` and shift, :func:`msrr.core.shape.fit_planar`)
    that best fits its vertices onto their ``poses``, lifted so the mean heights agree;
    fitted again without the worst-fitting vertex while one is more than ``tolerance``
    [m] off and over half remain, so the part already in place holds the target.

    The ``oriented`` vertices are bodies whose heading shows (boxes, not balls): when
    their heading changes agree, that is the turn, and only the shift is fitted (a
    chain's outline is not turned end for end to fit its modules' centres better).
    A part with one posed vertex takes that vertex's heading; a part with none is left
    out (nothing of it is on the robot to place it by).
    """
    graph = nx.Graph()
    graph.add_nodes_from(layout)
    graph.add_edges_from((e.source, e.target) for e in config.edges()
                         if e.source in layout and e.target in layout)
    headed = set(oriented)
    placed: dict[str, BodyPose] = {}
    for part in nx.connected_components(graph):
        shared = [v for v in layout if v in part and v in poses]
        if not shared:
            continue
        turn = _common_turn(layout, poses, [v for v in shared if v in headed])
        theta, shift = _trimmed_fit(layout, poses, shared, tolerance, turn)
        for v in (v for v in layout if v in part):
            placed[v] = BodyPose(rotate_z(layout[v].position, theta) + shift,
                                 math.remainder(layout[v].yaw + theta, 2 * math.pi))
    return placed


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
