"""Fig. 22(j)'s node wheels in MuJoCo (issue 31): the structure stands still with its wheels
stopped, and each floor node spins as fast as its wheel pair is asked, judged on the
simulator's bodies."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from freesn_held import held_commands
from scipy.spatial.transform import Rotation

from msrr.core.io import load_configuration
from msrr.core.library import load_library
from msrr.plugins.freesn.robot import SPEC, STRUT
from msrr.plugins.freesn.sim import FreeSNMujocoDriver, FreeSNWorld, SimOptions
from msrr.plugins.freesn.sim.controller import FreeSNController
from msrr.plugins.freesn.sim.world import _LEVEL_STEP

FREESN = Path(__file__).resolve().parents[3] / "plugins" / "freesn"
WHEELS = (("B1", "R1"), ("B2", "R3"), ("B3", "R5"))
"""Floor node -> the ring strut whose target connector spins it (the library's gait)."""


def _run(speed: float, seconds: float, sideways: float = 0.0
         ) -> tuple[np.ndarray, np.ndarray, dict[str, float]]:
    """fig22(j) held in shape by the controller every 0.1 s, its wheels at the library's
    gains for ``speed`` (and ``sideways``) from 1 s on: the centre (t, 2) [m] and each floor node's spin
    about its wheel strut's axis relative to the strut (t, 3) [rad/s], and the spins
    asked [rad/s]."""
    library = load_library(FREESN / "libraries" / "S12N6.json").sublibraries["S12N6"]
    behavior = library.behaviors["node-wheels"]
    start = load_configuration(FREESN / "configs" / "library" / "S12N6-5.1.json")
    wheels = {c.module: {c.connector: c.value({"speed": speed, "sideways": sideways})}
              for c in behavior.commands if c.command == "wheel_speed"}
    half_base = 0.5 * STRUT.geometry["wheel_base"]
    asked = {s: w["target"] * STRUT.geometry["wheel_radius"] / half_base
             for s, w in wheels.items()}
    controller = FreeSNController()
    centres, spins = [], []
    with FreeSNMujocoDriver() as driver:
        driver.reset(start)
        world = driver.world

        def frames() -> list[np.ndarray]:
            return [world.data.xmat[world._strut_body[world._strut_index[s]]].reshape(3, 3).T
                    @ world.data.xmat[world._node_body[world._node_index[n]]].reshape(3, 3)
                    for n, s in WHEELS]

        yaw = None
        for tick in range(round(seconds / 0.1)):
            commands, yaw = held_commands(controller, start, driver.get_observation(),
                                          wheels, tick, yaw)
            before = frames()
            driver.send_action(commands)
            driver.step(0.1)
            turned = [Rotation.from_matrix(a @ b.T).as_rotvec() / 0.1
                      for a, b in zip(frames(), before, strict=True)]
            spins.append([t[2] for t in turned])
            centres.append(world.data.xpos[world._node_body].mean(axis=0)[:2].copy())
    return np.array(centres), np.array(spins), asked


def test_fig22j_stands_still_with_its_wheels_stopped():
    """With R6 level (stop 36) the struts' weight moments on the floor nodes crept the
    structure 4.7 mm/s; R6 upright puts none on B3 (design.py, ``ring_struts``)."""
    centres, _, _ = _run(0.0, 4.0)
    creep = np.linalg.norm(centres[-1] - centres[9]) / 3.0
    assert creep < 0.002


def test_fig22j_floor_nodes_spin_as_their_wheels_are_asked():
    """Open loop at 0.03 m/s: B1 and B3 spin at the asked rate within 10 % (they ran at 27 %
    and 125 %: a wheel command was a voltage that drooped under load, and the node's other
    connectors re-aimed only at each command, braking the spin in between), B2, asked
    twice as much, at least 60 % (its torque limit), and the body goes along +x."""
    centres, spins, asked = _run(0.03, 5.0)
    spin = spins[25:].mean(axis=0)
    for i, (_, strut) in enumerate(WHEELS):
        ratio = spin[i] / asked[strut]
        assert (0.9 < ratio < 1.1) if strut != "R3" else (0.6 < ratio < 1.1), (strut, ratio)
    moved = centres[-1] - centres[25]
    assert np.linalg.norm(moved) > 0.01 and abs(np.arctan2(moved[1], moved[0])) < np.radians(15)


def test_fig22j_slides_sideways_as_its_wheels_are_asked():
    """The three floor nodes roll 120 deg apart, a kiwi drive: asked ``sideways`` alone the
    body goes along +y (the course loop slides the travel back onto the line instead of
    turning the body, which every wheel scrubs; issue 31). Before, nothing moved."""
    centres, _, _ = _run(0.0, 5.0, sideways=0.03)
    moved = centres[-1] - centres[25]
    assert np.linalg.norm(moved) > 0.01
    assert abs(np.degrees(np.arctan2(moved[1], moved[0])) - 90.0) < 20.0


def test_fig22j_held_at_4_degrees_of_noise_keeps_its_top_up():
    """fig22(j) held still by the controller (filtered reports, as the executor's) with 4
    deg of sensor noise, seed 10: its top nodes stay up (the lowest above 190 mm; 214 mm
    designed). Its connectors servo on their own attitude and localisation estimates;
    with a fresh fix fused at 0.2 per command (``fusion``; 0.45 s) they chased its 1.3 deg
    jitter and T1 sank to 121 mm in 10 s (issue 31, stop 47); at 0.05 (2 s) it holds."""
    start = load_configuration(FREESN / "configs" / "library" / "S12N6-5.1.json")
    controller = FreeSNController()
    tops = []
    with FreeSNMujocoDriver(noise=np.radians(4.0), seed=10) as driver:
        driver.reset(start)
        world = driver.world
        reports = controller._recognizer.report_filter()
        top = [world._node_body[world._node_index[n]] for n in ("T1", "T2", "T3")]
        yaw = None
        for tick in range(100):
            observation = reports.update(driver.get_observation())
            commands, yaw = held_commands(controller, start, observation, {}, tick, yaw)
            driver.send_action(commands)
            driver.step(0.1)
            tops.append(world.data.xpos[top, 2].min())
    assert min(tops) > 0.19


def test_a_held_top_node_that_is_not_the_root_is_kept_off_upside_down():
    """fig22(j) held still by the controller (filtered reports, as the executor's), the
    attitude estimate of its top node ``T3`` 2.9 deg off about x at every command (noise
    itself negligible): its shell, free under its four connectors, takes the error for
    good and rolls over, and past the report filter's upright bound (120 deg) its heading
    is left to its gyro, so every command to it is turned by that drift (issue 31, stop
    57: fig22 from unseen start 5404, seed 22, ``n4`` at 165-172 deg, its heading 3-8 deg
    off for 25 s, its connectors saturated and the top sagged). ``T3`` is not the group's
    root (``T2``: four connectors, the first id), and the levelling was the root's alone:
    it reached 179 deg in 10 s; levelled as a node its struts hold up, it stays under 105
    deg."""
    start = load_configuration(FREESN / "configs" / "library" / "S12N6-5.1.json")
    controller = FreeSNController()
    tilts = []
    with FreeSNMujocoDriver(noise=1e-6, seed=10) as driver:
        driver.reset(start)
        world = driver.world
        node = world._node_index["T3"]
        body = world._node_body[node]
        reports = controller._recognizer.report_filter()
        yaw = None
        for tick in range(100):
            observation = reports.update(driver.get_observation())
            commands, yaw = held_commands(controller, start, observation, {}, tick, yaw)
            world._attitude[node] = [np.radians(2.9), 0.0, 0.0]
            driver.send_action(commands)
            driver.step(0.1)
            tilts.append(np.degrees(np.arccos(np.clip(world.data.xmat[body][8], -1.0, 1.0))))
    assert max(tilts) < 115.0


def test_a_node_standing_on_the_floor_is_not_levelled_but_one_held_up_is():
    """Past 100 deg a node that is not its group's root is levelled only if one of its
    struts is commanded down from it (its struts hold it up): fig22(j)'s floor node ``B1``
    (three struts, all commanded upward) tilted 150 deg keeps its frame, since its shell
    rolls on the floor when turned (levelling every held node stalled fig22's move after
    R6's undock from unseen start 5404, seeds 17 and 18: the floor nodes turned 5 deg a
    command; issue 31, stop 57); the top node ``T3`` is turned ``_LEVEL_STEP`` toward
    upright. Both were left alone when the root alone was levelled."""
    start = load_configuration(FREESN / "configs" / "library" / "S12N6-5.1.json")
    world = FreeSNWorld(start, SPEC, SimOptions())
    for strut, end in world.ends:
        if world.docked[world._end_index[(strut, end)]] is not None:
            z = start.edge(strut).z * (1.0 if end == "a" else -1.0)
            world.command_target(strut, end, (np.asarray(z, dtype=float), None, 1.0))
    tilted = Rotation.from_rotvec([np.radians(150.0), 0.0, 0.0]).as_matrix()
    assert np.allclose(world._levelled(world._node_index["B1"], tilted), np.eye(3))
    up = (world._levelled(world._node_index["T3"], tilted) @ tilted)[:, 2]
    assert np.degrees(np.arccos(up[2])) == pytest.approx(150.0 - np.degrees(_LEVEL_STEP))
