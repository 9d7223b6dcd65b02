"""A FreeBOT piece travels over the floor as one rigid body (every shell rolls under its
arm, every module drives): ground truth judges the travel, the turn and the shape; the
commands come from the module reports only."""

from __future__ import annotations

import numpy as np
import pytest

from msrr.core.alignment import rot_z
from msrr.core.configuration import Configuration
from msrr.core.driver import ModuleCommand
from msrr.core.freeform.recognition import bend_error, links_of, module_headings
from msrr.core.freeform.travel import centres_of, twist_velocities
from msrr.core.io import load_configuration
from msrr.core.shape import skeletal_error
from msrr.plugins.freebot.plugin import plugin

from msrr_test_support import ROOT, control_until_reached

SPEED = 0.02        # [m/s], under a shell's rolling bound r * max_speed = 0.025


def _l8() -> Configuration:
    """Eight in an L: F1..F5 along x, F6..F8 along y from F5 (F5 carries F4 and F6)."""
    config = Configuration("freebot", name="l8")
    for i in range(1, 9):
        config.add_module(f"F{i}", "freebot")
    for i in range(1, 5):
        config.connect(f"F{i}", f"F{i + 1}", z=[1.0, 0.0, 0.0])
    for i in range(6, 9):
        config.connect(f"F{i}", f"F{i - 1}", z=[0.0, -1.0, 0.0])
    return config


def _pose(points: np.ndarray) -> tuple[np.ndarray, float]:
    """Centroid (2,) and yaw [rad] of ``points`` (n, 3) (the yaw of its first-to-last line)."""
    line = points[-1, :2] - points[0, :2]
    return points[:, :2].mean(axis=0), float(np.arctan2(line[1], line[0]))


@pytest.mark.parametrize("start", ["l8"])
def test_a_piece_travels_half_a_metre_and_turns_a_right_angle_keeping_its_shape(start):
    # a bent piece: a straight one cannot follow an arc (nothing grips the floor across
    # its line, so its velocity does not turn with it; it drives and turns in place)
    config = _l8() if start == "l8" else load_configuration(
        ROOT / "plugins" / "freebot" / "configs" / "chain6.json")
    driver = plugin.driver_factory()()
    driver.connect()
    driver.reset(config)
    world = driver.world
    before = world.ground_truth()
    first = np.array([world.centre(m) for m in world.modules])
    reports = driver.get_observation().sensors
    links = links_of(reports)
    centres, headings, _ = centres_of(reports, links, module_headings(reports, links),
                                      world.length)
    # a constant twist in the piece's frame: an arc of radius R through a quarter turn
    # moves the centroid by sqrt(2) R = 0.5 m
    radius = 0.5 / np.sqrt(2.0)
    about = np.mean([c[:2] for c in centres.values()], axis=0)
    velocities, turn = twist_velocities(centres, headings, np.array([radius, 0.0]), 1.0,
                                        about, speed=SPEED)
    driver.send_action({m: ModuleCommand(joints={"roll_x": float(v[0]), "roll_y": float(v[1]),
                                                 "turn": turn})
                        for m, v in velocities.items()})
    driver.step(0.5 * np.pi / turn)
    driver.send_action({})
    driver.step(0.5)
    last = np.array([world.centre(m) for m in world.modules])
    (c0, yaw0), (c1, yaw1) = _pose(first), _pose(last)
    assert np.linalg.norm(c1 - c0) == pytest.approx(0.5, abs=0.02)
    turned = (yaw1 - yaw0 + np.pi) % (2 * np.pi) - np.pi
    assert np.degrees(turned) == pytest.approx(90.0, abs=3.0)
    assert np.all(np.abs(last[:, 2] - first[:, 2]) < 0.002)      # on the floor all along
    assert world.docked_pairs() == {(e.source, e.target) for e in config.edges()}
    assert np.degrees(skeletal_error(world.ground_truth(), before)) < 1.0
    # each module's odometry (its rolling shell) saw its own centre's travel
    odometry = {m: r.odometry[:2] for m, r in driver.get_observation().sensors.items()}
    for k, m in enumerate(world.modules):
        assert np.linalg.norm(odometry[m]) == pytest.approx(
            np.linalg.norm(last[k, :2] - first[k, :2]), abs=0.02)


def test_a_snailbot_piece_is_refused_travel():
    from msrr.core.errors import ExecutionError
    from msrr.plugins.snailbot.plugin import plugin as snailbot

    config = Configuration("snailbot")
    config.add_module("S1", "snailbot")
    config.add_module("S2", "snailbot")
    config.connect("S1", "S2", z=[1.0, 0.0, 0.0])
    driver = snailbot.driver_factory()()
    driver.connect()
    driver.reset(config)
    with pytest.raises(ExecutionError, match="only alone"):
        driver.send_action({"S1": ModuleCommand(joints={"roll_x": 0.01, "roll_y": 0.0, "turn": 0.0})})


def _update(locator, driver) -> None:
    reports = driver.get_observation().sensors
    links = links_of(reports)
    locator.update(reports, links, module_headings(reports, links))


def test_a_travelling_piece_is_located_from_its_modules_odometry_and_gyros(mujoco_driver):
    from msrr.core.freeform.travel import Locator

    driver = mujoco_driver("freebot", "chain6", noise=np.radians(0.5), seed=2)
    world = driver.world
    locator = Locator(world.length)
    _update(locator, driver)
    driver.send_action({"F3": ModuleCommand(undock=("@F4",))})   # F1-F3 let go of F4-F6
    driver.step(0.1)
    _update(locator, driver)
    assert locator.piece("F3") == {"F1", "F2", "F3"}
    before = {m: world.centre(m) for m in world.modules}
    for _ in range(40):   # 4 s: away along its line while turning, commands from the map
        centres = {m: locator.pose(m)[0] for m in ("F1", "F2", "F3")}
        headings = {m: locator.pose(m)[1] for m in centres}
        line = (centres["F1"] - centres["F3"])[:2]
        velocities, turn = twist_velocities(centres, headings,
                                            0.02 * line / np.linalg.norm(line), 0.1,
                                            centres["F2"][:2], speed=SPEED)
        driver.send_action({m: ModuleCommand(joints={"roll_x": float(v[0]),
                                                     "roll_y": float(v[1]), "turn": turn})
                            for m, v in velocities.items()})
        driver.step(0.1)
        _update(locator, driver)
    assert np.linalg.norm(world.centre("F2") - before["F2"]) > 0.06, "it travelled"
    assert np.linalg.norm(world.centre("F6") - before["F6"]) < 0.002, "the rest held"
    for module, other in [("F3", "F4"), ("F1", "F6"), ("F2", "F5")]:
        k = world.modules.index(module)
        truth = rot_z(-(world._heading0[k] + world._turned[k])) @ (world.centre(other)
                                                                   - world.centre(module))
        assert np.linalg.norm(locator.relative(module)[other] - truth) < 0.01, (module, other)


def test_a_straight_piece_rolls_across_its_line_only_by_its_keel(mujoco_driver):
    # its shells would spin about the line through every centre, and nothing outside
    # the piece gives a torque about it (the floor's friction is what would move it)
    # but the weight of its root's hanging magnet unit, the keel: its angular momentum
    # about the line changes only by that, so it starts across far slower than along
    # (1 s: 20 mm along, 8 mm across; before the keel, 3.5 mm)
    driver = mujoco_driver("freebot", "chain6")
    world = driver.world
    moved = {}
    for name, velocity in [("along", (-SPEED, 0.0)), ("across", (0.0, -SPEED))]:
        driver.reset(load_configuration(ROOT / "plugins" / "freebot" / "configs" / "chain6.json"))
        world = driver.world
        start = world.centre("F3")
        driver.send_action({m: ModuleCommand(joints={"roll_x": velocity[0],
                                                     "roll_y": velocity[1], "turn": 0.0})
                            for m in world.modules})
        driver.step(1.0)
        moved[name] = float(np.linalg.norm(world.centre("F3") - start))
    assert moved["along"] == pytest.approx(SPEED, abs=0.002)
    assert moved["across"] < 0.5 * SPEED


