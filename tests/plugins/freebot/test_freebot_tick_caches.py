"""What the FreeBOT MuJoCo run keeps between ticks (issue 28, item 6: the 568-module
human example per simulated second): each memo found again when what it was found from
changed, and each batched readout the same, to the bit, as one module after another."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from msrr.core.alignment import rot_z, rot_zs
from msrr.core.configuration import Configuration
from msrr.core.freeform.mujoco import SensorNoise, yaw_of, yaws_of
from msrr.core.freeform.recognition import link_headings, links_of, module_headings
from msrr.core.plan import link_layout


def test_link_headings_are_found_again_when_a_report_changes_in_place(mujoco_driver):
    reports = mujoco_driver("freebot", "line6").world.reports()
    links, heading = link_headings(reports)
    assert links == links_of(reports) and heading == module_headings(reports)
    assert link_headings(reports)[0] is links          # the same tick's reports: kept
    reports["F1"] = replace(reports["F1"], attached=None, relative=None)   # F1 let go
    links, heading = link_headings(reports)
    assert "F1" not in links and links == links_of(reports)
    assert heading == module_headings(reports)
    again = dict(reports)
    again["F2"] = replace(again["F2"], tilt=rot_z(0.3) @ again["F2"].tilt)
    assert link_headings(again)[1] == module_headings(again) != heading


def _chain(z: list[float]) -> Configuration:
    config = Configuration("freebot")
    for m in ("A", "B", "C"):
        config.add_module(m, "freebot")
    config.connect("A", "B", z=z)
    config.connect("B", "C", z=[1.0, 0.0, 0.0])
    return config


def test_a_link_layout_changes_with_a_link_and_not_with_a_vector():
    assert link_layout(_chain([1.0, 0.0, 0.0])) == link_layout(_chain([0.0, 1.0, 0.0]))
    other = _chain([1.0, 0.0, 0.0])
    other.disconnect(other.edge_ids()[0])
    other.connect("C", "A", z=[1.0, 0.0, 0.0])
    assert link_layout(other) != link_layout(_chain([1.0, 0.0, 0.0]))
    ported = Configuration("freebot")
    for m in ("A", "B", "C"):
        ported.add_module(m, "freebot")
    ported.connect("A", "B", z=[1.0, 0.0, 0.0], ports=("magnet", "magnet"))
    ported.connect("B", "C", z=[1.0, 0.0, 0.0])
    assert link_layout(ported) != link_layout(_chain([1.0, 0.0, 0.0]))


def test_batched_rotations_are_each_modules_own_to_the_bit():
    rng = np.random.default_rng(3)
    yaws = rng.uniform(-7.0, 7.0, 40)
    assert np.array_equal(rot_zs(yaws), np.array([rot_z(y) for y in yaws]))
    readings = rot_zs(yaws) @ rot_zs(rng.uniform(-3.0, 3.0, 40)).transpose(0, 2, 1)
    one, many = SensorNoise(0.03, 12), SensorNoise(0.03, 12)
    assert np.array_equal(many.rotations(readings), np.array([one.rotation(r) for r in readings]))
    assert np.array_equal(SensorNoise(0.0, 12).rotations(readings), readings)
    assert yaws_of(readings).tolist() == [yaw_of(r) for r in readings]
