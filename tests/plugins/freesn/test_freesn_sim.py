"""FreeSN in MuJoCo: the world, actuation, identification and controllers (issue 12).

Judged on the simulator's ground truth (:meth:`FreeSNWorld.ground_truth`, body poses
and active constraints), never on what the recognizer says.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import networkx as nx
import numpy as np
import pytest
from scipy.integrate import quad
from scipy.spatial.transform import Rotation

from msrr.core import Configuration, plugins
from msrr.core.actions import detect_actions, topology_diff
from msrr.core.alignment import rot_z
from msrr.core.driver import ModuleCommand
from msrr.core.errors import ExecutionError
from msrr.core.events import Run
from msrr.core.executor import Executor, ExecutorOptions
from msrr.core.freeform.mujoco import heading
from msrr.core.generic import is_generic
from msrr.core.io import load_configuration
from msrr.core.library import load_library
from msrr.core.plan import Plan
from msrr.core.shape import skeletal_errors
from msrr.plugins.freesn.joints import JOINT_MODES
from msrr.plugins.freesn.robot import SPEC
from msrr.plugins.freesn.sim import (
    FOLLOW_EFFORT,
    FreeSNController,
    FreeSNMujocoDriver,
    FreeSNRecognizer,
    FreeSNWorld,
    NodeReport,
    SimOptions,
    StrutReport,
    bridges,
    connector_commands,
    driving_ends,
)
from msrr.plugins.freesn.sim.geometry import place
from msrr.plugins.freesn.sim.recognizer import node_headings, root_order
from msrr.plugins.freesn.sim.world import INTERPENETRATION, magnet_pull

FREESN = Path(__file__).resolve().parents[3] / "plugins" / "freesn"
LIBRARIES = {name: load_library(FREESN / "libraries" / f"{name}.json")
             for name in ("S4N5", "S6N3", "S12N6")}


def _shipped() -> list[tuple[str, Configuration]]:
    found = [(f"configs/{p.stem}", load_configuration(p))
             for p in sorted((FREESN / "configs").glob("*.json"))]
    for name, library in LIBRARIES.items():
        for sub in library.sublibraries.values():
            found += [(f"{name}/{c.id}", c.configuration) for c in sub.configurations.values()]
    return found


SHIPPED = _shipped()


def _library_config(library: str, config_id: str) -> Configuration:
    sub = next(iter(LIBRARIES[library].sublibraries.values()))
    return sub.configurations[config_id].configuration


def _lowered(config: Configuration, down: float) -> Configuration:
    """``config`` with every free strut (a leg) tilted ``down`` [rad] below the horizon."""
    z = {}
    for edge in config.edges():
        z[edge.id] = edge.z
        if config.is_virtual(edge.target):
            h = edge.z[:2] / np.linalg.norm(edge.z[:2])
            z[edge.id] = np.array([h[0] * np.cos(down), h[1] * np.cos(down), -np.sin(down)])
    return config.with_vectors(z=z)


# -- the world -------------------------------------------------------------------------


@pytest.mark.parametrize("label, config", SHIPPED, ids=[label for label, _ in SHIPPED])
def test_every_shipped_configuration_loads_and_rests_one_second(label, config):
    world = FreeSNWorld(config, SPEC, SimOptions())
    start = world.ground_truth()
    assert not topology_diff(start, config), "the world starts in the configuration's topology"
    world.step(1.0)
    assert np.all(np.isfinite(world.data.qpos)) and np.all(np.isfinite(world.data.qvel))
    assert world.constraint_residual() < 1e-3, "an active dock drifted off its node centre"
    assert not world.interpenetrations, "bodies sank into each other at rest"
    assert not world.events, f"connections broke at rest: {world.events}"
    assert world.docked_pairs() == {(e.id, end, n) for e in config.edges()
                                    for end, n in (("a", e.source), ("b", e.target))
                                    if not config.is_virtual(n)}


def test_placement_follows_z_for_trees_and_closes_loops_with_strut_length():
    tree = _library_config("S6N3", "S6N3-1.1")
    placed = place(tree, 0.2, 0.05, 0.02)
    assert placed.mismatch < 1e-5
    for edge in tree.edges():
        if not tree.is_virtual(edge.target):
            span = placed.nodes[edge.target] - placed.nodes[edge.source]
            assert np.allclose(span, 0.2 * edge.z, atol=1e-6)
    octahedron = _library_config("S12N6", "S12N6-1.1")  # its shipped z do not close
    placed = place(octahedron, 0.2, 0.05, 0.02)
    for a, b in placed.ends.values():
        assert abs(np.linalg.norm(placed.nodes[b] - placed.nodes[a]) - 0.2) < 1e-6
    centres = np.array(list(placed.nodes.values()))
    gaps = np.linalg.norm(centres[:, None] - centres[None], axis=2)[np.triu_indices(6, 1)]
    assert sorted(np.round(gaps / 0.2, 4)) == [1.0] * 12 + [1.4142] * 3  # a regular octahedron


def test_heading_is_the_twist_about_the_vertical():
    rng = np.random.default_rng(4)
    for _ in range(20):
        yaw = rng.uniform(-np.pi, np.pi)
        axis = np.r_[rng.normal(size=2), 0.0]
        swing = Rotation.from_rotvec(axis / np.linalg.norm(axis) * rng.uniform(0, 1.2))
        q = (Rotation.from_matrix(rot_z(yaw)) * swing).as_quat(scalar_first=True)
        assert abs(np.angle(np.exp(1j * (heading(q) - yaw)))) < 1e-9


def test_connector_breaks_when_its_load_exceeds_the_connection_strength():
    config = _library_config("S6N3", "S6N3-1.1")   # standing on three legs
    world = FreeSNWorld(config, SPEC, SimOptions(strength_factor=0.02))  # 0.8 N
    world.step(0.3)
    broken = [e for e in world.events if e.kind == "break"]
    assert broken and all(e.load > world.phys.strength for e in broken)
    assert {(e.strut, e.end, e.node) for e in broken}.isdisjoint(world.docked_pairs())


def test_a_connector_pressed_onto_its_node_does_not_count_the_press_against_the_magnet():
    """The S4N5 standup's feet carry their legs: ~3.9 N on each foot's connection, ~2.6 N
    of it pressing the connector onto the node (contact carries that), ~3 N shear. At a
    3.5 N strength none breaks; the whole force would have broken all four."""
    config = _library_config("S4N5", "S4N5-1.2")
    strength = 3.5
    hardware = SPEC.kind("strut").geometry["connection_strength"]
    world = FreeSNWorld(config, SPEC, SimOptions(strength_factor=strength / hardware))
    world.step(1.0)
    assert not [e for e in world.events if e.kind == "break"]
    feet = [k for k, node in enumerate(world.docked) if node in {"N1", "N2", "N3", "N4"}]
    assert len(feet) == 4 and all(2.5 < world._load[k] < strength for k in feet)


# -- actuation: docking ----------------------------------------------------------------


def test_dock_engages_only_within_tolerance_and_undock_releases():
    aimed = _library_config("S6N3", "S6N3-2.3")  # S5's free end on N1's centre
    driver = FreeSNMujocoDriver()
    with driver:
        driver.reset(aimed)
        driver.step(0.1)
        assert ("S5", "b", "N1") not in driver.world.docked_pairs()  # magnet not extended
        driver.send_action({"S5": ModuleCommand(dock=("b",))})
        driver.step(0.1)
        assert ("S5", "b", "N1") in driver.world.docked_pairs()
        assert [(e.kind, e.strut, e.end, e.node) for e in driver.world.events] == [
            ("dock", "S5", "b", "N1")]
        driver.send_action({"S5": ModuleCommand(undock=("b",))})
        driver.step(0.1)
        assert ("S5", "b", "N1") not in driver.world.docked_pairs()
        report = driver.get_observation().sensors["S5"]
        assert report.docked["b"] is None and report.magnet["b"] == "retracted"
        assert [e.kind for e in report.events] == ["dock", "undock"]
    legs = _library_config("S6N3", "S6N3-1.1")  # free ends far from every node
    world = FreeSNWorld(legs, SPEC, SimOptions())
    world.command_dock("S4", "b")
    world.step(0.3)
    assert world.magnet[world.ends.index(("S4", "b"))] == "extended" and not world.events


def test_driver_is_registered_and_rejects_unknown_commands():
    assert plugins.drivers.get("freesn", "mujoco") is FreeSNMujocoDriver
    assert isinstance(plugins.recognizers.get("freesn", "freesn"), FreeSNRecognizer)
    own = {n for n, c in plugins.controllers("freesn").items() if not is_generic(c)}
    assert own == {n.controller for n in JOINT_MODES}  # the generic runtime's come after
    with pytest.raises(ExecutionError, match="unknown MuJoCo driver option"):
        FreeSNMujocoDriver(noize=1.0)
    with FreeSNMujocoDriver(seed=1) as driver:
        driver.reset(_library_config("S6N3", "S6N3-1.1"))
        for commands, message in (
                ({"S99": ModuleCommand()}, "unknown module"),
                ({"S4": ModuleCommand(joints={"a.dir_x": 1.0})}, "given together"),
                ({"S4": ModuleCommand(joints={"a.speed": 1.0})}, "unknown joint"),
                ({"S4": ModuleCommand(dock=("c",))}, "unknown connector"),
                ({"N1": ModuleCommand(dock=("a",))}, "takes no command")):
            with pytest.raises(ExecutionError, match=message):
                driver.send_action(commands)


def test_a_command_that_names_no_wheels_stops_them():
    """A ``ModuleCommand`` is one tick's: wheels a strut's next command leaves out stop
    (before, they ran on at the last speed into the next action)."""
    with FreeSNMujocoDriver(seed=1) as driver:
        driver.reset(_library_config("S6N3", "S6N3-1.1"))
        driver.send_action({"S4": ModuleCommand(wheels={"b": 2.0})})
        driver.step(0.1)
        assert driver.world.wheel_speed("S4", "b") == 2.0
        driver.send_action({"S4": ModuleCommand(wheels={"a": 1.0})})
        assert (driver.world.wheel_speed("S4", "a"), driver.world.wheel_speed("S4", "b")) \
            == (1.0, 0.0)


# -- identification --------------------------------------------------------------------


@pytest.mark.parametrize("library, config_id", [("S6N3", "S6N3-1.1"), ("S6N3", "S6N3-2.1"),
                                                ("S12N6", "S12N6-2.1")])
def test_recognizer_matches_ground_truth(library, config_id):
    config = _library_config(library, config_id)
    exact = FreeSNWorld(config, SPEC, SimOptions())
    noisy = FreeSNWorld(config, SPEC, SimOptions(noise=np.radians(2.0), seed=7))
    for world in (exact, noisy):
        world.step(0.2)
    recognizer = FreeSNRecognizer()
    truth = exact.ground_truth()
    seen = recognizer.recognize(exact.reports())
    assert not topology_diff(seen, truth) and set(seen) == set(truth)
    rms, angles, yaw = skeletal_errors(seen, truth)
    assert angles.max() < np.radians(1.0) and abs(yaw) < np.radians(1.0)
    rms, angles, _ = skeletal_errors(recognizer.recognize(noisy.reports()), noisy.ground_truth())
    assert np.radians(0.5) < rms < np.radians(6.0), "2 deg noise gives a bounded error"


def _reports(config: Configuration, rng: np.random.Generator) -> tuple[dict, dict]:
    """Noise-free module reports of ``config`` (world frame) with random node orientations,
    and the node headings [rad]."""
    frames = {n: Rotation.random(random_state=rng).as_matrix() for n in config.vertices()
              if not config.is_virtual(n)}
    yaws = {n: heading(Rotation.from_matrix(r).as_quat(scalar_first=True))
            for n, r in frames.items()}
    located: dict[str, dict] = {n: {} for n in frames}
    reports: dict = {}
    for edge in config.edges():
        strut = np.column_stack([edge.x, np.cross(edge.z, edge.x), edge.z])
        docked, attitude = {}, {}
        for end, node, sign in (("a", edge.source, 1.0), ("b", edge.target, -1.0)):
            if config.is_virtual(node):
                docked[end] = None
                continue
            docked[end] = node
            located[node][f"{edge.id}:{end}"] = frames[node].T @ (sign * edge.z)
            attitude[end] = rot_z(-float(yaws[node])) @ strut
        reports[edge.id] = StrutReport(docked, attitude, np.eye(3), {"a": "neutral",
                                                                      "b": "neutral"})
    for node, frame in frames.items():
        reports[node] = NodeReport(rot_z(-float(yaws[node])) @ frame, located[node])
    return reports, yaws


@pytest.mark.parametrize("library, config_id", [("S6N3", "S6N3-4.1"), ("S12N6", "S12N6-1.1"),
                                                ("S4N5", "S4N5-2.1")])
def test_recognizer_round_trips_synthetic_reports(library, config_id):
    """Reports made by hand (no simulator) from a configuration give it back exactly."""
    config = _library_config(library, config_id)
    x = {e.id: np.cross(e.z, [0.3, -0.5, 0.8]) / np.linalg.norm(np.cross(e.z, [0.3, -0.5, 0.8]))
         for e in config.edges()}
    config = config.with_vectors(x=x)
    root = config.vertices()[0]
    reports, headings = _reports(config, np.random.default_rng(3))
    seen = FreeSNRecognizer(root=root).recognize(reports)
    assert not topology_diff(seen, config)
    to_root = rot_z(-float(headings[root]))  # output frame: the root's horizontal frame
    for edge in config.edges():
        assert np.allclose(seen.edge(edge.id).z, to_root @ edge.z, atol=1e-9)
        assert np.allclose(seen.edge(edge.id).x, to_root @ edge.x, atol=1e-9)
        assert {seen.edge(edge.id).source, seen.edge(edge.id).target} == {edge.source, edge.target}


# -- controllers -----------------------------------------------------------------------


@pytest.mark.parametrize("noise, slip", [(0.0, 0.0), (np.radians(2.0), 0.05)])
def test_moving_action_reaches_a_nearby_configuration(noise, slip):
    """S6N3 standing on three legs crouches (legs 45 -> 30 deg below the horizon)."""
    start = _library_config("S6N3", "S6N3-1.1")
    goal = _lowered(start, np.radians(30.0))
    assert skeletal_errors(start, goal)[0] > np.radians(8.0)
    controller = FreeSNController()
    with FreeSNMujocoDriver(noise=noise, slip=slip, drift=np.radians(0.5), seed=5) as driver:
        driver.reset(start)
        for _ in range(30):
            driver.send_action(controller.commands(goal, driver.get_observation()))
            driver.step(0.1)
        truth = driver.world.ground_truth()
        assert not driver.world.events
    rms, _, _ = skeletal_errors(truth, goal)
    assert rms < np.radians(5.0), f"{np.degrees(rms):.1f} deg RMS from the goal"


def test_revolute_controller_turns_a_strut_about_its_axis():
    start = _library_config("S6N3", "S6N3-1.1")
    with FreeSNMujocoDriver() as driver:
        driver.reset(start)
        current = driver.world.ground_truth()
        turn = Rotation.from_rotvec(current.edge("S4").z * np.radians(40.0)).as_matrix()
        goal = current.with_vectors(x={e.id: (turn @ e.x if e.id == "S4" else e.x)
                                       for e in current.edges()})
        controller = FreeSNController("revolute")
        for _ in range(20):
            commands = controller.commands(goal, driver.get_observation())
            assert "a.fwd_x" in commands["S4"].joints
            driver.send_action(commands)
            driver.step(0.1)
        reached = driver.world.ground_truth().edge("S4").x
    assert np.degrees(np.arccos(np.clip(reached @ goal.edge("S4").x, -1, 1))) < 5.0


def _drive(driver, controller, goal, ticks, extra=None):
    """Command ``goal`` for ``ticks`` ticks of 0.1 s, the yaw fixed at the start."""
    yaw = skeletal_errors(FreeSNRecognizer().recognize(driver.get_observation().sensors), goal)[2]
    for _ in range(ticks):
        commands = dict(controller.commands(goal, driver.get_observation(), yaw=yaw))
        for strut, command in (extra or {}).items():
            base = commands.get(strut, ModuleCommand())
            commands[strut] = ModuleCommand(joints=base.joints, dock=command.dock,
                                            undock=command.undock)
        driver.send_action(commands)
        driver.step(0.1)


def test_connection_then_disconnection_by_connector_commands():
    """S6N3: swing a leg onto a node, dock it (a loop closes), undock it, swing it back."""
    flat, aimed, docked = (_library_config("S6N3", k) for k in ("S6N3-2.2", "S6N3-2.3",
                                                                 "S6N3-3.1"))
    controller = FreeSNController()
    with FreeSNMujocoDriver(noise=np.radians(2.0), slip=0.05, seed=11) as driver:
        driver.reset(flat)
        _drive(driver, controller, aimed, 40)                      # moving (150 deg swing)
        assert skeletal_errors(driver.world.ground_truth(), aimed)[0] < np.radians(5.0)
        _drive(driver, controller, docked, 10, {"S5": ModuleCommand(dock=("b",))})
        truth = driver.world.ground_truth()
        assert not topology_diff(truth, docked), "S5's free end docked on N1"
        assert skeletal_errors(truth, docked)[0] < np.radians(5.0)
        _drive(driver, controller, aimed, 3, {"S5": ModuleCommand(undock=("b",))})
        _drive(driver, controller, flat, 40)
        truth = driver.world.ground_truth()
        assert not topology_diff(truth, flat)
        assert skeletal_errors(truth, flat)[0] < np.radians(5.0)
        kinds = [(e.kind, e.strut, e.end, e.node) for e in driver.world.events]
    assert kinds == [("dock", "S5", "b", "N1"), ("undock", "S5", "b", "N1")]


def test_driving_ends_form_one_spanning_tree_of_locks():
    config = _library_config("S6N3", "S6N3-3.1")  # triangle, two legs on N1, one on N3
    links = {(e.id, end): n for e in config.edges()
             for end, n in (("a", e.source), ("b", e.target)) if not config.is_virtual(n)}
    driving = driving_ends(links)
    loops = [e.id for e in config.edges() if not config.is_virtual(e.target)]
    tree = [(s, end) for s, end in driving if s in loops]
    assert len(tree) == 2, "three nodes: two struts lock them, the rest follow"
    root = root_order({"N1", "N2", "N3"}, links)[0]
    reached = {root} | {links[(s, "b" if end == "a" else "a")] for s, end in tree}
    assert reached == {"N1", "N2", "N3"}
    assert ("S6", "a") in driving  # the leg is driven from its docked end
    commands = connector_commands(config, _reports(config.with_vectors(
        x={e.id: np.cross(e.z, [0.0, 0.0, 1.0]) / np.linalg.norm(np.cross(e.z, [0, 0, 1.0]))
           for e in config.edges()}), np.random.default_rng(0))[0])
    efforts = {(s, end): c.joints.get(f"{end}.effort", 1.0) for s, c in commands.items()
               for end in ("a", "b") if f"{end}.dir_x" in c.joints}
    assert {k for k, v in efforts.items() if v == 1.0} == driving
    assert all(v == FOLLOW_EFFORT for k, v in efforts.items() if k not in driving)


def test_a_strut_on_no_loop_between_two_hubs_drives_at_both_ends():
    """A bridge cannot be set against itself (no loop), so both its connectors drive when
    each of its nodes holds at least three other struts; a soft end made the S12N6 quadruped's single
    bar a hinge of a quarter of the torque (its front half pitched about it and a
    connector broke, issue 32). Bridges are checked against the definition: removing the
    strut disconnects its two nodes."""
    for library in ("S6N3", "S12N6", "S4N5"):
        sub = next(iter(LIBRARIES[library].sublibraries.values()))
        for entry in sub.configurations.values():
            config = entry.configuration
            links = {(e.id, end): n for e in config.edges()
                     for end, n in (("a", e.source), ("b", e.target))
                     if not config.is_virtual(n)}
            both = [e for e in config.edges() if not config.is_virtual(e.source)
                    and not config.is_virtual(e.target)]
            cut = set()
            for edge in both:
                graph = nx.MultiGraph()
                graph.add_nodes_from(n for n in links.values())
                graph.add_edges_from((e.source, e.target) for e in both if e.id != edge.id)
                if not nx.has_path(graph, edge.source, edge.target):
                    cut.add(edge.id)
            assert bridges(links) == cut, entry.configuration.name
            degree = {n: list(links.values()).count(n) for n in links.values()}
            driving = driving_ends(links)
            for edge in both:
                inner = degree[edge.source] > 3 and degree[edge.target] > 3
                assert ((edge.id, "a") in driving and (edge.id, "b") in driving) \
                    == (edge.id in cut and inner), (entry.configuration.name, edge.id)
    quadruped = _library_config("S12N6", "S12N6-8.1")
    links = {(e.id, end): n for e in quadruped.edges()
             for end, n in (("a", e.source), ("b", e.target)) if not quadruped.is_virtual(n)}
    assert {("S1", "a"), ("S1", "b")} <= driving_ends(links)   # the bar N1-N2
    assert ("L1", "b") not in driving_ends(links)               # a foot's connector
    chain = _library_config("S4N5", "S4N5-2.1")   # the squirm's chain: links of degree 2
    links = {(e.id, end): n for e in chain.edges()
             for end, n in (("a", e.source), ("b", e.target)) if not chain.is_virtual(n)}
    assert bridges(links) == {"S1", "S2", "S3", "S4"}
    assert sum(end in driving_ends(links) for end in links) == 4   # one per strut


def test_the_root_is_the_best_connected_node_never_a_wheel_or_a_foot():
    """A leaf node rolls (a wheel, Fig. 18(a)) or a foot turns (Fig. 19): the group's root
    frame, in which the configuration is recognized and the commands are given, must not
    turn with it. The S4N5 star's centre (degree 4) roots it whatever its id; between
    equals the smallest id does; the driving connectors' tree starts there too."""
    star = _library_config("S4N5", "S4N5-1.2").relabel({"N0": "N9", "N1": "N0"})
    links = {(e.id, end): n for e in star.edges()
             for end, n in (("a", e.source), ("b", e.target)) if not star.is_virtual(n)}
    assert root_order(set(links.values()), links)[0] == "N9"
    assert root_order({"N3", "N2"}, {("S1", "a"): "N3", ("S1", "b"): "N2"}) == ["N2", "N3"]
    star = star.with_vectors(x={e.id: np.cross(e.z, [0.0, 0.0, 1.0])
                                / np.linalg.norm(np.cross(e.z, [0.0, 0.0, 1.0]))
                                for e in star.edges()})
    headings = node_headings(_reports(star, np.random.default_rng(1))[0], links)
    assert headings["N9"] == 0.0 and any(h != 0.0 for h in headings.values())
    assert all((s, "a") in driving_ends(links) for s in ("S1", "S2", "S3", "S4"))


