"""The S12N6 figure scenarios fig21 and fig22 (issue 13, paper Figs. 21, 22): planned at
prepare time through the parallel connections and disconnections of the library; the
fig22 rollers' gains checked in simulation (the full runs are in docs/freesn.md)."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest

from msrr.core import plugins
from msrr.core.app.run import RunRequest, prepare_run, resolve_scenario
from msrr.core.configuration import Configuration
from msrr.core.driver import ModuleCommand
from msrr.core.io import load_configuration
from msrr.core.library import load_library
from msrr.core.plan import ActionType
from msrr.core.shape import skeletal_error
from msrr.plugins.freesn.robot import NODE, STRUT
from msrr.plugins.freesn.sim import FreeSNMujocoDriver

FREESN = Path(__file__).resolve().parents[3] / "plugins" / "freesn"
PARALLEL = (ActionType.PARALLEL_CONNECTION, ActionType.PARALLEL_DISCONNECTION)


def test_fig21_reaches_the_tree_and_the_star_by_parallel_actions(tmp_path):
    prepared = prepare_run(RunRequest(robot="freesn", scenario="fig21", out=tmp_path / "run",
                                      log=False))
    plan = prepared.run.plan
    assert [a.reaches for a in plan.actions if a.reaches] == ["S12N6-7.1", "S12N6-2.1"]
    parallel = [a for a in plan.actions if a.type in PARALLEL]
    # out: dock R6 and C1 together, undock R1 and R4 together; back: the reverse
    assert [a.type for a in parallel] == list(PARALLEL) * 2
    assert all(len(a.changes) == 2 for a in parallel)
    tree = next(i for i, a in enumerate(plan.actions) if a.reaches == "S12N6-7.1")
    assert plan.actions[tree].type is ActionType.PARALLEL_DISCONNECTION
    reached = plan.actions[tree].target
    assert reached.is_connected() and len(reached.edges()) == 12
    assert sum(not reached.is_virtual(e.target) for e in reached.edges()) == 5   # a tree
    star = plugins.load_configuration(FREESN / "configs" / "library" / "S12N6-2.1.json")
    assert skeletal_error(plan.goal, star) < 1e-9                    # back where it began
    assert (plan.docks, plan.undocks) == (5, 5)


def test_fig22_frees_a_face_drives_twice_and_closes_the_octahedron(tmp_path):
    prepared = prepare_run(RunRequest(robot="freesn", scenario="fig22", out=tmp_path / "run",
                                      log=False))
    plan = prepared.run.plan
    behaviors = [a for a in plan.actions if a.type is ActionType.BEHAVIOR]
    assert [(a.behavior.name, a.behavior.parameters["speed"]) for a in behaviors] == [
        ("wheeled-move", 0.05), ("node-wheels", 0.03)]
    assert plan.actions[0].type is ActionType.MOVING   # onto the octahedron of the library
    first = plan.actions[1]     # then the bottom face's three chords undock at once
    assert first.type is ActionType.PARALLEL_DISCONNECTION and len(first.changes) == 3
    assert plan.actions[-1].type is ActionType.PARALLEL_CONNECTION
    assert (plan.docks, plan.undocks) == (4, 4)
    # the rollers are the three struts the first action freed, in the system's own ids
    assert {c.module for c in behaviors[0].behavior.commands} == {c.edge_id
                                                                  for c in first.changes}
    start = plugins.load_configuration(resolve_scenario("freesn", "fig22").start)
    assert sorted(plan.goal.edge_ids()) == sorted(start.edge_ids())  # its own ids
    octahedron = plugins.load_configuration(FREESN / "configs" / "library" / "S12N6-1.1.json")
    assert skeletal_error(plan.goal, octahedron) < 1e-9             # back where it began


def _node_positions(config: Configuration) -> dict[str, np.ndarray]:
    """Node centres [m] from the docked struts' ``z`` (one strut length each), the lowest
    node's centre one node radius above the floor (z = 0)."""
    length = STRUT.geometry["length"]
    first = config.vertices(virtual=False)[0]
    pos, todo = {first: np.zeros(3)}, [first]
    while todo:
        v = todo.pop()
        for e in config.incident(v):
            if config.is_virtual(e.source) or config.is_virtual(e.target):
                continue
            w, sign = (e.target, 1.0) if e.source == v else (e.source, -1.0)
            if w not in pos:
                pos[w] = pos[v] + sign * length * np.asarray(e.z)
                todo.append(w)
    lift = NODE.geometry["radius"] - min(p[2] for p in pos.values())
    return {v: p + [0.0, 0.0, lift] for v, p in pos.items()}


