"""Hypothesis strategies of the core tests: small configurations and module maps.

The configurations belong to a tiny robot defined here (no plugin): vertex modules
``node``, connections that are modules (``strut``, FreeSN-like, with ``z``/``x`` and
free ends on virtual vertices) or plain connections with ports (MMRP-like faces).
"""

from __future__ import annotations

import numpy as np
from hypothesis import strategies as st

from msrr.core import Configuration
from msrr.core.mapping import ModuleMap

FACES = ("T", "B", "L", "R")


def _unit(rng: np.random.Generator) -> np.ndarray:
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def strut_configuration(seed: int, nodes: int, extra: int, free: int) -> Configuration:
    """A connected configuration of ``nodes`` nodes joined by struts (a random tree plus
    ``extra`` struts closing cycles) and ``free`` struts with one end on a virtual vertex."""
    rng = np.random.default_rng(seed)
    config = Configuration("tiny", name=f"struts-{seed}")
    for i in range(nodes):
        config.add_module(f"N{i}", "node")
    n = 0

    def strut(source: str, target: str) -> None:
        nonlocal n
        n += 1
        x = _unit(rng) if rng.random() < 0.5 else None
        config.connect(source, target, id=f"S{n}", kind="strut", z=_unit(rng), x=x)

    for i in range(1, nodes):
        strut(f"N{i}", f"N{int(rng.integers(i))}")
    for _ in range(extra if nodes > 1 else 0):
        a, b = rng.choice(nodes, size=2, replace=False)
        strut(f"N{a}", f"N{b}")
    for j in range(free):
        config.add_virtual(f"v{j}")
        node = f"N{int(rng.integers(nodes))}"
        if rng.random() < 0.5:
            strut(node, f"v{j}")
        else:
            strut(f"v{j}", node)
    return config


def face_configuration(seed: int, modules: int) -> Configuration:
    """A random tree of ``modules`` modules connected face to face (each face used once)."""
    rng = np.random.default_rng(seed)
    config = Configuration("tiny", name=f"faces-{seed}")
    used: set[tuple[str, str]] = set()
    config.add_module("0", "cube")
    for i in range(1, modules):
        config.add_module(str(i), "cube")
        for _ in range(100):
            parent = str(int(rng.integers(i)))
            mine, theirs = FACES[int(rng.integers(4))], FACES[int(rng.integers(4))]
            if (parent, theirs) not in used:
                break
        used |= {(parent, theirs), (str(i), mine)}
        config.connect(str(i), parent, ports=(mine, theirs))
    return config


strut_configurations = st.builds(strut_configuration, st.integers(0, 2**32 - 1),
                                 st.integers(1, 6), st.integers(0, 3), st.integers(0, 3))
face_configurations = st.builds(face_configuration, st.integers(0, 2**32 - 1),
                                st.integers(1, 7))
configurations = st.one_of(strut_configurations, face_configurations)


def random_map(config: Configuration, seed: int, prefix: str = "m") -> ModuleMap:
    """A complete map of ``config`` onto fresh ids: vertices and edges shuffled, each edge
    reversed with probability one half (virtual vertices mapped too)."""
    rng = np.random.default_rng(seed)
    vertices = config.vertices()
    order = rng.permutation(len(vertices))
    edges = config.edge_ids()
    edge_order = rng.permutation(len(edges))
    return ModuleMap({v: f"{prefix}{order[i]}" for i, v in enumerate(vertices)},
                     {e: (f"{prefix}e{edge_order[i]}", bool(rng.random() < 0.5))
                      for i, e in enumerate(edges)})


def rewired(config: Configuration, seed: int, changes: int) -> Configuration:
    """``config`` with the same modules and up to ``changes`` random topology changes:
    plain connections removed or added face to face, strut ends moved to another node,
    to a free end or from a free end onto a node."""
    rng = np.random.default_rng(seed)
    out = config.copy()
    nodes = out.vertices(virtual=False)
    for k in range(changes):
        edges = out.edges()
        struts = [e for e in edges if e.kind is not None]
        if struts:
            edge = struts[int(rng.integers(len(struts)))]
            at_source = bool(rng.random() < 0.5)
            old = edge.source if at_source else edge.target
            other = edge.target if at_source else edge.source
            choices = [n for n in nodes if n != other]
            if rng.random() < 0.3 or not choices:
                new = f"free{seed % 1000}-{k}"
                out.add_virtual(new)
            else:
                new = choices[int(rng.integers(len(choices)))]
            out.disconnect(edge.id)
            source, target = (new, edge.target) if at_source else (edge.source, new)
            out.connect(source, target, id=edge.id, kind=edge.kind, z=edge.z, x=edge.x)
            if out.is_virtual(old) and out.degree(old) == 0:
                out.remove_module(old)
        elif edges and rng.random() < 0.5:
            out.disconnect(edges[int(rng.integers(len(edges)))].id)
        elif len(nodes) > 1:
            used = {(e.source, e.ports[0]) for e in edges} | {(e.target, e.ports[1]) for e in edges}
            u, v = (str(n) for n in rng.choice(nodes, size=2, replace=False))
            free_u = [f for f in FACES if (u, f) not in used]
            free_v = [f for f in FACES if (v, f) not in used]
            if free_u and free_v:
                out.connect(u, v, ports=(free_u[int(rng.integers(len(free_u)))],
                                         free_v[int(rng.integers(len(free_v)))]))
    return out


@st.composite
def configuration_pairs(draw: st.DrawFn) -> tuple[Configuration, Configuration]:
    """A configuration and a rewired copy of it (same modules, changed topology)."""
    config = draw(configurations)
    return config, rewired(config, draw(st.integers(0, 2**32 - 1)), draw(st.integers(0, 4)))