def test_core_executor_runs_a_connection_and_a_disconnection():
    """The core executor, unchanged, with this driver, recognizer and controller (no IK)."""
    sequence = [_library_config("S6N3", k) for k in ("S6N3-2.3", "S6N3-3.1", "S6N3-2.3")]
    actions = detect_actions(sequence)
    assert [a.type.value for a in actions] == ["connection", "disconnection"]
    plan = Plan(robot="freesn", planner="manual", start=sequence[0], goal=sequence[-1],
                actions=actions)
    run = Run(robot="freesn", scenario="custom", plan=plan, spec=SPEC, driver="mujoco")
    with FreeSNMujocoDriver(noise=np.radians(2.0), slip=0.05, seed=2) as driver:
        driver.reset(sequence[0])
        result = Executor(run, driver, plugins.recognizers.get("freesn"),
                          plugins.controllers.get("freesn"),
                          ExecutorOptions(action_timeout=10.0, retries=0)).execute()
        events = [(e.kind, e.strut, e.end, e.node) for e in driver.world.events]
        truth = driver.world.ground_truth()
    assert result.success, result.reason
    assert (result.docks, result.undocks) == (1, 1)
    assert events == [("dock", "S5", "b", "N1"), ("undock", "S5", "b", "N1")]
    assert not topology_diff(truth, sequence[-1])


