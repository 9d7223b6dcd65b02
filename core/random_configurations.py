"""Random legal configurations of any robot, from its description and docking rules.

Used by property tests (the same tests run over every installed robot, built-in or
third-party) and by benchmarks. Deterministic for a given ``numpy`` generator.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .alignment import rot_z
from .bodies import geometry_problems, has_bodies
from .configuration import Configuration
from .robot import DockingRules, RobotSpec

__all__ = ["newly_built", "pointer_configuration", "random_configuration", "random_unit"]


def random_unit(rng: np.random.Generator) -> np.ndarray:
    """A uniformly random unit vector, shape (3,)."""
    while True:
        v = rng.normal(size=3)
        norm = float(np.linalg.norm(v))
        if norm > 1e-9:
            return v / norm


def pointer_configuration(robot: str, kind: str, parent: Sequence[int],
                          rng: np.random.Generator, *, prefix: str = "F") -> Configuration:
    """The configuration of a MISO pointer array (``parent[i]`` the module ``i``
    connects to, ``-1`` none; :func:`msrr.core.freeform.miso.random_miso_tree` draws
    them): modules ``F1``... of ``kind``, random unit connection vectors."""
    config = Configuration(robot)
    for i in range(len(parent)):
        config.add_module(f"{prefix}{i + 1}", kind)
    for i, p in enumerate(parent):
        if p >= 0:
            config.connect(f"{prefix}{i + 1}", f"{prefix}{p + 1}", z=random_unit(rng))
    return config


def _port_pair(rules: DockingRules, spec: RobotSpec, config: Configuration, child: str,
               parent: str, used: set[tuple[str, str]], rng: np.random.Generator
               ) -> tuple[str, str] | None:
    """A compatible free (child port, parent port) pair, chosen at random, or None."""
    child_kind, parent_kind = config.kind_of(child), config.kind_of(parent)
    pairs = [(a.name, b.name) for a in spec.kind(child_kind).ports
             for b in spec.kind(parent_kind).ports
             if (child, a.name) not in used and (parent, b.name) not in used
             and rules.ports_compatible(child_kind, a.name, parent_kind, b.name)]
    return pairs[int(rng.integers(len(pairs)))] if pairs else None


def random_configuration(spec: RobotSpec, rules: DockingRules, n_vertices: int,
                         rng: np.random.Generator, *, extra_edges: int = 0,
                         free_connectors: int = 0, positions: bool = False) -> Configuration:
    """A random configuration of ``spec`` that its docking rules accept.

    The base is a random tree whose every edge points from child to parent, so each
    module makes at most one out-connection (legal for MISO robots too). Robots with
    discrete ports get a random compatible free port pair per edge (a child whose
    ports cannot meet any earlier vertex, or whose body would overlap another where its
    ports place it, is re-attached elsewhere); freeform robots get
    random unit ``z`` (and sometimes ``x``) vectors. Robots whose connections are
    modules (FreeSN struts) can also get ``extra_edges`` closing cycles or doubling
    edges, and ``free_connectors`` struts ending on virtual vertices.

    Args:
        spec: the robot's description.
        rules: its docking rules.
        n_vertices: number of vertex modules, at least 1.
        rng: the random generator (seed it).
        extra_edges: edge-module robots only: extra connections between random modules.
        free_connectors: edge-module robots only: struts with one free end.
        positions: give every module a random position [m].
    """
    vertex_kinds = spec.kinds_with_role("vertex")
    edge_kinds = spec.kinds_with_role("edge")
    ported = not edge_kinds and any(
        rules.ports_compatible(a.name, pa.name, b.name, pb.name)
        for a in vertex_kinds for b in vertex_kinds for pa in a.ports for pb in b.ports)
    config = Configuration(spec.name, name=f"random-{n_vertices}")
    used: set[tuple[str, str]] = set()

    def add_vertex(i: int) -> str:
        vid = f"{vertex_kinds[0].symbol}{i + 1}"
        kind = vertex_kinds[int(rng.integers(len(vertex_kinds)))].name
        config.add_module(vid, kind, position=rng.normal(size=3) if positions else None)
        return vid

    def edge_attrs() -> dict:
        attrs: dict = {}
        if edge_kinds:
            attrs["kind"] = edge_kinds[int(rng.integers(len(edge_kinds)))].name
            attrs["id"] = f"{edge_kinds[0].symbol}{len(config.edges()) + 1}"
        if not ported:
            attrs["z"] = random_unit(rng)
            if rng.random() < 0.5:
                attrs["x"] = random_unit(rng)
        return attrs

    described = ported and has_bodies(spec)
    vertices = [add_vertex(0)]
    for i in range(1, n_vertices):
        child = add_vertex(i)
        for parent in rng.permutation(vertices):
            ports = None
            if ported:
                ports = _port_pair(rules, spec, config, child, str(parent), used, rng)
                if ports is None:
                    continue
            edge = config.connect(child, str(parent), ports=ports, **edge_attrs())
            if described and geometry_problems(config, spec):  # bodies would overlap there
                config.disconnect(edge)
                continue
            if ports is not None:
                used.update({(child, ports[0]), (str(parent), ports[1])})
            break
        else:
            config.remove_module(child)
            continue
        vertices.append(child)
    if edge_kinds:
        for _ in range(extra_edges if len(vertices) > 1 else 0):
            a, b = rng.choice(len(vertices), size=2, replace=False)
            config.connect(vertices[a], vertices[b], **edge_attrs())
        for j in range(free_connectors):
            free = f"v{j + 1}"
            config.add_virtual(free)
            config.connect(vertices[int(rng.integers(len(vertices)))], free, **edge_attrs())
    return config


def newly_built(config: Configuration, rng: np.random.Generator, *, noise: float,
                yaw: float | None = None, prefixes: dict[str, str] | None = None,
                name: str = "") -> Configuration:
    """``config`` as a newly built system would report it (FreeSN paper, section 7: "a
    newly constructed system with any isomorphic labelling"): its modules renamed in a
    random order (``n0, n1, ...`` per kind prefix), the whole turned about the vertical
    by ``yaw``, and each ``z`` tilted by a random angle of standard deviation ``noise``
    about a random axis perpendicular to it. Free connectors (virtual vertices) are
    named after their edge's new id (``s3:b``); forward vectors are turned, not tilted.

    Args:
        config: the configuration (a library configuration, say).
        rng: the random generator (seeded by the caller).
        noise: standard deviation of each vector's tilt [rad].
        yaw: the turn [rad]; uniform in [-pi, pi) when ``None``.
        prefixes: new id prefix per module kind (default its kind's first letter).
        name: the new configuration's name.
    """
    prefixes = prefixes or {}
    vertices: dict[str, str] = {}
    edges: dict[str, str] = {}
    by_kind: dict[str, list[str]] = {}
    for module, kind in config.modules().items():
        by_kind.setdefault(kind, []).append(module)
    for kind, ids in by_kind.items():
        order = rng.permutation(len(ids))
        prefix = prefixes.get(kind, kind[:1])
        for k, j in enumerate(order):
            target = edges if ids[j] in config.edge_ids() else vertices
            target[ids[j]] = f"{prefix}{k}"
    for edge in config.edges():
        new = edges.get(edge.id, edge.id)
        for vertex, end in ((edge.source, "a"), (edge.target, "b")):
            if config.is_virtual(vertex):
                vertices[vertex] = f"{new}:{end}"
    z = {}
    for edge in config.edges():
        if edge.z is None:
            continue
        axis = np.cross(edge.z, random_unit(rng))
        axis /= np.linalg.norm(axis)
        angle = float(rng.normal(scale=noise))
        # Rodrigues: z turned by angle about an axis perpendicular to it
        z[edge.id] = np.cos(angle) * edge.z + np.sin(angle) * np.cross(axis, edge.z)
    turn = float(rng.uniform(-np.pi, np.pi)) if yaw is None else yaw
    return config.derive(z=z, x={e.id: e.x for e in config.edges() if e.x is not None},
                         rotation=rot_z(turn), vertices=vertices, edges=edges,
                         name=name or config.name)
