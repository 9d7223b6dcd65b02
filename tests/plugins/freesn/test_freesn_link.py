"""FreeSN over the module link (issue 32, item 3): the reports' encoder counts
(``StrutReport.rolled``) and stated accuracy (``accuracy``) travel, quantised as the
codec quantises rotations, with the record table docs/hardware.md gives for FreeSN; and a
noisy FreeSN emulated behind the link is filtered by the host as in simulation."""

from __future__ import annotations

import json
import math
import re
import threading
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.spatial.transform import Rotation

from msrr.core import plugins
from msrr.core.app.cli import get_cli
from msrr.core.app.run import RunRequest, execute_run, prepare_run
from msrr.core.driver import Observation
from msrr.core.link import Emulator, KeyRef, write_key, write_system
from msrr.core.link.codec import Codec, RecordSpec, RecordTable, infer_records
from msrr.plugins.freesn.sim import FreeSNMujocoDriver
from msrr.plugins.freesn.sim.recognizer import FreeSNRecognizer
from msrr.plugins.freesn.sim.world import Accuracy, NodeReport, StrutReport

ROOT = Path(__file__).resolve().parents[3]
CONFIGS = ROOT / "plugins" / "freesn" / "configs" / "library"
NOISE = math.radians(4.0)


def _documented_table() -> RecordTable:
    """The record table of the systems file in docs/hardware.md (FreeSN's)."""
    text = (ROOT / "docs" / "hardware.md").read_text()
    block = re.search(r"```json\n(.*?)```", text, re.S)
    assert block is not None
    records = json.loads(block.group(1))["records"]
    return RecordTable([RecordSpec(r["type"], tuple(r.get("rotations", ())),
                                   tuple(r.get("directions", ()))) for r in records])


def _noisy_reports() -> list[NodeReport | StrutReport]:
    start = plugins.load_configuration(CONFIGS / "S6N3-2.3.json")
    with FreeSNMujocoDriver(noise=NOISE, slip=0.10, seed=2) as driver:
        driver.reset(start)
        driver.step(0.3)
        return list(driver.get_observation().sensors.values())


def test_the_documented_freesn_record_table_is_what_its_reports_need():
    """docs/hardware.md's records are the table ``platform emulate`` infers from FreeSN's
    reports: ``Accuracy`` a record, ``rolled`` a rotation field."""
    assert _documented_table().specs == tuple(infer_records(_noisy_reports()))


def test_reports_round_trip_with_their_encoder_counts_and_accuracy():
    codec = Codec(_documented_table())
    reports = _noisy_reports()
    strut = next(r for r in reports if isinstance(r, StrutReport) and len(r.rolled) == 2)
    node = next(r for r in reports if isinstance(r, NodeReport))
    assert strut.accuracy.angle == NOISE
    strut = replace(strut, rolled={"a": Rotation.from_rotvec([0.4, -0.2, 1.1]).as_matrix(),
                                   "b": Rotation.from_rotvec([0.0, 0.0, -2.5]).as_matrix()})
    back_strut, back_node = codec.decode(codec.encode(strut)), codec.decode(codec.encode(node))
    for end, rolled in strut.rolled.items():   # within the rotation quantum (8e-5 rad)
        np.testing.assert_allclose(back_strut.rolled[end], rolled, atol=1e-4)
    assert back_strut.accuracy == back_node.accuracy == Accuracy(
        *(float(np.float32(getattr(strut.accuracy, f))) for f in
          ("angle", "slip", "drift", "gyro_noise", "gyro_bias", "gyro_walk")))
    bare = Codec(_documented_table()).encode(
        StrutReport(strut.docked, strut.attitude, strut.tilt, strut.magnet, strut.events, {},
                    strut.accuracy))
    assert len(codec.encode(strut)) - len(bare) <= 2 * (2 + 1 + 6)   # per end: key, head, 6


@pytest.fixture
def emulated_freesn(tmp_path):
    """S6N3-2.3's nine modules emulated at 4 deg + 10 % slip, serving in a thread."""
    capabilities = plugins.capabilities("freesn")
    factory = capabilities.driver()
    emulator = Emulator(factory, plugins.load_configuration(CONFIGS / "S6N3-2.3.json"),
                        recognizer=capabilities.recognizer(factory.companions.recognizer),
                        speed=2.0, timeout=2.0, seed=3,
                        driver_options=(("noise", str(NOISE)), ("slip", "0.1")))
    stop = threading.Event()
    with emulator:
        write_key(tmp_path / "system.key", emulator.key)
        path = write_system(tmp_path / "system.json",
                            emulator.system_file(KeyRef(file="system.key"), "freesn"))
        thread = threading.Thread(target=emulator.serve, kwargs={"duration": 120.0,
                                                                 "stop": stop.is_set})
        thread.start()
        try:
            yield path
        finally:
            stop.set()
            thread.join(10.0)
            assert not thread.is_alive()


def test_a_noisy_freesn_emulated_over_the_link_is_filtered(tmp_path, emulated_freesn,
                                                            monkeypatch):
    """S6N3 2.3 -> 3.1 (a leg swings and docks) with ``--driver link`` against the
    emulated modules: the reports arrive stating 4 deg and the host's report filter
    filters every tick. (Whether the run then reaches its goal is not asserted: it depends
    on the machine's load, the emulator running at twice real time.)"""
    seen: list[tuple[Accuracy, bool]] = []
    make = FreeSNRecognizer.report_filter

    class Counting:
        def __init__(self, inner):
            self.inner = inner

        def update(self, observation: Observation) -> Observation:
            out = self.inner.update(observation)
            accuracy = next(iter(observation.sensors.values())).accuracy
            seen.append((accuracy, out is not observation))
            return out

    monkeypatch.setattr(FreeSNRecognizer, "report_filter", lambda self: Counting(make(self)))
    result = execute_run(prepare_run(RunRequest(
        robot="freesn", start=CONFIGS / "S6N3-2.3.json", goal=CONFIGS / "S6N3-3.1.json",
        out=tmp_path / "run", log=False, seed=3, driver="link", deadline=6.0,
        driver_options=(("system", str(emulated_freesn)),))))
    # reached within a few ticks, or ran long enough that its filtering was exercised
    assert result.ticks > 0 and (result.success or result.ticks > 10), result.reason
    assert len(seen) >= result.ticks and all(filtered for _, filtered in seen)
    assert {a.angle for a, _ in seen} == {float(np.float32(NOISE))}


def test_platform_emulate_takes_the_simulators_options(tmp_path):
    """``--driver-option noise=...`` reaches the simulator behind the modules (checked
    against its declaration like ``platform run``'s)."""
    args = ["emulate", "--robot", "freesn", str(CONFIGS / "S6N3-2.3.json"), "--system-out",
            str(tmp_path / "system.json"), "--duration", "0.3", "--speed", "3"]
    result = CliRunner().invoke(get_cli(), [*args, "--driver-option", "noise=0.0698"])
    assert result.exit_code == 0, result.output
    assert "9 emulated freesn modules" in result.output
    bad = CliRunner().invoke(get_cli(), [*args, "--driver-option", "loudness=3"])
    assert bad.exit_code == 1 and "unknown option 'loudness'" in bad.output