def test_a_strut_left_out_of_the_commands_stops_where_it_is():
    start = _library_config("S6N3", "S6N3-1.2")   # flat: legs on the ground
    goal = start.with_vectors(z={e.id: (rot_z(np.radians(-90.0)) @ e.z if e.id == "S4" else e.z)
                                 for e in start.edges()})
    controller = FreeSNController()
    with FreeSNMujocoDriver() as driver:
        driver.reset(start)
        for _ in range(3):
            driver.send_action(controller.commands(goal, driver.get_observation(), yaw=0.0))
            driver.step(0.1)
        driver.send_action({})
        stopped = driver.world.ground_truth().edge("S4").z
        driver.step(1.0)
        after = driver.world.ground_truth().edge("S4").z
    swing = np.degrees(np.arccos(np.clip(stopped @ start.edge("S4").z, -1, 1)))
    assert 5.0 < swing < 80.0, "stopped half way"
    assert np.degrees(np.arccos(np.clip(stopped @ after, -1, 1))) < 2.0


def test_saturation_is_reported_while_motors_stall_against_a_load():
    """S6N3 on three legs asked to stand up straighter: with a fifth of a percent of the
    torque the driving connectors stall at their limit for the whole try; with the
    nominal torque they reach the pose and nothing is saturated at the end."""
    start = _library_config("S6N3", "S6N3-1.1")
    goal = _lowered(start, np.radians(60.0))
    controller = FreeSNController()
    streaks = []
    for torque_factor in (0.002, 0.6):
        with FreeSNMujocoDriver(torque_factor=torque_factor) as driver:
            driver.reset(start)
            assert driver.saturation() == {}
            _drive(driver, controller, goal, 20)
            streaks.append(driver.saturation())
    assert streaks[0] and max(streaks[0].values()) > 1.5
    assert all(key.split(":")[1] in ("a", "b") for key in streaks[0])
    assert streaks[1] == {}


