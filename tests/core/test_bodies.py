"""Geometry of described modules (msrr.core.bodies): port frames, docked poses, derived
vectors and consistency checks, against independent constructions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from msrr.core import (
    Body,
    Configuration,
    Hinge,
    ModuleKind,
    PluginError,
    PortSpec,
    Robot,
    RobotSpec,
)
from msrr.core.bodies import (
    body_reach,
    close_loops,
    docked_pose,
    even_bend,
    geometry_problems,
    layout,
    port_frame,
    port_mismatch,
    rotation_about,
    with_port_vectors,
)

FACES = {"E": (1.0, 0.0, 0.0), "N": (0.0, 1.0, 0.0), "W": (-1.0, 0.0, 0.0),
         "S": (0.0, -1.0, 0.0)}
CUBE = ModuleKind("cube", "C", "vertex", tuple(PortSpec(n, "neutral", v) for n, v in FACES.items()),
                  body=Body(shape="box", size=(0.1, 0.1, 0.08), mass=0.4))
SPEC = RobotSpec("cubes", "cubes", (CUBE,))
LINK = ModuleKind("link", "L", "vertex", (
    PortSpec("head", "active", (1.0, 0.0, 0.0), position=(0.095, 0.0, 0.0)),
    PortSpec("tail", "passive", (-1.0, 0.0, 0.0), position=(-0.095, 0.0, 0.0))),
    body=Body(shape="box", size=(0.1, 0.03, 0.03), mass=0.2), hinge=Hinge(port="head"))
LINKS = RobotSpec("links", "links", (LINK,))


def _cubes(*links: tuple[str, str, str, str], n: int = 4) -> Configuration:
    config = Configuration("cubes")
    for i in range(1, n + 1):
        config.add_module(f"c{i}", "cube")
    for a, pa, b, pb in links:
        config.connect(a, b, ports=(pa, pb))
    return config


def test_ports_sit_on_the_body_where_their_normal_leaves_it() -> None:
    for name, normal in FACES.items():
        rotation, position = port_frame(CUBE, name)
        assert np.allclose(position, np.array(normal) * 0.05)
        assert np.allclose(rotation @ rotation.T, np.eye(3))
        assert np.allclose(rotation[:, 0], normal) and np.allclose(rotation[:, 2], (0, 0, 1))
    ball = ModuleKind("ball", "B", "vertex", (PortSpec("p", normal=(0.6, 0.0, 0.8)),),
                      body=Body(shape="sphere", size=(0.07,), mass=1.0))
    assert math.isclose(body_reach(ball, np.array([0.6, 0.0, 0.8])), 0.07, rel_tol=1e-9)
    capsule = ModuleKind("cap", "K", "vertex", (PortSpec("p", normal=(1.0, 0.0, 0.0)),),
                         body=Body(shape="capsule", size=(0.02, 0.1), mass=1.0))
    assert math.isclose(body_reach(capsule, np.array([1.0, 0.0, 0.0])), 0.07, rel_tol=1e-9)


def test_docked_ports_coincide_with_opposite_normals_and_equal_ups() -> None:
    for a in FACES:
        for b in FACES:
            rotation, position = docked_pose((CUBE, CUBE), (a, b))
            (ra, pa), (rb, pb) = port_frame(CUBE, a), port_frame(CUBE, b)
            assert np.allclose(rotation @ pb + position, pa)          # same point
            assert np.allclose(rotation @ rb[:, 0], -ra[:, 0])        # normals opposite
            assert np.allclose(rotation @ rb[:, 2], ra[:, 2])         # ups equal
            gap, turn = port_mismatch((np.eye(3), np.zeros(3)), (rotation, position),
                                      (CUBE, CUBE), (a, b))
            assert np.allclose(gap, 0.0) and np.allclose(turn, 0.0)


def test_a_hinge_turns_about_its_axis_through_the_port() -> None:
    angle = 0.7
    rotation, position = docked_pose((LINK, LINK), ("head", "tail"), angle)
    assert np.allclose(rotation, rotation_about(np.array([0.0, 0.0, 1.0]), angle))
    tail = rotation @ np.array([-0.095, 0.0, 0.0]) + position
    assert np.allclose(tail, (0.095, 0.0, 0.0))  # the tail stays on the head's port


def test_derived_vectors_follow_the_ports() -> None:
    line = with_port_vectors(_cubes(("c1", "E", "c2", "W"), ("c2", "N", "c3", "S"), n=3), SPEC)
    z = {e.id: np.round(e.z, 9) for e in line.edges()}
    assert np.allclose(z["c1E-c2W"], (1, 0, 0)) and np.allclose(z["c2N-c3S"], (0, 1, 0))
    assert all(np.allclose(e.x, (0, 0, 1)) for e in line.edges())


def test_a_loop_of_rigid_ports_must_close_and_bodies_must_not_overlap() -> None:
    square = _cubes(("c1", "E", "c2", "W"), ("c2", "N", "c3", "S"), ("c3", "W", "c4", "E"),
                    ("c4", "S", "c1", "N"))
    assert geometry_problems(square, SPEC) == []
    twisted = _cubes(("c1", "E", "c2", "W"), ("c2", "N", "c3", "S"), ("c3", "W", "c4", "E"),
                     ("c4", "E", "c1", "N"))
    found = geometry_problems(twisted, SPEC)
    assert found and "does not close" in found[0][1]
    assert [str(v) for v in Robot(SPEC).violations(twisted)] == [f"{w}: {m}" for w, m in found]
    crowded = _cubes(("c1", "E", "c2", "W"), ("c2", "N", "c3", "S"), ("c3", "W", "c4", "E"),
                     ("c4", "S", "c5", "N"), n=5)  # c5 lands on c1
    assert geometry_problems(crowded, SPEC) == [
        ("module c1", "overlaps module c5 where the ports place them")]


def test_hinges_fold_a_chain_shut() -> None:
    chain = Configuration("links")
    for i in range(1, 5):
        chain.add_module(f"h{i}", "link")
    for i in range(1, 4):
        chain.connect(f"h{i}", f"h{i + 1}", ports=("head", "tail"))
    angles, gap = close_loops(chain, LINKS, [("h4", "head", "h1", "tail")], {})
    assert gap < 1e-4
    poses, _ = layout(chain, LINKS, angles)
    head = poses["h4"][0] @ np.array([0.095, 0, 0]) + poses["h4"][1]
    tail = poses["h1"][0] @ np.array([-0.095, 0, 0]) + poses["h1"][1]
    assert np.linalg.norm(head - tail) < 1e-4  # forward kinematics agrees


@pytest.mark.parametrize("n", [4, 10, 30])
def test_a_ring_of_like_hinges_folds_into_a_regular_polygon(n: int) -> None:
    """The least even bend that closes a planar ring of n like links is 2 pi / n (one
    turn; 4 pi / n would wind it twice), and close_loops keeps it."""
    chain = Configuration("links")
    for i in range(1, n + 1):
        chain.add_module(f"h{i}", "link")
    for i in range(1, n):
        chain.connect(f"h{i}", f"h{i + 1}", ports=("head", "tail"))
    closing = [(f"h{n}", "head", "h1", "tail")]
    start = even_bend(chain, LINKS, closing)
    assert all(a == pytest.approx(2 * math.pi / n, abs=1e-4) for a in start.values())
    angles, gap = close_loops(chain, LINKS, closing, start)
    assert gap < 1e-6
    assert all(a == pytest.approx(2 * math.pi / n, abs=1e-4) for a in angles.values())


@pytest.mark.parametrize(("make", "needle"), [
    (lambda: PortSpec("p", "master", (1.0, 0.0, 0.0)), "role must be one of active, passive"),
    (lambda: PortSpec("p", normal=(1.0, 1.0, 0.0)), "normal must be a unit vector"),
    (lambda: PortSpec("p", normal=(1.0, 0.0, 0.0), up=(1.0, 0.0, 0.0)), "perpendicular"),
    (lambda: Body(shape="cone", size=(1.0,), mass=1.0), "Body.shape must be one of"),
    (lambda: Body(shape="box", size=(0.1, 0.1), mass=1.0), "Body.size of a box"),
    (lambda: Body(shape="sphere", size=(0.1,), mass=0.0), "Body.mass must be"),
    (lambda: ModuleKind("k", "K", "vertex", (PortSpec("p", normal=(1.0, 0.0, 0.0)),),
                        body=Body(shape="sphere", size=(0.1,), mass=1.0),
                        hinge=Hinge(port="q")), "hinge at unknown port"),
])
def test_bad_descriptions_are_refused_in_one_line(make, needle) -> None:
    with pytest.raises(PluginError, match=needle) as info:
        make()
    assert "\n" not in str(info.value)
