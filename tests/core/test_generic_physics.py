"""The generic mujoco driver's hinge servos: a fold within the torque the description
gives reaches its goal; one beyond it fails saying which hinge stalled, at what bound."""

from __future__ import annotations

from dataclasses import replace

from msrr.core import Configuration, Plan, plugins
from msrr.core.actions import detect_action
from msrr.core.app.testing import run_physics
from msrr.core.bodies import with_port_vectors


def _fold(n: int) -> Plan:
    spec = plugins.robot("hinge")
    chain = Configuration("hinge")
    for i in range(1, n + 1):
        chain.add_module(f"h{i}", "hinge")
    for i in range(1, n):
        chain.connect(f"h{i}", f"h{i + 1}", ports=("head", "tail"))
    ring = chain.copy()
    ring.connect(f"h{n}", "h1", ports=("head", "tail"))
    chain, ring = with_port_vectors(chain, spec), with_port_vectors(ring, spec)
    return Plan("hinge", "test", chain, ring, [detect_action(chain, ring)])


def test_a_servo_too_weak_for_the_fold_fails_naming_the_stalled_hinge() -> None:
    spec = plugins.robot("hinge")
    kind = spec.module_kinds[0]
    weak = replace(spec, module_kinds=(replace(kind, hinge=replace(kind.hinge, torque=0.002)),))
    result = run_physics(_fold(4), weak, action_timeout=60.0)
    assert not result.success
    assert "stalled: hinge h" in result.reason and "its servo at most 0.002 N m" in result.reason
    assert result.sim_time < 30.0  # before the action's timeout (60 s)


def test_the_example_servo_folds_a_chain_of_four_into_a_square() -> None:
    result = run_physics(_fold(4), plugins.robot("hinge"))
    assert result.success, result.reason
    assert result.goal.basis == "ground truth"


def test_a_docked_pair_of_cubes_drives_in_along_the_dock_axis_and_docks() -> None:
    """Two wheeled cubes docked in a row turn only by sliding sideways; they dock a side
    port to a pair at rest without shoving it (once failed after pushing it along)."""
    spec = plugins.robot("cube")
    start = Configuration("cube")
    for m in "abcd":
        start.add_module(m, "cube")
    start.connect("a", "b", ports=("E", "W"))
    start.connect("d", "c", ports=("E", "W"))
    goal = start.copy()
    goal.connect("c", "b", ports=("S", "N"))
    start, goal = with_port_vectors(start, spec), with_port_vectors(goal, spec)
    result = run_physics(Plan("cube", "test", start, goal, [detect_action(start, goal)]),
                         spec, seed=1)
    assert result.success, result.reason
    assert result.goal.basis == "ground truth" and result.goal.shape.within