def test_the_integral_action_removes_the_static_error_a_load_leaves():
    """S6N3 standing on three legs crouches under its own weight: the pure position loop
    stops short where its torque balances the load; the integral action (the default)
    goes on to the goal. Over 9 s: since the wheel base is the firmware's (46.7 mm, stop
    40) the legs' wider free wheels scrub the floor harder and the integral takes longer
    (1.61, 1.38, 0.52 deg at 3, 6, 9 s; the pure loop 1.97, 2.06, 2.27 deg)."""
    start = _library_config("S6N3", "S6N3-1.1")
    goal = _lowered(start, np.radians(30.0))
    controller = FreeSNController()
    errors = []
    for integral_gain in (0.0, SimOptions().integral_gain):
        with FreeSNMujocoDriver(integral_gain=integral_gain) as driver:
            driver.reset(start)
            _drive(driver, controller, goal, 90)
            errors.append(skeletal_errors(driver.world.ground_truth(), goal)[0])
    assert SimOptions().integral_gain > 0.0
    assert errors[1] < 0.5 * errors[0], [f"{np.degrees(e):.2f} deg" for e in errors]


def test_the_integral_drives_a_connector_no_faster_than_its_bound():
    """S6N3 crouching under its own weight winds its connectors' integrals up: what an
    integral adds to the speed command stays within ``integral_bound`` of the roll rate
    (the anti-windup bound; issue 31: at the whole roll rate a connector held off its
    target -- a strut pressed on a node, a loop whose ends disagree -- pushes with the
    full torque at any error), and it is the bound that holds it there."""
    start = _library_config("S6N3", "S6N3-1.1")
    goal = _lowered(start, np.radians(30.0))
    controller = FreeSNController()
    peaks = {}
    for bound in (1.0, 0.25):
        with FreeSNMujocoDriver(integral_bound=bound) as driver:
            driver.reset(start)
            world, peak = driver.world, 0.0
            yaw = skeletal_errors(FreeSNRecognizer().recognize(
                driver.get_observation().sensors), goal)[2]
            for _ in range(30):
                driver.send_action(controller.commands(goal, driver.get_observation(), yaw=yaw))
                driver.step(0.1)
                peak = max(peak, float(np.max(np.linalg.norm(world._integral, axis=1))))
            peaks[bound] = peak * world.options.integral_gain / world.phys.max_roll_rate
    assert peaks[1.0] > 0.5                                        # it winds up that far
    assert peaks[0.25] == pytest.approx(0.25, rel=1e-6), peaks     # and no further


