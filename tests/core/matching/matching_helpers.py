"""Helpers of the matching tests: random multigraph configurations and an isomorphism check."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np

from msrr.core.alignment import rot_z
from msrr.core.configuration import Configuration
from msrr.core.kinematics import FixedNode
from msrr.core.random_configurations import random_unit
from msrr.core.robot import ModuleKind, Robot, RobotSpec

BARS = Robot(RobotSpec("bars", "Bars test robot", (ModuleKind("node", "N", "vertex"),
                                                    ModuleKind("strut", "S", "edge"))),
             joint_modes={"fixed": FixedNode})
"""A robot without module joint modes (only ``fixed``): the matcher falls back to distance."""

if "kin_helpers" not in sys.modules:      # the kinematics tests' ``stick`` robot
    _PATH = Path(__file__).resolve().parents[1] / "kinematics" / "kin_helpers.py"
    _SPEC = importlib.util.spec_from_file_location("kin_helpers", _PATH)
    sys.modules["kin_helpers"] = importlib.util.module_from_spec(_SPEC)
    _SPEC.loader.exec_module(sys.modules["kin_helpers"])
stick = sys.modules["kin_helpers"]
"""``stick.STICK`` (hubs, rods, gimbal joints) and ``stick.triangle_leg()``."""


def random_freesn(rng: np.random.Generator, nodes: int, struts: int, free: int) -> Configuration:
    """A connected FreeSN-like multigraph: a random tree, extra (often parallel) struts, free struts."""
    config = Configuration("freesn", name="random")
    for i in range(nodes):
        config.add_module(f"N{i}", "node")
    count = 0

    def strut(a: str, b: str) -> None:
        nonlocal count
        count += 1
        config.connect(a, b, id=f"S{count}", kind="strut", z=random_unit(rng))

    for i in range(1, nodes):
        strut(f"N{i}", f"N{int(rng.integers(i))}")
    for _ in range(struts):
        a, b = rng.choice(nodes, size=2, replace=False)
        strut(f"N{a}", f"N{b}")
    for k in range(free):
        config.add_virtual(f"v{k}")
        strut(f"N{int(rng.integers(nodes))}", f"v{k}")
    return config


def scrambled(config: Configuration, rng: np.random.Generator, *, yaw: float | None = None,
              noise: float = 0.0) -> Configuration:
    """``config`` under a random yaw and random vertex/edge relabelling, some edges reversed.

    Args:
        noise: standard deviation [rad] of a random tilt added to every vector.
    """
    theta = rng.uniform(-np.pi, np.pi) if yaw is None else yaw
    rotation = rot_z(theta)
    vertices = list(config.vertices())
    new_names = {v: f"r{i}" for v, i in zip(vertices, rng.permutation(len(vertices)), strict=True)}
    edges = config.edges()
    edge_names = {e.id: f"e{i}" for e, i in zip(edges, rng.permutation(len(edges)), strict=True)}
    out = Configuration(config.robot, name="scrambled")
    for v in rng.permutation(vertices):
        out.add_module(new_names[v], config.kind_of(v))
    for k in rng.permutation(len(edges)):
        e = edges[k]
        z = None
        if e.z is not None:
            z = rotation @ e.z + noise * rng.normal(size=3)
            z /= np.linalg.norm(z)
        flip = bool(rng.integers(2)) and not config.is_virtual(e.target)
        source, target = new_names[e.source], new_names[e.target]
        ports = e.ports
        if flip:
            source, target = target, source
            z = None if z is None else -z
            ports = None if ports is None else (ports[1], ports[0])
        out.connect(source, target, id=edge_names[e.id], kind=e.kind, z=z, ports=ports)
    return out


def assert_isomorphism(system: Configuration, reference: Configuration, mapping) -> None:
    """Fail unless ``mapping`` preserves kinds, edges, directions (with inv) and ports."""
    nodes, edges = mapping.nodes, mapping.edges
    assert sorted(nodes) == sorted(system.vertices())
    assert sorted(nodes.values()) == sorted(reference.vertices())
    for v, r in nodes.items():
        assert system.kind_of(v) == reference.kind_of(r)
    assert sorted(edges) == sorted(system.edge_ids())
    assert sorted(f for f, _ in edges.values()) == sorted(reference.edge_ids())
    for e in system.edges():
        f_id, inv = edges[e.id]
        f = reference.edge(f_id)
        assert f.kind == e.kind
        ends = (nodes[e.source], nodes[e.target])
        assert (f.target, f.source) == ends if inv else (f.source, f.target) == ends
        if e.ports is not None or f.ports is not None:
            assert f.ports == ((e.ports[1], e.ports[0]) if inv else e.ports)