def test_twist_velocities_are_one_rigid_motion_under_the_speed_bound():
    rng = np.random.default_rng(3)
    centres = {f"F{i}": np.append(rng.uniform(-0.3, 0.3, 2), 0.05) for i in range(7)}
    headings = {m: float(rng.uniform(-np.pi, np.pi)) for m in centres}
    about = np.array([0.05, -0.02])
    velocities, turn = twist_velocities(centres, headings, np.array([0.03, 0.01]), 0.2, about,
                                        speed=SPEED)
    world = {m: rot_z(headings[m])[:2, :2] @ v for m, v in velocities.items()}
    scale = turn / 0.2
    assert 0 < scale < 1 and max(np.linalg.norm(v) for v in world.values()) == \
        pytest.approx(SPEED)
    for m, v in world.items():   # v_m = s (v + w e_z x (p_m - about))
        arm = centres[m][:2] - about
        assert np.allclose(v, scale * (np.array([0.03, 0.01]) + 0.2 * np.array([-arm[1], arm[0]])))


def test_a_piece_goal_is_the_goal_shape_where_the_target_stays():
    from msrr.core.freeform.travel import piece_goal

    goal = {"A": np.array([0.0, 0.0, 0.0]), "B": np.array([0.1, 0.0, 0.0]),
            "P": np.array([0.1, -0.1, 0.0]), "Q": np.array([0.1, -0.2, 0.0])}
    turn, shift = rot_z(0.7), np.array([0.4, -0.3, 0.0])
    here = {m: turn @ p + shift for m, p in goal.items() if m in ("A", "B")}
    here |= {"P": np.array([2.0, 2.0, 0.0]), "Q": np.array([2.1, 2.0, 0.0])}   # elsewhere
    end = piece_goal(goal, here, {"P", "Q"}, "B")
    for m in ("P", "Q"):
        assert np.allclose(end[m], (turn @ goal[m] + shift)[:2])


def _closest(legs, offsets, others, start) -> float:
    """The smallest distance [m] between a module of the piece and another module over
    every pose the legs sweep, resampled every millimetre of the farthest module's
    travel (independently of the planner's own samples)."""
    from msrr.core.freeform.piece_way import poses_along

    reach = float(np.max(np.linalg.norm(offsets, axis=1)))
    return min(float(np.min(np.linalg.norm(
        (c + offsets @ rot_z(h)[:2, :2].T)[:, None, :] - others[None, :, :], axis=2)))
        for c, h in poses_along(legs, start, 0.001, reach))


def test_a_straight_piece_way_is_turns_in_place_and_drives_along_its_line_all_clear():
    from msrr.core.freeform.piece_way import plan_legs

    # chains-to-tree's layout: a chain beside a row of four, below it another row; the
    # chain must end across the row's third module, standing on it
    rows = np.array([[0.101 * i, y] for y in (0.0, 0.101) for i in range(4)])
    chain = np.array([[0.101 * i, 0.202] for i in range(4)])
    start = (chain.mean(axis=0), 0.0)
    offsets = chain - start[0]
    goal = (np.array([0.202, 0.101 + 0.121 + 0.1515 + 0.15]), -np.pi / 2)
    legs = plan_legs(rows, offsets, np.array([1.0, 0.0]), start, goal, 0.101)
    c, h = start
    for leg in legs:
        if leg.kind == "turn":
            assert np.allclose(leg.to, c), "a turn stays in place"
        else:    # a drive goes along the piece's line
            assert abs(leg.heading - h) < 1e-9
            way = leg.to - c
            line = rot_z(h)[:2, 0]
            assert abs(way[0] * line[1] - way[1] * line[0]) < 1e-9
        c, h = leg.to, leg.heading
    assert np.allclose(c, goal[0]) and abs(np.sin(h - goal[1])) < 1e-9
    # every swept pose: clear of the rows, as close as the start at most (it lies beside)
    assert _closest(legs, offsets, rows, start) >= 0.101 - 0.0021


def test_a_piece_in_a_cup_whose_mouth_faces_away_from_its_goal_finds_its_way_out():
    # the human example's action 22: a wall between the piece and its goal. Led by the
    # straight distance, the search filled the cup before the wall and stopped at its
    # bound on poses ("no free way"); led by the centroid's way round the modules, it
    # leaves by the mouth and goes round the side
    from msrr.core.freeform.piece_way import plan_legs

    s = 0.101
    cup = np.array([[0.0, y] for y in np.arange(-10, 11) * s]
                   + [[x, side * 10 * s] for side in (-1, 1) for x in np.arange(1, 16) * s])
    chain = np.column_stack([(np.arange(4) - 1.5) * s, np.zeros(4)])
    start, goal = (np.array([0.8, 0.0]), 0.0), (np.array([-1.5, 2.5]), 0.0)
    legs = plan_legs(cup, chain, np.array([1.0, 0.0]), start, goal, s)
    assert np.allclose(legs[-1].to, goal[0]) and abs(np.sin(legs[-1].heading)) < 1e-9
    assert _closest(legs, chain, cup, start) >= s + 0.008 - 1e-6


def test_a_search_cut_off_at_its_bound_is_run_again_weighted_and_finds_a_way(monkeypatch):
    # the human example's action 33: a piece of 10 whose way goes round a wall through
    # a door, 69,064 poses for the cheapest way, beyond the bound of 20,000; led by twice
    # its estimate the search found one (17.68 m, 273 poses). Here the cup's way: 11,601
    # poses for the cheapest, the bound 2,000
    from msrr.core.freeform import piece_way as ways
    from msrr.core.freeform.piece_way import PieceWay, plan_legs

    s = 0.101
    cup = np.array([[0.0, y] for y in np.arange(-10, 11) * s]
                   + [[x, side * 10 * s] for side in (-1, 1) for x in np.arange(1, 16) * s])
    chain = np.column_stack([(np.arange(4) - 1.5) * s, np.zeros(4)])
    start, goal = (np.array([0.8, 0.0]), 0.0), (np.array([-1.5, 2.5]), 0.0)

    def travel(legs) -> float:
        return PieceWay("a", "b", ("a",), start[0], chain, 0.0, tuple(legs), goal[0],
                        np.zeros(2), None).travel()

    best = plan_legs(cup, chain, np.array([1.0, 0.0]), start, goal, s)
    cheapest = travel(best)
    monkeypatch.setattr(ways, "_EXPANSIONS", 2000)
    legs = plan_legs(cup, chain, np.array([1.0, 0.0]), start, goal, s)
    assert np.allclose(legs[-1].to, goal[0]) and abs(np.sin(legs[-1].heading)) < 1e-9
    assert _closest(legs, chain, cup, start) >= s + 0.008 - 1e-6
    assert cheapest <= travel(legs) <= ways._INFLATE * cheapest
    # and its lattice's zigzags shortcut by direct ways between its poses (stop 53:
    # action 33 in 23 legs against the cheapest way's 15): here 11 legs and 5.86 m
    # before, 7 legs and 5.77 m after, the cheapest 9 legs and 5.74 m
    assert len(legs) <= len(best) and travel(legs) <= 1.01 * cheapest, (len(legs),
                                                                         travel(legs))