def test_connectors_servo_on_their_own_noisy_sensors():
    """The connectors' loops read the node's IMU and their localisation with the reports'
    noise: a held aim wanders by a fraction of the noise, exactly without noise."""
    start = _library_config("S6N3", "S6N3-1.1")

    def wander(noise: float) -> float:
        world = FreeSNWorld(start, SPEC, SimOptions(noise=noise, seed=4))
        k = world.ends.index(("S4", "a"))
        node = world.docked[k]
        want = world.ground_truth(node).edge("S4").z
        errors = []
        for _ in range(20):
            world.command_target("S4", "a", (want, None, 1.0))
            world.step(0.1)
            have = world.ground_truth(node).edge("S4").z
            errors.append(np.degrees(np.arccos(np.clip(have @ want, -1.0, 1.0))))
        return float(np.max(errors[5:]))

    assert wander(0.0) < 0.2
    assert 0.3 < wander(np.radians(2.0)) < 4.0


def test_a_connectors_twist_drift_is_pulled_back_by_its_struts_accelerometer():
    """The encoders' twist error (``eps``: slip and drift, a random walk) is fused with
    the strut's accelerometer at each command, weighted by how far the axis is from the
    vertical: with exact readings it decays as ``(1 - _TWIST_FUSION sin^2)^n``; before, it stayed
    (a strut wheel's axle rolled that far off level for good)."""
    world = FreeSNWorld(_library_config("S6N3", "S6N3-1.1"), SPEC, SimOptions(slip=0.1))
    world.step(0.1)
    k = world.ends.index(("S4", "a"))
    want = world.ground_truth(world.docked[k]).edge("S4").z
    axis_z = world.data.xmat[world.bodies["S4"]].reshape(3, 3)[2, 2]
    seen = 1.0 - axis_z**2
    assert seen > 0.1                                  # a leg, not vertical
    world._eps[k] = 0.3
    for _ in range(10):
        world.command_target("S4", "a", (want, None, 1.0))
    assert world._eps[k] == pytest.approx(0.3 * (1.0 - 0.2 * seen) ** 10, rel=1e-9)