def _turned(a: np.ndarray, b: np.ndarray, angle: float, lowest: float) -> np.ndarray:
    """``a`` turned toward ``b`` along their great circle by at most ``angle`` [rad] (a
    connector's servo at its speed bound), its ``z`` kept at least ``lowest`` (the
    floor under the strut's far end)."""
    full = math.acos(float(np.clip(a @ b, -1.0, 1.0)))
    f = 1.0 if full < 1e-9 else min(angle, full) / full
    z = b if full < 1e-9 else (math.sin((1 - f) * full) * a + math.sin(f * full) * b) \
        / math.sin(full)
    if z[2] < lowest:
        flat = math.hypot(z[0], z[1])
        z = np.array([z[0] / flat * math.sqrt(1 - lowest ** 2),
                      z[1] / flat * math.sqrt(1 - lowest ** 2), lowest])
    return z


def _free_strut_clearance(before: Configuration, after: Configuration
                          ) -> tuple[float, tuple[str, str]]:
    """The smallest gap [m] between the bodies of two struts free at one end while each
    turns from ``before`` to ``after`` at one common rate, the nodes held where ``before``
    puts them: negative where their capsules would pass through each other."""
    length, radius = STRUT.geometry["length"], STRUT.geometry["radius"]
    inner = NODE.geometry["radius"] + radius            # the capsule's axis starts here
    along = np.linspace(inner, length - inner, 12)
    pos = _node_positions(before)
    free = [e.id for e in after.edges()
            if after.is_virtual(e.target) or before.is_virtual(before.edge(e.id).target)]
    worst = (math.inf, ("", ""))
    for angle in np.linspace(0.0, math.pi, 91):
        axes = {}
        for sid in free:
            base = pos[before.edge(sid).source]
            lowest = -(base[2] - radius) / (length - inner)   # the far end's floor
            z = _turned(np.asarray(before.edge(sid).z), np.asarray(after.edge(sid).z),
                        angle, max(-1.0, lowest))
            axes[sid] = base + along[:, None] * z
        for i, j in itertools.combinations(free, 2):
            gap = float(np.min(np.linalg.norm(axes[i][:, None] - axes[j][None], axis=2)))
            worst = min(worst, (gap - 2 * radius, (i, j)))
    return worst


@pytest.mark.parametrize("scenario", ["fig21", "fig22"])
def test_s12n6_figures_move_no_free_strut_through_another(tmp_path, scenario):
    """Every move of the plan turns its free struts clear of each other (issue 31): in
    fig22, through ``aim-j`` (the closed face's chord directions) the release of R6 turned
    C4 and C6 toward each other along the floor onto the same segment B2-B3; they jammed
    there (C6 pressed on C4 for 30 s even with exact sensors) and under 2 deg of noise
    the move stalled (seeds 12, 17, 19)."""
    plan = prepare_run(RunRequest(robot="freesn", scenario=scenario, out=tmp_path / "run",
                                  log=False)).run.plan
    before = plan.start
    for index, action in enumerate(plan.actions):
        if action.type is ActionType.BEHAVIOR:
            continue
        gap, pair = _free_strut_clearance(before, action.target)
        assert gap > 0.01, f"action {index + 1} ({action.note}): {pair} {gap * 1000:.0f} mm"
        before = action.target


@pytest.mark.parametrize("drive, speed", itertools.product(["holonomic", "differential"],
                                                            [0.05, -0.05]))
def test_fig22e_rollers_drive_the_octahedron_along_the_library_x(drive, speed):
    """Fig. 22(e): the wheeled move's gains (``design.py: roller_commands``) roll the three
    freed chords, pressed onto the floor, about their axes: the structure goes along
    ``+x`` for a positive speed (ground truth; the other connectors hold). With
    differential connectors too (stop 50: 0.29 of the asked speed; 0.19 before, the
    rollers' aim taking the wheels' voltage from their spin)."""
    library = load_library(FREESN / "libraries" / "S12N6.json")
    behavior = library.sublibraries["S12N6"].behaviors["wheeled-move"]
    start = load_configuration(FREESN / "configs" / "library" / f"{behavior.start}.json")
    wheels: dict[str, dict[str, float]] = {}
    for command in behavior.commands:
        wheels.setdefault(command.module, {})[command.connector] = command.value(
            {"speed": speed, "yaw_rate": 0.0})
    assert set(wheels) == {"C2", "C4", "C6"}
    with FreeSNMujocoDriver(connector_drive=drive) as driver:
        driver.reset(start)
        driver.step(0.5)
        world = driver.world
        before = world.data.xpos[world._node_body].mean(axis=0).copy()
        driver.send_action({m: ModuleCommand(wheels=w) for m, w in wheels.items()})
        driver.step(2.0)
        velocity = (world.data.xpos[world._node_body].mean(axis=0) - before) / 2.0
    assert 0.25 < velocity[0] / speed < 1.2
    assert abs(velocity[1]) < 0.1 * abs(velocity[0])
    assert np.ptp(world.data.xpos[world._node_body][:, 2]) > 0.15   # still standing