def test_a_bent_piece_way_keeps_clear_and_a_closed_goal_is_refused():
    from msrr.core.errors import ExecutionError
    from msrr.core.freeform.piece_way import plan_legs

    wall = np.array([[0.4, 0.1 * i - 0.3] for i in range(7)])        # x = 0.4, |y| <= 0.3
    ell = np.array([[0.0, 0.0], [0.1, 0.0], [0.2, 0.0], [0.2, 0.1]])
    start = (ell.mean(axis=0), 0.3)
    offsets = ell - start[0]
    goal = (np.array([0.8, 0.0]), 2.0)
    legs = plan_legs(wall, offsets, None, start, goal, 0.1)
    assert np.allclose(legs[-1].to, goal[0]) and abs(np.sin(legs[-1].heading - 2.0)) < 1e-9
    assert _closest(legs, offsets, wall, start) >= 0.108 - 1e-6
    boxed = np.array([[start[0][0] + 0.3 * np.cos(a), start[0][1] + 0.3 * np.sin(a)]
                      for a in np.linspace(0, 2 * np.pi, 30, endpoint=False)])  # a pen
    with pytest.raises(ExecutionError, match="no free way|not free"):
        plan_legs(np.vstack([wall, boxed]), offsets, None, start, goal, 0.1)


def test_separate_start_pieces_are_related_by_the_start_layout(mujoco_driver):
    # three chains never docked to each other: no report relates them, the start file's
    # layout (as the world lays it, and a lab places the modules) does
    from msrr.core.freeform.travel import Locator
    from msrr.core.freeform.world import place

    driver = mujoco_driver("freebot", "chains12/chains12-forest", noise=np.radians(0.5), seed=1)
    world = driver.world
    alone = Locator(world.length)
    _update(alone, driver)
    assert "F3" not in alone.relative("F12"), "another island"
    config = load_configuration(ROOT / "plugins" / "freebot" / "configs" / "chains12"
                                / "chains12-forest.json")
    centres, frames = place(config, world.length, world.design.radius)
    locator = Locator(world.length)
    locator.start({m: (centres[m], frames[m]) for m in centres})
    _update(locator, driver)
    for module, other in [("F12", "F3"), ("F8", "F9"), ("F1", "F12")]:
        k = world.modules.index(module)
        truth = rot_z(-(world._heading0[k] + world._turned[k])) @ (world.centre(other)
                                                                   - world.centre(module))
        assert np.linalg.norm(locator.relative(module)[other] - truth) < 0.01, (module, other)


def _let_go(config: Configuration, module: str, holder: str):
    """A MuJoCo FreeBOT driver reset to ``config``, 0.3 s after ``module`` let go of
    ``holder``."""
    driver = plugin.driver_factory()()
    driver.connect()
    driver.reset(config)
    driver.send_action({module: ModuleCommand(undock=(f"@{holder}",))})
    driver.step(0.3)
    return driver


def _row_let_go_across(name: str):
    """F1..F4 in a row held on F5 across its line, F4 let go of F5: the driver."""
    config = Configuration("freebot", name=name)
    for i in range(1, 6):
        config.add_module(f"F{i}", "freebot")
    for i in range(1, 4):
        config.connect(f"F{i}", f"F{i + 1}", z=[1.0, 0.0, 0.0])
    config.connect("F4", "F5", z=[0.0, 1.0, 0.0])
    return _let_go(config, "F4", "F5")