def test_a_nodes_attitude_estimate_is_its_noisy_readings_low_passed():
    """The connectors turn commands into the node frame through the node's attitude
    estimate: each tick's reading (the reports' noise) fused at ``b`` = ``fusion`` into the
    gyro-propagated attitude, so the error is a low-passed noise (std ``sigma b / sqrt(1 -
    (1 - b)^2)`` ~ 0.16 sigma at 0.05, lag-one correlation ``1 - b``), not a fresh 2 deg
    per tick; exact without noise."""
    start = _library_config("S6N3", "S6N3-1.1")

    def errors(noise: float) -> np.ndarray:
        world = FreeSNWorld(start, SPEC, SimOptions(noise=noise, seed=3))
        body = world._node_body[0]
        out = []
        for _ in range(4000):
            world._imu.clear()
            truth = world.data.xmat[body].reshape(3, 3).T \
                @ rot_z(-float(heading(world.data.xquat[body]))).T
            out.append(Rotation.from_matrix(world._node_tilt(0) @ truth.T).as_rotvec())
        return np.array(out[200:])

    assert np.abs(errors(0.0)).max() < 1e-9
    sigma, b = np.radians(2.0), SimOptions().fusion
    e = errors(sigma)
    assert np.std(e) == pytest.approx(sigma * b / np.sqrt(1 - (1 - b) ** 2), rel=0.2)
    lag = np.mean([np.corrcoef(e[1:, i], e[:-1, i])[0, 1] for i in range(3)])
    assert lag == pytest.approx(1 - b, abs=0.1)


@pytest.mark.parametrize("off_deg, docks", [(2.0, True), (6.0, False)])
def test_a_magnet_docks_only_touching_and_aligned(off_deg, docks):
    """S5's free end aimed at N1 but turned about N2: 2 deg touches the shell squarely
    and docks; 6 deg (2.1 cm off, 20 deg askew: a weld from a distance before) only
    pulls, with a force bounded by the connection strength, against S5's held connector
    and the open triangle's."""
    aimed = _library_config("S6N3", "S6N3-2.3")
    turn = rot_z(np.radians(off_deg))
    world = FreeSNWorld(aimed.with_vectors(z={e.id: turn @ e.z if e.id == "S5" else e.z
                                              for e in aimed.edges()}), SPEC, SimOptions())
    world.command_dock("S5", "b")
    pull = 0.0
    for _ in range(50):
        world.step(0.01)
        pull = max(pull, float(np.linalg.norm(world.data.xfrc_applied[world.bodies["N1"], :3])))
    assert (world.docked[world.ends.index(("S5", "b"))] == "N1") is docks
    assert pull <= world.phys.strength + 1e-9


@pytest.mark.parametrize("gap_mm", [-3.0, 0.0, 0.5, 2.0, 5.0, 20.0])
@pytest.mark.parametrize("tilt_deg", [0.0, 5.0, 10.0, 30.0])
def test_the_magnets_pull_is_maxwells_pressure_over_its_tilted_face(gap_mm, tilt_deg):
    """Against a quadrature of the pressure ``S (g0 / (g0 + g))^2`` across a flat face of
    width ``2 w`` whose gap grows by ``sin(tilt)`` per metre across it, the face moved out
    to touching where its near edge would be inside the shell; face-on it is the
    magnetic-circuit law, never more than the strength, and pressed on the shell it
    falls with the tilt."""
    strength, g0, w = 20.0, 0.005, 0.01
    gap, tilt = gap_mm * 1e-3, np.radians(tilt_deg)
    centre = max(gap, w * np.sin(tilt))          # a rigid face does not enter the shell

    def pressure(x: float) -> float:
        return strength * (g0 / (g0 + centre + x * np.sin(tilt))) ** 2

    reference = quad(pressure, -w, w)[0] / (2 * w)
    pull = magnet_pull(gap, tilt, strength, falloff=g0, half_width=w)
    assert pull == pytest.approx(reference, rel=1e-9)
    assert pull <= strength + 1e-12
    if tilt == 0.0:
        assert pull == pytest.approx(strength * (g0 / (g0 + max(gap, 0.0))) ** 2)
    elif gap <= 0.0:   # pressed on the shell: the more askew, the weaker
        assert magnet_pull(gap, tilt + 0.01, strength, falloff=g0, half_width=w) < pull < strength


def test_an_askew_magnet_pressed_on_its_node_pulls_less_than_a_square_one():
    """Issue 32, item 5 (fig21 under noise: a face pressed 11 deg askew with the full 20 N
    sank 3.1 mm into its node). S5's free end turned 6 deg about N2 lands on N1's shell
    20 deg askew: it does not dock, and its magnet pulls at most what a face tilted by
    the alignment tolerance pulls pressed on the shell (0.59 S), so it presses the shell
    less than half the interpenetration limit (the full strength pressed it 2.5 mm)."""
    aimed = _library_config("S6N3", "S6N3-2.3")
    turn = rot_z(np.radians(6.0))
    world = FreeSNWorld(aimed.with_vectors(z={e.id: turn @ e.z if e.id == "S5" else e.z
                                              for e in aimed.edges()}), SPEC, SimOptions())
    world.command_dock("S5", "b")
    pull = depth = 0.0
    for _ in range(60):
        world.step(0.01)
        pull = max(pull, float(np.linalg.norm(world.data.xfrc_applied[world.bodies["N1"], :3])))
        depth = max([depth, *(d for a, b, d in world.penetrations(0.0) if {a, b} == {"S5", "N1"})])
    assert world.docked[world.ends.index(("S5", "b"))] is None
    assert 0.0 < pull <= magnet_pull(0.0, np.radians(10.0), world.phys.strength)
    assert 0.0 < depth < 0.5 * INTERPENETRATION