def _turn_then_drive(driver, piece: tuple[str, ...], ticks: int, settle: float = 0.0
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Turn ``piece`` in place at 0.2 rad/s for ``ticks`` of 0.1 s, hold still ``settle``
    [s], then drive it along its line at ``SPEED`` for 3 s: its modules' centres (n, 2) on
    ground truth before and after the drive."""
    for _ in range(ticks):
        _twist(driver, piece, 0.0, 0.2)
        driver.step(0.1)
    if settle:
        _twist(driver, piece, 0.0, 0.0)
        driver.step(settle)
    before = np.array([driver.world.centre(m)[:2] for m in piece])
    for _ in range(30):
        _twist(driver, piece, SPEED, 0.0)
        driver.step(0.1)
    return before, np.array([driver.world.centre(m)[:2] for m in piece])


def _twist(driver, piece: tuple[str, ...], speed: float, turn: float) -> None:
    """Command ``piece`` from its reports: ``speed`` [m/s] along its line (first module to
    last) and ``turn`` [rad/s] about its centroid."""
    reports = driver.get_observation().sensors
    links = links_of(reports)
    centres, headings, _ = centres_of(reports, links, module_headings(reports, links),
                                      driver.world.length)
    centres = {m: centres[m] for m in piece}
    line = (centres[piece[-1]] - centres[piece[0]])[:2]
    velocities, w = twist_velocities(
        centres, {m: headings[m] for m in piece}, speed * line / np.linalg.norm(line),
        turn, np.mean([c[:2] for c in centres.values()], axis=0), speed=SPEED)
    driver.send_action({m: ModuleCommand(joints={"roll_x": float(u[0]),
                                                 "roll_y": float(u[1]), "turn": w})
                        for m, u in velocities.items()})


def test_a_piece_that_let_go_sideways_turns_then_drives_along_its_line():
    # F1-F2 held on F3 across its line, then let go: F2, the piece's free module, has its
    # magnet (and the weld's foot) pointing sideways. Turned in place a quarter turn about
    # its centroid, then told 0.02 m/s along its line for 3 s, it covers 80 % of that on
    # ground truth, more along its line than across. Before the foot weighed nothing, the
    # foot swung the piece about its own line, which no travel loop sees: 1.3 cm
    # backwards and 23 cm across instead (docs/freebot.md, chains-to-tree)
    config = Configuration("freebot", name="let-go")
    for m in ("F1", "F2", "F3"):
        config.add_module(m, "freebot")
    config.connect("F1", "F2", z=[1.0, 0.0, 0.0])
    config.connect("F2", "F3", z=[0.0, 1.0, 0.0])
    driver = _let_go(config, "F2", "F3")
    piece = ("F1", "F2")
    before, after = _turn_then_drive(driver, piece, 80)   # a quarter turn at 0.2 rad/s
    line = before[1] - before[0]
    line /= np.linalg.norm(line)
    moved = after.mean(axis=0) - before.mean(axis=0)
    assert float(moved @ line) >= 0.8 * SPEED * 3.0
    across = abs(float(line[0] * moved[1] - line[1] * moved[0]))
    assert across < float(moved @ line)                  # mostly along its line


def test_a_straight_piece_keeps_its_line_after_a_turn_in_place():
    # F1..F4 in a row, F4 held on F5 across it, then let go: turned in place about its
    # centroid (0.2 rad/s for 7.8 s), it keeps rolling about its own line afterwards
    # (its angular momentum about that line) unless something holds it: told 0.02 m/s
    # along its line for 3 s it went 60 mm along and 54 mm across (42 deg off its line:
    # pieces-to-tree's F13-F16 drove 36 deg off and into F4-F5). Its root's magnet unit
    # now hangs as a pendulum (the keel) and holds the piece's roll: under 5 mm across
    driver = _row_let_go_across("turned")
    piece = ("F1", "F2", "F3", "F4")
    before, after = _turn_then_drive(driver, piece, 78, settle=1.0)
    moved = after.mean(axis=0) - before.mean(axis=0)
    line = (before[-1] - before[0]) / np.linalg.norm(before[-1] - before[0])
    assert float(moved @ line) >= 0.8 * SPEED * 3.0
    assert abs(float(line[0] * moved[1] - line[1] * moved[0])) < 0.005


def test_a_piece_whose_goal_place_is_taken_docks_where_the_target_is_free_now():
    # the goal has the chain P1-P3 hanging from T along -y, where B lies now (a later
    # step moves B away): the piece docks on T at a free place, in the shape it has
    from msrr.core.freeform.piece_way import piece_way, poses_along

    spacing = 0.1
    row = {f"T{i}": np.array([0.1 * i, 0.0]) for i in range(4)}
    here = row | {"B": np.array([0.0, -0.1]),
                  **{f"P{i}": np.array([0.8 + 0.1 * i, 0.6]) for i in range(1, 4)}}
    goal = {m: np.append(p, 0.0) for m, p in row.items()} | {
        "B": np.array([0.1, 0.1, 0.0]), **{f"P{i}": np.array([0.0, -0.1 * i, 0.0])
                                          for i in range(1, 4)}}
    group, piece = set(row) | {"B"}, {"P1", "P2", "P3"}
    way = piece_way(here, piece, group, "P1", 0.3, "T0", goal, spacing)
    shape = np.array([here[m] for m in way.piece]) - np.mean([here[m] for m in way.piece],
                                                              axis=0)
    offsets = shape @ rot_z(0.3)[:2, :2]
    poses = poses_along(way.legs, (way.origin, 0.3), 0.001, 0.1)
    docked = poses[-1][0] + offsets @ rot_z(poses[-1][1])[:2, :2].T + 0.02 * way.push
    root = docked[way.piece.index("P1")]
    assert abs(np.linalg.norm(root - here["T0"]) - spacing) < 0.005, "P1 touches T0"
    assert np.allclose(way.centre, here["T0"])
    assert not way.at_goal, "the way says it docks at a free place, not the goal's"
    others = np.array([p for m, p in here.items() if m not in piece])
    gaps = np.linalg.norm(docked[:, None, :] - others[None, :, :], axis=2)
    gaps[way.piece.index("P1"), list(here).index("T0")] = np.inf
    assert gaps.min() >= spacing - 0.01, "docked, no shell overlaps another"
    assert _closest(way.legs, offsets, others, (way.origin, 0.3)) >= spacing
    # the time the approach asks for: the farthest module's travel, against the path
    # each module sweeps, resampled every millimetre
    paths = np.sum([np.linalg.norm(
        (b[0] + offsets @ rot_z(b[1])[:2, :2].T) - (a[0] + offsets @ rot_z(a[1])[:2, :2].T),
        axis=1) for a, b in zip(poses, poses[1:], strict=False)], axis=0)
    assert way.travel() == pytest.approx(float(np.max(paths)), rel=0.05)
    # the same goal with B gone: the piece ends 2 cm short of its goal place, as before
    del here["B"], goal["B"]
    way = piece_way(here, piece, set(row), "P1", 0.3, "T0", goal, spacing)
    end = way.legs[-1].to + 0.02 * way.push
    assert np.allclose(end, [0.0, -0.2], atol=1e-6)
    assert way.at_goal


def _three_chains(apart: float | None) -> Configuration:
    """Chains A, B, C of five along x (each module on the one before); their first
    modules at ``y = 0, apart, 2 apart`` when ``apart`` is given, else no positions."""
    config = Configuration("freebot", name="three-chains")
    for k, c in enumerate("ABC"):
        for i in range(1, 6):
            at = [0.3, k * apart, 0.05] if apart is not None and i == 1 else None
            config.add_module(f"{c}{i}", "freebot", position=at)
        for i in range(2, 6):
            config.connect(f"{c}{i}", f"{c}{i - 1}", z=[-1.0, 0.0, 0.0])
    return config


def test_a_start_laid_out_by_its_positions_leaves_room_to_dock_mid_chain():
    # the piece A4-A5 lets go of A3 and docks on B3, the middle of the middle chain. Laid
    # side by side by the world's rule (10 cm between shells) no place touching B3 is
    # free; laid where the file's positions put the chains (0.6 m apart, as a lab lays
    # them), the piece finds its way and docks touching B3, clear of every shell
    from msrr.core.errors import ExecutionError
    from msrr.core.freeform.piece_way import piece_way
    from msrr.core.freeform.world import place

    spacing = 0.101
    goal = {f"B{i}": np.array([0.1 * i, 0.0, 0.0]) for i in range(1, 6)} | {
        "A4": np.array([0.3, -0.1, 0.0]), "A5": np.array([0.3, -0.2, 0.0])}
    piece, group = {"A4", "A5"}, {f"B{i}" for i in range(1, 6)}
    packed, _ = place(_three_chains(None), spacing, 0.05)
    here = {m: c[:2] for m, c in packed.items()}
    with pytest.raises(ExecutionError, match="no place touching module B3 is free"):
        piece_way(here, piece, group, "A4", 0.0, "B3", goal, spacing)
    laid, _ = place(_three_chains(0.6), spacing, 0.05)
    assert np.allclose(laid["C1"], [0.3, 1.2, 0.05]) and np.allclose(laid["C5"], [0.704, 1.2, 0.05])
    here = {m: c[:2] for m, c in laid.items()}
    way = piece_way(here, piece, group, "A4", 0.0, "B3", goal, spacing)
    end = way.legs[-1].to + 0.02 * way.push
    shape = np.array([here[m] for m in way.piece])
    docked = end + (shape - shape.mean(axis=0)) @ rot_z(way.legs[-1].heading)[:2, :2].T
    root = docked[way.piece.index("A4")]
    assert abs(np.linalg.norm(root - here["B3"]) - spacing) < 0.005, "A4 touches B3"
    others = np.array([p for m, p in here.items() if m not in piece])
    gaps = np.linalg.norm(docked[:, None, :] - others[None, :, :], axis=2)
    gaps[way.piece.index("A4"), list(m for m in here if m not in piece).index("B3")] = np.inf
    assert gaps.min() >= spacing - 0.01


def test_a_position_that_disagrees_with_its_piece_is_named():
    from msrr.core.errors import ExecutionError
    from msrr.core.freeform.world import place

    config = _three_chains(0.6)
    config.graph.nodes["A3"]["position"] = np.array([0.0, 5.0, 0.05])
    with pytest.raises(ExecutionError, match=r"^configuration 'three-chains': module A3: "
                                             r"its position is 5\.\d+ m from"):
        place(config, 0.101, 0.05)


def test_a_start_the_world_cannot_lay_out_stops_the_run_saying_why(tmp_path, monkeypatch):
    # the error of the failed reset reaches the user, not the stop sent after it
    from click.testing import CliRunner

    from msrr.core.app.cli import get_cli
    from msrr.core.io import save_configuration

    config = _three_chains(0.6)
    config.graph.nodes["A3"]["position"] = np.array([0.0, 5.0, 0.05])
    save_configuration(config, tmp_path / "bad.json")
    save_configuration(_three_chains(None), tmp_path / "good.json")
    monkeypatch.chdir(tmp_path)
    out = CliRunner().invoke(get_cli(), ["run", "--robot", "freebot", "--from", "bad.json",
                                         "--to", "good.json", "--no-log"])
    assert out.exit_code != 0
    assert "module A3: its position is 5." in out.output.splitlines()[-1]


def test_a_goal_place_no_way_reaches_gives_way_to_a_free_place(monkeypatch):
    # the goal hangs the piece P1-P2 from T inside a pen closed by T's own row: the place
    # is free but no way leads in, nor to the free places beside it, so the piece docks
    # at a free place on another side of T, outside (before, the search for the goal
    # place's way failed the step: "no free way"). The search is bounded to keep the
    # failing ones short
    from msrr.core.freeform import piece_way as ways
    from msrr.core.freeform.piece_way import piece_way

    monkeypatch.setattr(ways, "_EXPANSIONS", 300)

    spacing = 0.1
    row = {f"R{i}": np.array([0.1 * i - 0.4, 0.0]) for i in range(9)}       # T is R4
    pen = {f"W{k}": p for k, p in enumerate(
        [np.array([x, -0.8]) for x in np.arange(-0.4, 0.41, 0.1)]
        + [np.array([s * 0.4, -0.1 * j]) for s in (-1, 1) for j in range(1, 8)])}
    piece = {"P1": np.array([0.0, 0.6]), "P2": np.array([0.1, 0.6])}
    here = row | pen | piece
    goal = {m: np.append(p, 0.0) for m, p in (row | pen).items()} | {
        "P1": np.array([0.0, -0.1, 0.0]), "P2": np.array([0.0, -0.2, 0.0])}
    way = piece_way(here, set(piece), set(row) | set(pen), "P1", 0.0, "R4", goal, spacing)
    end = way.legs[-1].to + 0.02 * way.push
    assert end[1] > 0.1, "docked outside the pen, on the row's open side"
    offsets = np.array([piece[m] for m in way.piece]) - np.mean(list(piece.values()), axis=0)
    others = np.array([p for m, p in here.items() if m not in piece])
    assert _closest(way.legs, offsets, others, (way.origin, 0.0)) >= spacing


def _docked(way, here: dict, heading: float) -> dict[str, np.ndarray]:
    """Where the way leaves every module of the piece, latched (its push's 2 cm)."""
    shape = np.array([here[m] for m in way.piece])
    offsets = (shape - shape.mean(axis=0)) @ rot_z(heading)[:2, :2]
    end = way.legs[-1].to + 0.02 * way.push
    return dict(zip(way.piece, end + offsets @ rot_z(way.legs[-1].heading)[:2, :2].T,
                    strict=True))


def test_a_straight_piece_with_a_bent_goal_docks_its_root_at_its_goal_place():
    # the goal hangs P1-P2 below T1 and bends P3-P4 along x; the straight piece docks in
    # the shape it has with P1 where the goal wants it, lying straight out from T1 (before,
    # fitted by its centroid, P1 docked 4 cm off T1's side, across T2's)
    from msrr.core.freeform.piece_way import piece_way

    spacing = 0.1
    row = {f"T{i}": np.array([0.1 * i, 0.0]) for i in range(4)}
    piece = {f"P{i}": np.array([0.1 * i - 0.5, 0.8]) for i in range(1, 5)}
    here = row | piece
    goal = {m: np.append(p, 0.0) for m, p in row.items()} | {
        "P1": np.array([0.1, -0.1, 0.0]), "P2": np.array([0.1, -0.2, 0.0]),
        "P3": np.array([0.2, -0.2, 0.0]), "P4": np.array([0.3, -0.2, 0.0])}
    way = piece_way(here, set(piece), set(row), "P1", 0.0, "T1", goal, spacing)
    docked = _docked(way, here, 0.0)
    assert np.allclose(docked["P1"], [0.1, -0.1], atol=0.003)
    assert np.allclose(docked["P4"], [0.1, -0.4], atol=0.003)
    others = np.array(list(row.values()))
    offsets = np.array([piece[m] for m in way.piece]) - np.mean(list(piece.values()), axis=0)
    assert _closest(way.legs, offsets, others, (way.origin, 0.0)) >= spacing - 0.01


def test_a_piece_goal_is_not_turned_by_a_docked_piece_not_yet_bent():
    # the human example: a long piece docked straight down from T2 whose goal bends it
    # along x further down (the plan's last move bends it, later). The goal place of the
    # next piece, on T5, follows the row and the modules in their goal's shape (before:
    # the least squares over all turned it 17 deg, across its neighbour's place)
    from msrr.core.freeform.travel import piece_goal

    row = {f"T{i}": np.array([0.1 * i, 0.0]) for i in range(8)}
    docked = {f"D{j}": np.array([0.2, -0.1 * j]) for j in range(1, 31)}
    goal = {m: np.append(p, 0.0) for m, p in row.items()} | {
        f"D{j}": np.array([0.2, -0.1 * j, 0.0]) if j <= 5
        else np.array([0.2 + 0.1 * (j - 5), -0.5, 0.0]) for j in range(1, 31)} | {
        f"P{i}": np.array([0.5, 0.1 * i, 0.0]) for i in range(1, 6)}
    here = row | docked
    end = piece_goal(goal, here, {f"P{i}" for i in range(1, 6)}, "T5")
    for i in range(1, 6):
        assert np.allclose(end[f"P{i}"], [0.5, 0.1 * i], atol=1e-9)
    # all in their goal's shape: the least squares over all, as before
    exact = piece_goal(goal, row | {m: p[:2] for m, p in goal.items() if m in docked},
                       {f"P{i}" for i in range(1, 6)}, "T5")
    assert np.allclose(exact["P5"], [0.5, 0.5], atol=1e-9)


def test_a_piece_slides_in_between_two_chains_one_spacing_apart_from_a_tilted_start():
    # a comb: chains of five hang from T2 and T4; the goal hangs P1..P5 from T3 between
    # them, one spacing from each, as the human example packs its chains. The piece lies
    # 0.6 deg off the goal's lattice of headings. It stands clear below the comb and
    # slides in along the chains (before: no stand with the way's clearance, and a search
    # that merged every off-lattice heading of a cell into one: no way to the goal place)
    from msrr.core.freeform.piece_way import piece_way

    spacing = 0.1
    row = {f"T{i}": np.array([0.1 * i, 0.0]) for i in range(7)}
    comb = {f"{c}{j}": np.array([x, -0.1 * j]) for c, x in (("A", 0.2), ("B", 0.4))
            for j in range(1, 6)}
    tilt = rot_z(0.01)[:2, :2]
    piece = {f"P{i}": tilt @ np.array([0.1 * i - 0.3, 0.0]) + np.array([0.3, -1.5])
             for i in range(1, 6)}
    here = row | comb | piece
    goal = {m: np.append(p, 0.0) for m, p in (row | comb).items()} | {
        f"P{i}": np.array([0.3, -0.1 * i, 0.0]) for i in range(1, 6)}
    way = piece_way(here, set(piece), set(row) | set(comb), "P1", 0.01, "T3", goal, spacing)
    docked = _docked(way, here, 0.01)
    for i in range(1, 6):
        assert np.allclose(docked[f"P{i}"], [0.3, -0.1 * i], atol=0.003)
    others = np.array([p for m, p in here.items() if m not in piece])
    offsets = (np.array([piece[m] for m in way.piece])
               - np.mean(list(piece.values()), axis=0)) @ tilt
    assert _closest(way.legs, offsets, others, (way.origin, 0.01)) >= spacing - 0.01


def test_a_long_piece_slides_in_between_two_docked_chains_as_long_as_itself():
    # the human example's arm: side chains of 18 docked on T2 and T4, the piece of 18
    # docks on T3 between them. Its stand, clear of both, lies beyond their ends, 1.8 m
    # back: the stretch in grows by the piece's length (before: at most 1.65 m, so no
    # stand on its goal line was clear and it docked at a free place above the row)
    from msrr.core.freeform.piece_way import piece_way

    spacing, n = 0.1, 18
    row = {f"T{i}": np.array([0.1 * i, 0.0]) for i in range(7)}
    comb = {f"{c}{j}": np.array([x, -0.1 * j]) for c, x in (("A", 0.2), ("B", 0.4))
            for j in range(1, n + 1)}
    piece = {f"P{i}": np.array([0.1 * i + 0.6, -3.2]) for i in range(1, n + 1)}
    here = row | comb | piece
    goal = {m: np.append(p, 0.0) for m, p in (row | comb).items()} | {
        f"P{i}": np.array([0.3, -0.1 * i, 0.0]) for i in range(1, n + 1)}
    way = piece_way(here, set(piece), set(row) | set(comb), "P1", 0.0, "T3", goal, spacing)
    docked = _docked(way, here, 0.0)
    for i in (1, n):
        assert np.allclose(docked[f"P{i}"], [0.3, -0.1 * i], atol=0.003)
    others = np.array([p for m, p in here.items() if m not in piece])
    offsets = np.array([piece[m] for m in way.piece]) - np.mean(list(piece.values()), axis=0)
    assert _closest(way.legs, offsets, others, (way.origin, 0.0)) >= spacing - 0.01


def test_a_piece_beside_a_row_its_map_bends_drives_out_along_its_line():
    # under 2 deg of angle noise the map bends a row by millimetres: here the row of four
    # lying beside a row of twelve, one spacing away, zigzags 4 mm, so driving out along
    # its line each module passes the row's modules a little closer than the one that
    # lay beside them (before: it could come only 2 mm closer than it starts, "no free
    # way"; pieces-to-tree at 2 deg stopped so at its first dock)
    from msrr.core.freeform.piece_way import piece_way

    spacing = 0.101
    row = {f"T{i}": np.array([spacing * i, 0.0]) for i in range(12)}
    piece = {f"P{i}": np.array([spacing * i, -spacing - 0.004 * (-1) ** i]) for i in range(4)}
    here = row | piece
    goal = {m: np.append(p, 0.0) for m, p in row.items()} | {
        f"P{i}": np.array([spacing * 8, spacing * (i + 1), 0.0]) for i in range(4)}
    way = piece_way(here, set(piece), set(row), "P0", 0.0, "T8", goal, spacing)
    assert way.legs[0].kind == "drive"                 # straight out along its line
    end = way.legs[-1].to + 0.02 * way.push
    wanted = np.mean([goal[m][:2] for m in piece], axis=0)
    assert np.allclose(end, wanted, atol=0.01)



def _latched(mujoco_driver, name: str, root: str, target: str, piece: tuple[str, ...]):
    """The shipped configuration ``name`` and the FreeBOT controller in the tick that sees
    a piece's latch: ``piece`` was pushing on toward ``target`` (its way's target centre
    far ahead) with its ``root``'s connector armed, and ``root`` reports the latch on
    ``target``; with the commands of that tick."""
    from msrr.core.events import Phase
    from msrr.core.freeform.piece_way import Leg, PieceWay
    from msrr.core.plan import Action, ActionType

    driver = mujoco_driver("freebot", name)
    start = load_configuration(ROOT / "plugins" / "freebot" / "configs" / f"{name}.json")
    controller = plugin.controllers()[0]
    controller.start(start)
    shape = 0.1 * np.arange(len(piece), dtype=float)[:, None] * np.array([1.0, 0.0])
    way = PieceWay(root=root, target=target, piece=piece, origin=np.zeros(2),
                   shape=shape - shape.mean(axis=0), heading=0.0,
                   legs=(Leg("drive", np.zeros(2), 0.3),), centre=np.array([10.0, 0.0]),
                   push=np.array([1.0, 0.0]), line=None)
    controller._pieces = {root: (way, 1)}
    action = Action(ActionType.CONNECTION, start)
    control = controller.control(action, Phase.CONNECT, driver.get_observation())
    return driver, start, controller, control


def test_a_piece_that_reports_its_latch_travels_no_more(mujoco_driver):
    # the tick that saw the latch told the piece to travel again, and that travel outlived
    # the dock: pieces-to-tree under 2 deg of noise (seed 12) rolled a latched row of four
    # on into the tree through the plan's final move until F11-F12 broke at 10.2 N
    driver, _, controller, control = _latched(mujoco_driver, "row4", "F2", "F3", ("F1", "F2"))
    assert not {"F1", "F2"} & set(control.commands), "the latched piece gets no command"
    assert not controller._pieces
    before = {m: driver.world.centre(m) for m in ("F1", "F2")}
    driver.send_action(control.commands)
    driver.step(1.0)
    assert not np.any(driver.world._travel)
    for m, c in before.items():
        assert np.linalg.norm(driver.world.centre(m) - c) < 0.001, m


def test_a_latched_piece_is_not_swung_to_take_out_a_few_degrees(mujoco_driver):
    # once latched a piece's shells are braked, so a move turning its connections, or one
    # that carries it, drags it over the floor: pieces-to-tree under 2 deg of noise broke
    # F2-F3 in the final move (seeds 11, 12). ``line6``: F1 -> F2 -> F3 <- F4 <- F5 <- F6;
    # F1 latched on F2, so F2 -> F3 carries it; F4 -> F3 does not
    driver, start, controller, _ = _latched(mujoco_driver, "line6", "F1", "F2", ("F1",))
    observation = driver.get_observation()

    def turned(degrees: float) -> Configuration:
        goal = start.copy()
        for e in list(goal.edges()):
            turn = {("F2", "F3"): degrees, ("F4", "F3"): -degrees}.get((e.source, e.target))
            if turn is not None:
                goal.disconnect(e.id)
                goal.connect(e.source, e.target, z=rot_z(np.radians(turn)) @ np.asarray(e.z))
        return goal

    near = controller.commands(turned(3.0), observation)
    assert "F4" in near and not {"F1", "F2"} & set(near)
    far = controller.commands(turned(30.0), observation)
    assert {"F2", "F4"} <= set(far)


def _turned_from(start: Configuration, source: str, degrees: float) -> Configuration:
    """``start`` with the connection out of ``source`` turned by ``degrees`` about the
    vertical."""
    goal = start.copy()
    for e in list(goal.edges()):
        if e.source == source:
            goal.disconnect(e.id)
            goal.connect(e.source, e.target, z=rot_z(np.radians(degrees)) @ np.asarray(e.z))
    return goal


def test_a_latched_piece_a_few_degrees_off_is_swung_onto_its_goal_rolling(mujoco_driver):
    # a latch lands where the piece's root touches its target, which the map has
    # centimetres off under noise; held within 20 deg, the piece stayed off:
    # pieces-to-tree at 2 deg, seed 18, both rows latched and the true shape ended 5.04
    # deg off (the judge's tolerance 5). ``line6`` with F1 latched on F2 (F2 -> F3
    # carries it), the goal turning F1 -> F2 by 6 deg about the vertical: F1 rolls round
    # F2 onto it, the rest stays, nothing breaks, and the move's measure counts the swing
    from msrr.core.freeform.recognition import piece_turn

    driver, start, controller, _ = _latched(mujoco_driver, "line6", "F1", "F2", ("F1",))
    goal = _turned_from(start, "F1", 6.0)
    links = {e.source: e.target for e in start.edges()}
    truth = driver.ground_truth()
    assert np.degrees(abs(piece_turn(truth, goal, links, "F2", ("F1",)))) > 5.0
    rest = [e.id for e in start.edges() if e.source != "F1"]
    before = truth.vectors(rest)
    seen = controller.recognizer.recognize(driver.get_observation().sensors)
    assert np.degrees(controller.reach_measure(seen, goal)) > 2.5, "the swing counts"
    for _ in range(100):
        observation = driver.get_observation()
        driver.send_action(controller.commands(goal, observation))
        driver.step(0.1)
    truth = driver.ground_truth()
    assert "F1" in controller.latches.settled
    assert np.degrees(abs(piece_turn(truth, goal, links, "F2", ("F1",)))) < 1.0
    assert np.degrees(np.max(np.arccos(np.clip(np.sum(truth.vectors(rest) * before, axis=0),
                                               -1, 1)))) < 0.5
    assert not driver.faults()
    seen = controller.recognizer.recognize(driver.get_observation().sensors)
    assert np.degrees(controller.reach_measure(seen, goal)) < 1.0, "settled: held"


def test_a_move_is_not_reached_before_its_latched_pieces_are_swung(mujoco_driver):
    # in the RMS over every commanded bend a swinging piece's turn was diluted: a row
    # turned 3.6 deg among 19 connections kept the final move under its 3 deg, which
    # ended within 0.1-1.4 s, the swing not begun or cut short (pieces-to-tree at 2 deg,
    # seed 10: both rows left 2.2 and 3.6 deg turned on ground truth). ``line6`` with F1
    # latched on F2, the goal turning F1 -> F2 by 2 deg: not reached until it is swung
    from msrr.core.closed_loop import TrackingOptions

    driver, start, controller, _ = _latched(mujoco_driver, "line6", "F1", "F2", ("F1",))
    goal = _turned_from(start, "F1", 2.0)
    seen = controller.recognizer.recognize(driver.get_observation().sensors)
    tolerance = TrackingOptions().reach_tolerance
    assert controller.reach_measure(seen, goal) >= tolerance, "the swing is pending"
    controller.latches.settled.add("F1")
    assert controller.reach_measure(seen, goal) < tolerance, "swung: the bends only"


def test_a_move_is_reached_on_the_bends_it_commands_not_on_a_held_latch(mujoco_driver):
    # a latched piece's connections within 20 deg of the goal are held, not moved, so a
    # move reached on them too stalls on the latch's error: pieces-to-tree's final move
    # under 2 deg of noise (seed 15: 5.5 deg for 15 s, twice, 18 of 19 connections held).
    # ``line6`` with F1 latched on F2: F1 -> F2 is held once its swing is done
    # (test_a_latched_piece_a_few_degrees_off_is_swung_onto_its_goal_rolling), F4 -> F3 moves
    driver, start, controller, _ = _latched(mujoco_driver, "line6", "F1", "F2", ("F1",))
    current = controller.recognizer.recognize(driver.get_observation().sensors)
    measure = controller.reach_measure

    def turned(**turns: float) -> Configuration:
        goal = start.copy()
        for e in list(goal.edges()):
            if e.source in turns:
                goal.disconnect(e.id)
                goal.connect(e.source, e.target,
                             z=rot_z(np.radians(turns[e.source])) @ np.asarray(e.z))
        return goal

    held = turned(F1=10.0)
    assert np.degrees(bend_error(current, held)) > 4.0
    assert np.degrees(measure(current, held)) > 4.0, "F1 still to be swung: counted"
    controller.latches.settled.add("F1")     # its swing done (or given up): held
    assert np.degrees(measure(current, held)) < 0.5, "F1 -> F2 is held: not counted"
    assert np.degrees(measure(current, turned(F1=10.0, F4=-10.0))) > 4.0, "F4 is moved"
    assert np.degrees(measure(current, turned(F1=30.0))) > 10.0, "farther: moved again"


def test_a_piece_pushes_on_toward_its_target_where_the_map_has_it_now(mujoco_driver):
    # the guarded push aimed at the target's centre as the way planned it: a row at rest
    # rolls on once pushed (nothing brakes a sphere on the floor), and in chains-to-tree
    # the row F1-F4 rolled 9 cm across while F9-F12 travelled; the push stopped at the
    # planned place, 9 cm short of F3, and the dock never latched (2 x 90 s). Here the
    # way was planned with F3 15 cm further on than the map has it now: the push goes on.
    from dataclasses import replace

    from msrr.core.events import Phase
    from msrr.core.freeform.piece_way import Leg, PieceWay
    from msrr.core.plan import Action, ActionType

    name = "chains12/chains12-forest"
    driver = mujoco_driver("freebot", name)
    start = load_configuration(ROOT / "plugins" / "freebot" / "configs" / f"{name}.json")
    controller = plugin.controllers()[0]
    controller.start(start)
    observation = driver.get_observation()
    controller._locate(observation.sensors)
    piece = ("F9", "F10", "F11", "F12")
    target = controller.locator.pose("F3")[0][:2]
    root = controller.locator.pose("F12")[0][:2]
    push = (target - root) / np.linalg.norm(target - root)
    shape = 0.1 * np.arange(4, dtype=float)[:, None] * np.array([1.0, 0.0])
    way = PieceWay(root="F12", target="F3", piece=piece, origin=np.zeros(2),
                   shape=shape - shape.mean(axis=0), heading=0.0,
                   legs=(Leg("drive", np.zeros(2), 0.0),), centre=root - 0.05 * push,
                   push=push, line=None)
    heading = way.heading_of({m: controller.locator.pose(m)[0] for m in piece})
    way = replace(way, legs=(Leg("drive", np.zeros(2), heading),))   # no turn left
    controller._pieces = {"F12": (way, 1)}
    control = controller.control(Action(ActionType.CONNECTION, start), Phase.CONNECT,
                                 observation)
    assert control.commands["F12"].dock == ("@F3",)
    frame = rot_z(controller.locator.pose("F12")[1])[:2, :2]
    joints = control.commands["F12"].joints
    velocity = frame @ np.array([joints["roll_x"], joints["roll_y"]])
    assert float(velocity @ push) > 0.4 * controller.piece_speed, velocity
    assert control.errors["F12"] > 0.0 and not control.reached


def _drive_with_keel_off(off: float) -> tuple[float, float]:
    """The row F1..F4 let go of F5 across its line, told 0.02 m/s along its line for 3 s,
    its keel F4's command turned by ``off`` [rad] (its unit's frame turned about the
    vertical): the line's turn [deg] and the centroid's motion across it [m], on ground truth."""
    driver = _row_let_go_across("keel")
    piece = ("F1", "F2", "F3", "F4")
    before = np.array([driver.world.centre(m)[:2] for m in piece])
    for _ in range(30):
        _twist(driver, piece, SPEED, 0.0)
        command = driver.world._travel_v[driver.world._k("F4")]
        driver.world._travel_v[driver.world._k("F4")] = rot_z(off) @ command
        driver.step(0.1)
    after = np.array([driver.world.centre(m)[:2] for m in piece])
    line = (before[-1] - before[0]) / np.linalg.norm(before[-1] - before[0])
    now = (after[-1] - after[0]) / np.linalg.norm(after[-1] - after[0])
    moved = after.mean(axis=0) - before.mean(axis=0)
    turn = np.degrees(np.arctan2(line[0] * now[1] - line[1] * now[0], line @ now))
    return float(turn), float(line[0] * moved[1] - line[1] * moved[0])


def test_a_keel_whose_frame_turned_drives_with_its_piece():
    # the keel's magnet unit hangs on a free bearing, so it turns about the vertical with
    # nothing holding it (5 deg in its swing down in chains-to-tree), and its command is
    # given in its gyro's frame: the keel, the one module that holds the piece's velocity
    # across its line, drove 2 deg off the line, the piece turned 2 deg in 13 s into the row
    # beside it and pushed it 9 cm aside (the dock then missed). The keel now hangs toward
    # its piece's twist, taken from an arm of the piece
    turn, across = _drive_with_keel_off(np.radians(6.0))
    assert abs(turn) < 0.5 and abs(across) < 0.005, (turn, across)   # main: 1.49 deg


def test_a_straight_piece_with_a_shallow_c_for_a_goal_docks_straight_out_from_its_target():
    # the goal hangs P1-P2 from T1 at -114 deg, then P3 straight down, P4 at -66 deg: a
    # shallow C, within a quarter spacing of a line (the human example's step 2: a rib of
    # two and its two riders). The piece lies straight out through P1's goal place (before:
    # fitted by least squares, it hung straight down, across T2's rib at -114 deg)
    from msrr.core.freeform.piece_way import piece_way

    spacing = 0.1
    row = {f"T{i}": np.array([0.1 * i, 0.0]) for i in range(4)}
    piece = {f"P{i}": np.array([0.1 * i - 0.2, -1.0]) for i in range(1, 5)}
    here = row | piece
    rib = np.array([np.cos(np.radians(-114.0)), np.sin(np.radians(-114.0))])
    tail = np.array([np.cos(np.radians(-66.0)), np.sin(np.radians(-66.0))])
    p1 = row["T1"] + spacing * rib
    p3 = p1 + spacing * rib + np.array([0.0, -spacing])
    goal = {m: np.append(p, 0.0) for m, p in row.items()} | {
        m: np.append(p, 0.0) for m, p in
        {"P1": p1, "P2": p1 + spacing * rib, "P3": p3, "P4": p3 + spacing * tail}.items()}
    way = piece_way(here, set(piece), set(row), "P1", 0.0, "T1", goal, spacing)
    docked = _docked(way, here, 0.0)
    assert np.allclose(docked["P1"], p1, atol=0.003)
    assert np.allclose(docked["P4"], row["T1"] + 4 * spacing * rib, atol=0.003)


def test_a_long_move_is_refused_at_its_first_hit_without_checking_the_rest():
    # the direct way is tried from every eighth pose of the search, metres long, and a
    # failing one mostly hits near its start: checked whole, the human example's first
    # step spent most of its 11 minutes of planning sampling drives already refused
    from msrr.core.freeform import piece_way as ways

    offsets = np.array([[-0.05, 0.0], [0.05, 0.0]])
    space = ways._Space(np.array([[0.0, 0.0]]), offsets, 0.1, (np.array([5.0, 5.0]), 0.0))
    tree, queried = space.tree, []

    class Counting:
        def query(self, points, **options):
            queried.append(len(points))
            return tree.query(points, **options)

    space.tree = Counting()
    assert not space.drive_free(np.array([0.0, 0.05]), np.array([3.0, 0.05]), 0.0)
    assert sum(queried) < 601, "not all its 601 poses (1,202 points) sampled"
    assert space.drive_free(np.array([0.0, 0.5]), np.array([3.0, 0.5]), 0.0)


def test_a_stand_between_docked_chains_is_free_off_its_line_not_by_a_hair():
    # the human example's action 46: a chain of three slides in between two docked
    # chains, its stand chosen where it cleared them by 0.2 mm, free nowhere 1 mm aside,
    # so no way of the search (poses on a lattice, ending in a turn) reached it. Here the
    # walls' modules line up with the piece's at the first stand (0.1092 m, the clearance
    # 0.109 m), and lie half a module off them one step further back
    from msrr.core.freeform import piece_way as ways

    s = 0.101
    offsets = np.array([[-s, 0.0], [0.0, 0.0], [s, 0.0]])       # root first, at -x
    middle, push = np.array([2 * s, 0.0]), np.array([-1.0, 0.0])
    first = middle[0] + ways._SHORT + ways._LAST               # the first stand's centroid
    walls = np.array([[first + s * (k - 1), side * 0.1092] for k in range(25)
                      for side in (-1, 1)])
    others = np.vstack([[[0.0, 0.0]], walls])                   # the target first
    space = ways._Space(others, offsets, s, (np.array([5.0, 5.0]), 0.0))
    back = ways._dock_free(space, offsets, 0, others, 0, middle, 0.0, push, clear_in=False)
    assert back is not None
    stand = middle - (ways._SHORT + back) * push
    for aside in (0.001, -0.001):
        assert space.free((stand + np.array([0.0, aside]))[None, :], np.array([0.0])), aside


def test_a_piece_way_is_the_one_planned_before_its_search_was_batched(monkeypatch):
    # the moves from one pose checked in one query of the obstacles, and a long move
    # stopped at its first hit, change no answer (legs to the tenth of a millimetre, as
    # planned by the search before, at commit dbff9af): chains-to-tree's layout, and a
    # piece whose goal place no way reaches before it docks at a free place
    from msrr.core.freeform import piece_way as ways
    from msrr.core.freeform.piece_way import piece_way, plan_legs

    rows = np.array([[0.101 * i, y] for y in (0.0, 0.101) for i in range(4)])
    chain = np.array([[0.101 * i, 0.202] for i in range(4)])
    start = (chain.mean(axis=0), 0.0)
    goal = (np.array([0.202, 0.101 + 0.121 + 0.1515 + 0.15]), -np.pi / 2)
    legs = plan_legs(rows, chain - start[0], np.array([1.0, 0.0]), start, goal, 0.101)
    assert _rounded(legs) == [("drive", 0.5415, 0.202, 0.0), ("turn", 0.5415, 0.202, -0.7582),
                              ("drive", 0.202, 0.5235, -0.7582),
                              ("turn", 0.202, 0.5235, -1.5708)]
    monkeypatch.setattr(ways, "_EXPANSIONS", 300)
    row = {f"R{i}": np.array([0.1 * i - 0.4, 0.0]) for i in range(9)}
    pen = {f"W{k}": p for k, p in enumerate(
        [np.array([x, -0.8]) for x in np.arange(-0.4, 0.41, 0.1)]
        + [np.array([s * 0.4, -0.1 * j]) for s in (-1, 1) for j in range(1, 8)])}
    piece = {"P1": np.array([0.0, 0.6]), "P2": np.array([0.1, 0.6])}
    goals = {m: np.append(p, 0.0) for m, p in (row | pen).items()} | {
        "P1": np.array([0.0, -0.1, 0.0]), "P2": np.array([0.0, -0.2, 0.0])}
    way = piece_way(row | pen | piece, set(piece), set(row) | set(pen), "P1", 0.0, "R4",
                    goals, 0.1)
    assert _rounded(way.legs) == [("turn", 0.05, 0.6, 1.8992), ("drive", 0.16, 0.2771, 1.8992),
                                  ("turn", 0.16, 0.2771, 1.0472), ("drive", 0.085, 0.1472, 1.0472)]


def _rounded(legs) -> list[tuple[str, float, float, float]]:
    return [(leg.kind, round(float(leg.to[0]), 4), round(float(leg.to[1]), 4),
             round(float(leg.heading), 4)) for leg in legs]


def test_a_piece_latched_far_off_counts_its_whole_turn_in_the_measure(mujoco_driver):
    # a piece latched beyond the hold band is moved by its connections, but in the RMS
    # over a large robot its few connections weigh little (3 of 560 connections 60 deg
    # off: 4.4 deg RMS). ``line6`` with F1 latched on F2, the goal turning F1 -> F2 by 40
    # deg: the measure is that turn, not its share of the robot's RMS (20 deg before)
    from msrr.core.freeform.recognition import piece_turn

    driver, start, controller, _ = _latched(mujoco_driver, "line6", "F1", "F2", ("F1",))
    goal = _turned_from(start, "F1", 40.0)
    links = {e.source: e.target for e in start.edges()}
    turn = abs(piece_turn(driver.ground_truth(), goal, links, "F2", ("F1",)))
    assert np.degrees(turn) > 35.0
    seen = controller.recognizer.recognize(driver.get_observation().sensors)
    assert np.degrees(controller.reach_measure(seen, goal)) > 35.0, "diluted in the RMS"


def test_a_straight_piece_re_aims_a_drive_in_place_and_ends_on_its_line():
    # a straight piece cannot steer as it drives, so its line points where its last turn
    # left it: 1.5 deg off over the human example's 3.5 m drive put a piece 50 mm across
    # its way, and its push latched 19 deg off its goal place (action 5). Told a 0.4 m
    # drive 2 deg off its line (14 mm across at the end, driven as it points), it turns
    # in place first and ends on the drive's line, on ground truth
    from msrr.core.events import Phase
    from msrr.core.freeform.piece_way import Leg, PieceWay
    from msrr.core.plan import Action, ActionType

    driver = _row_let_go_across("aim")
    piece, off = ("F1", "F2", "F3", "F4"), np.radians(2.0)
    controller = plugin.controllers()[0]
    controller._locate(driver.get_observation().sensors)
    centres = np.array([controller.locator.pose(m)[0][:2] for m in piece])
    middle, heading = centres.mean(axis=0), controller.locator.pose("F4")[1]
    line = (centres[-1] - centres[0]) / np.linalg.norm(centres[-1] - centres[0])
    end = middle + 0.4 * rot_z(off)[:2, :2] @ line
    way = PieceWay(root="F4", target="F5", piece=piece, origin=middle,
                   shape=centres - middle, heading=heading,
                   legs=(Leg("drive", end, heading + off),), centre=end + 0.2 * line,
                   push=line, line=rot_z(-heading)[:2, :2] @ line)
    controller._pieces = {"F4": (way, 0)}
    truth = np.array([driver.world.centre(m)[:2] for m in piece])
    along = rot_z(off)[:2, :2] @ (truth[-1] - truth[0]) / np.linalg.norm(truth[-1] - truth[0])
    action = Action(ActionType.CONNECTION, Configuration("freebot", name="aim"))
    assert control_until_reached(controller, action, Phase.APPROACH, driver, 400).reached
    moved = np.array([driver.world.centre(m)[:2] for m in piece]).mean(axis=0) - truth.mean(axis=0)
    assert float(moved @ along) > 0.39
    assert abs(float(along[0] * moved[1] - along[1] * moved[0])) < 0.003