def test_a_strut_pushed_onto_a_node_with_the_connection_strength_barely_sinks():
    """Module bodies are hard (``_BODY_SOLREF``). Under noise, fig21 (seed 10) pressed
    S5's free end 17 deg askew on N1 with its magnet and the extruded configuration's
    push (section 4.2), and MuJoCo's default 20 ms contact let it sink 3.0 mm, read as
    interpenetration. The askew end above, pushed along the strut with the full
    connection strength besides its magnet, sinks 1.0 mm, under half the limit (4.2 mm
    with the default); the floor's contacts keep MuJoCo's default."""
    aimed = _library_config("S6N3", "S6N3-2.3")
    turn = rot_z(np.radians(6.0))
    world = FreeSNWorld(aimed.with_vectors(z={e.id: turn @ e.z if e.id == "S5" else e.z
                                              for e in aimed.edges()}), SPEC, SimOptions())
    world.command_dock("S5", "b")
    dofs = world.model.joint("free/S5").dofadr[0] + np.arange(3)
    depth = 0.0
    for _ in range(60):
        toward = world.data.xpos[world.bodies["N1"]] - world.data.xpos[world.bodies["S5"]]
        world.data.qfrc_applied[dofs] = world.phys.strength * toward / np.linalg.norm(toward)
        world.step(0.01)
        depth = max([depth, *(d for a, b, d in world.penetrations(0.0) if {a, b} == {"S5", "N1"})])
    assert world.docked[world.ends.index(("S5", "b"))] is None
    assert 0.0 < depth < INTERPENETRATION / 2
    ground = world.model.geom("ground").id
    floor = [c.solref for c in world.data.contact[:world.data.ncon] if ground in c.geom]
    assert floor and np.allclose(floor, [0.02, 1.0])   # MuJoCo's default


@pytest.mark.parametrize("angle_deg", [10.0, 20.0, 40.0])
def test_interpenetration_matches_the_capsules_geometry(angle_deg):
    """Two leaf struts on one node, ``angle`` apart, collide (no exclusion): their
    capsules (radius ``r``) start ``a = R + gap + r`` from the node centre, so they overlap
    by ``2 r - 2 a sin(angle/2)`` (none at 40 deg, past the 31.8 deg at which they
    touch); the world notes it from the start, past its 3 mm tolerance."""
    config = Configuration("freesn")
    config.add_module("N1", "node")
    for name, azimuth in (("S1", 0.0), ("S2", np.radians(angle_deg))):
        config.add_virtual(f"{name}:b")
        config.connect("N1", f"{name}:b", id=name, kind="strut",
                       z=[np.cos(azimuth), np.sin(azimuth), 0.0])
    world = FreeSNWorld(config, SPEC, SimOptions())
    r, big_r = world.phys.strut_radius, world.phys.node_radius
    expected = 2 * r - 2 * (big_r + 0.003 + r) * np.sin(np.radians(angle_deg) / 2)
    found = world.penetrations(depth=0.0)
    if expected > 0:
        assert [p[:2] for p in found] == [("S1", "S2")]
        assert found[0][2] == pytest.approx(expected, abs=1e-4)
        assert list(world.interpenetrations) == ([("S1", "S2")] if expected > 0.003 else [])
    else:
        assert not found and not world.interpenetrations


def test_shipped_configurations_are_free_of_self_collision():
    """Issue 32, item 4: every shipped configuration (library, scenario starts) is built
    without two bodies interpenetrating, even by a millimetre (a strut's axis passes
    through the centres of the nodes it docks to, so two struts docked to the same two
    nodes would coincide, 40 mm deep)."""
    found = {label: FreeSNWorld(config, SPEC, SimOptions()).penetrations(0.001)
             for label, config in SHIPPED}
    assert {label: pairs for label, pairs in found.items() if pairs} == {}


def test_the_ground_truth_is_in_the_world_frame_whatever_a_node_shell_does():
    """The judge turns a behavior's commanded direction onto the ground truth and
    measures the shift in the world, so the truth's vectors are the world's: each strut
    along its body's axis, and unchanged when a node's shell turns under its connectors
    (fig22's rollers spin them by radians; a truth in a node's frame turned the judged
    direction with it, issue 31)."""
    world = FreeSNWorld(_library_config("S12N6", "S12N6-4.1"), SPEC, SimOptions())
    before = world.ground_truth()
    for edge in before.edges():
        axis = world.data.xmat[world._strut_body[world.struts.index(edge.id)]].reshape(3, 3)[:, 2]
        assert abs(float(np.dot(edge.z, axis))) > 1.0 - 1e-9
    body = world._node_body[world._node_index[min(world.nodes)]]
    address = world.model.jnt_qposadr[world.model.body_jntadr[body]]
    turned = Rotation.from_euler("z", 1.0) * Rotation.from_quat(
        world.data.qpos[address + 3:address + 7], scalar_first=True)
    world.data.qpos[address + 3:address + 7] = turned.as_quat(scalar_first=True)
    mujoco.mj_forward(world.model, world.data)
    assert abs(heading(world.data.xquat[body])) > 0.9      # the shell turned
    after = world.ground_truth()
    for edge in before.edges():
        assert np.allclose(edge.z, after.edge(edge.id).z, atol=1e-9)


def _s4n1_leg(twist_deg: float = 0.0) -> tuple[FreeSNWorld, int, str, np.ndarray]:
    """S4N1 with its leg ``S1`` built turned ``twist_deg`` about its own axis: the world,
    the index of the leg's docked end ``S1:a``, the node it holds and its aim there."""
    start = load_configuration(FREESN / "configs" / "library" / "S4N1-1.2.json")
    if twist_deg:
        edge = start.edge("S1")
        twisted = Rotation.from_rotvec(np.radians(twist_deg) * edge.z).as_matrix() @ edge.x
        start = start.with_vectors(x={"S1": twisted})
    world = FreeSNWorld(start, SPEC, SimOptions())
    k = world.ends.index(("S1", "a"))
    node = world.docked[k]
    return world, k, node, world.ground_truth(node).edge("S1").z


def test_a_leg_rolling_on_its_free_wheels_holds_their_axle_level():
    """A leaf strut driving on its free connector's wheels is commanded the design's
    twist, its wheels' axle (the strut's y) level, hence tangential: S4N1's legs built 8
    deg twisted off it (as built, the start file's legs are 5, 1, 2, -1 deg off) and
    taken round the vertical end with their axles level; the kept twist held the 8 deg,
    and the radial wheels drove the spider tens of degrees off its course (issue 31)."""
    world, k, node, aim = _s4n1_leg(8.0)
    world.command_target("S1", "a", (aim, None, 1.0))
    world.command_wheels("S1", "b", 5.0)   # the free end's wheels drive
    to_node = world._node_tilt(world._node_index[node])   # horizontal -> node frame
    for step in range(0, 37):
        turned = rot_z(np.radians(10.0 * step)) @ aim
        world.command_target("S1", "a", (turned, None, 1.0))
        axle = world._target[k][:, 1]   # the strut's y in the node frame
        assert abs(np.dot(axle, to_node @ [0.0, 0.0, 1.0])) < 1e-9   # level
        assert abs(np.dot(axle, to_node @ turned)) < 1e-9   # across the leg: tangential


def test_a_leg_whose_free_wheels_ride_tilted_keeps_its_twist():
    """A wheel pair built to ride with its axle tilted (S6N3's tripod legs: 27-45 deg
    off level) is not levelled while it drives: it keeps the twist it was built with."""
    world, k, _, aim = _s4n1_leg(40.0)
    world.command_target("S1", "a", (aim, None, 1.0))
    built = world._target[k][:, 1].copy()
    world.command_wheels("S1", "b", 5.0)
    world.command_target("S1", "a", (aim, None, 1.0))
    assert abs(built[2]) > np.sin(np.radians(15.0))   # tilted as built ...
    assert np.allclose(world._target[k][:, 1], built, atol=1e-9)   # ... and kept


@pytest.mark.parametrize("turns", [1, 3])
def test_a_leg_twisted_on_the_way_rolls_on_its_free_wheels_level_on_its_built_side(turns):
    """A leg built level keeps that ride whatever twist the way leaves it: its kept twist
    composes minimal rotations, which turn its axle by the solid angle its aim sweeps
    round the node's vertical (65 deg a turn at S4N1's 55 deg: the hub's shell spinning
    under the legs under noise). Taken for a pair built tilted (its axle past 10 deg when
    its wheels started: S4N1 at 4 deg + 10 %, seeds 13 and 17), it was not levelled and
    twisted on past the vertical; level again on the reversed side, its wheels rolled
    backwards and the spider drove backwards (issue 31, stop 50)."""
    world, k, node, aim = _s4n1_leg()
    to_node = world._node_tilt(world._node_index[node])   # horizontal -> node frame
    up = to_node @ [0.0, 0.0, 1.0]

    def side() -> float:   # the axle along up x z (tangential, one way round) or against it
        axle, z = world._target[k][:, 1], world._target[k][:, 2]
        return float(np.dot(axle, np.cross(up, world._sign[k] * z)) /
                     np.linalg.norm(np.cross(up, z)))

    world.command_target("S1", "a", (aim, None, 1.0))
    built = side()
    assert abs(built) > 0.99   # built level: tangential
    for step in range(1, 36 * turns + 1):   # the wheels stopped: the kept twist turns
        world.command_target("S1", "a", (rot_z(np.radians(10.0 * step)) @ aim, None, 1.0))
    assert abs(side() - built) > 0.3   # the way twisted it
    world.command_wheels("S1", "b", 5.0)   # the free end's wheels drive
    world.command_target("S1", "a", (aim, None, 1.0))
    assert abs(np.dot(world._target[k][:, 1], up)) < 1e-9   # level
    assert side() == pytest.approx(built, abs=1e-9)   # on the side it was built on


def test_a_leg_whose_free_wheels_ride_tilted_holds_its_built_tilt_round_the_vertical():
    """A wheel pair built to ride tilted (S6N3's tripod legs: 27-45 deg off level) holds
    the turn from level it was built with while it drives, wherever its leg is aimed: its
    kept twist turned with the solid angle the aim swept, and S6N3's wheeled move (exact)
    drifted its legs' axles from 26 deg to 45 deg off level, or, within 10 deg of level,
    levelled them (issue 31, stop 50)."""
    world, k, node, aim = _s4n1_leg(40.0)
    up = world._node_tilt(world._node_index[node]) @ [0.0, 0.0, 1.0]

    def turn() -> float:   # the axle's turn about the strut's axis from the level axle
        axle, z = world._target[k][:, 1], world._sign[k] * world._target[k][:, 2]
        level = np.cross(up, z) / np.linalg.norm(np.cross(up, z))
        return float(np.arctan2(axle @ np.cross(z, level), axle @ level))

    world.command_target("S1", "a", (aim, None, 1.0))
    built = turn()
    assert abs(np.sin(built)) > np.sin(np.radians(30.0))   # tilted as built
    world.command_wheels("S1", "b", 5.0)   # the free end's wheels drive
    for step in range(1, 73):   # twice round the vertical
        world.command_target("S1", "a", (rot_z(np.radians(10.0 * step)) @ aim, None, 1.0))
        assert turn() == pytest.approx(built, abs=1e-9)
