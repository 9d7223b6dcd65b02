"""Faults as a feature: the SPEC parser, each fault kind on the tiny robot (recovery or a
safe stop with one line and all three files, the fault on the timeline), the NaN guard
and the run's deadline."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from tiny_robot import PointDriver, chain, installed

from msrr.core import hookimpl, plugins
from msrr.core.app.cli import get_cli
from msrr.core.app.run import RunRequest, execute_run, prepare_run
from msrr.core.driver import ModuleCommand, Observation
from msrr.core.errors import ConfigurationError, ExecutionError
from msrr.core.events import FaultEvent, Run
from msrr.core.faults import FaultyDriver, GuardedDriver, parse_faults
from msrr.core.timeline import read_recording


def test_spec_parses_with_defaults_and_names_every_mistake() -> None:
    faults = parse_faults("dropout:module=3,at=5;loss:p=0.05;latency:ticks=2;"
                          "dock-fail:count=1;noise:sigma=0.01;nan:at=3")
    assert [f.kind for f in faults] == ["dropout", "loss", "latency", "dock-fail", "noise", "nan"]
    assert faults[0].params == {"module": "3", "at": 5.0, "for": math.inf}
    assert faults[3].params == {"count": 1.0, "ticks": 20.0}
    assert faults[5].params == {"at": 3.0, "module": "", "ticks": 1.0, "reading": "pose"}
    assert str(faults[1]) == "loss:p=0.05"
    for spec, words in [("warp:x=1", "unknown kind 'warp'"), ("loss", "loss needs p"),
                        ("loss:p=2", "p must be at most 1"), ("loss:p=nan", "must be finite"),
                        ("loss:q=1", "unknown key 'q'"), ("loss:p", "is not KEY=VALUE"),
                        ("latency:ticks=1.5", "whole number"), ("noise:sigma=-1", ">= 0"),
                        ("loss:p=0.1,p=0.2", "given twice"), ("dropout:at=1", "needs module"),
                        (" ; ", "no fault given"), ("nan:at=inf", "must be finite"),
                        ("nan:reading=imu", "one of pose, sensors")]:
        with pytest.raises(ConfigurationError, match=words) as error:
            parse_faults(spec)
        assert "--faults" in str(error.value) and "\n" not in str(error.value)


def _driver(spec: str, seed: int = 0) -> tuple[FaultyDriver, list]:
    events: list = []
    driver = FaultyDriver(PointDriver(), parse_faults(spec), seed=seed, on_fault=events.append)
    driver.connect()
    driver.reset(chain(("a", "b")))
    return driver, events


def test_dropout_loss_and_latency_change_what_reaches_the_modules() -> None:
    go = {m: ModuleCommand(wheels={"v": 1.0}) for m in "abc"}
    driver, events = _driver("dropout:module=b,at=0.2,for=0.2")
    for _ in range(6):
        driver.send_action(go)
        driver.step(0.1)
    x = driver.inner.x
    assert x["a"] == pytest.approx(0.6) and x["b"] == pytest.approx(1.4)  # b idle 0.2..0.4 s
    assert [e.recovered for e in events] == [False, True]

    driver, events = _driver("latency:ticks=2")
    for _ in range(3):
        driver.send_action(go)
        driver.step(0.1)
    assert driver.inner.x["a"] == pytest.approx(0.1)  # two ticks lost to the delay

    lost = []
    for seed in (0, 1):
        driver, events = _driver("loss:p=0.5", seed)
        for _ in range(200):
            driver.send_action(go)
            driver.step(0.01)
        lost.append(2.0 - driver.inner.x["a"])
    assert 0.6 < lost[0] < 1.4 and lost[0] != lost[1]  # about half lost, seeded


def test_noise_is_seeded_and_nan_readings_are_held_by_the_guard() -> None:
    driver, _ = _driver("noise:sigma=0.01")
    again, _ = _driver("noise:sigma=0.01")
    positions = [driver.get_observation().tracked["a"].position for _ in range(400)]
    assert np.std([p[0] for p in positions]) == pytest.approx(0.01, rel=0.15)
    assert np.allclose(again.get_observation().tracked["a"].position, positions[0])

    events: list = []
    faulty, _ = _driver("nan:at=0.1,module=b,ticks=2")
    guard = GuardedDriver(faulty, on_fault=events.append)
    good = guard.get_observation().tracked["b"].position.copy()
    guard.step(0.1)
    for _ in range(2):
        held = guard.get_observation()
        assert np.array_equal(held.tracked["b"].position, good)
        assert all(np.isfinite(p.position).all() for p in held.tracked.values())
    assert [e.kind for e in events] == ["nan"]

    fresh, _ = _driver("nan:at=0")
    with pytest.raises(ExecutionError, match="no earlier finite"):
        GuardedDriver(fresh).get_observation()


@dataclass(frozen=True)
class _Report:
    tilt: np.ndarray
    label: str


class _SensingDriver(PointDriver):
    """Sensor data with numbers in it: per module a report with an array."""

    def get_observation(self) -> Observation:
        seen = super().get_observation()
        return replace(seen, sensors={m: _Report(np.array([x, 1.0]), m) for m, x in self.x.items()})


def test_nan_in_sensor_data_is_held_per_module_by_the_guard() -> None:
    events: list = []
    faulty = FaultyDriver(_SensingDriver(), parse_faults("nan:reading=sensors,module=b,at=0.1"),
                          on_fault=events.append)
    guard = GuardedDriver(faulty, on_fault=events.append)
    guard.connect()
    guard.reset(chain(("a", "b")))
    first = guard.get_observation().sensors
    guard.step(0.1)
    held = guard.get_observation().sensors
    assert held["b"] is first["b"] and held["a"].label == "a"  # b's last finite report
    assert [e.text.split(" of")[0] for e in events] == ["NaN sensors reading",
                                                       "non-finite sensors"]
    assert guard.get_observation().sensors["b"].tilt[1] == 1.0  # one tick only: fresh again


def test_dock_fail_blocks_the_first_attempt_for_its_ticks() -> None:
    driver, events = _driver("dock-fail:count=1,ticks=3")
    driver.inner.links.clear()
    dock = {"b": ModuleCommand(dock=("T",)), "c": ModuleCommand(dock=("B",))}
    steps = 0
    while not driver.get_observation().sensors["b"]:
        driver.send_action(dock)
        driver.step(0.1)
        steps += 1
    assert steps == 4 and len(events) == 1  # the port armed first (b.T) blocked 3 ticks


def test_deadline_stops_stepping() -> None:
    guard = GuardedDriver(PointDriver(), deadline=0.25)
    guard.connect()
    guard.reset(chain(("a", "b")))
    guard.step(0.1)
    guard.step(0.1)
    with pytest.raises(ExecutionError, match="deadline of 0.25 s"):
        guard.step(0.1)


class _StoppedClock(PointDriver):
    def step(self, dt: float) -> None:
        pass  # time never advances


def test_deadline_holds_when_the_drivers_clock_stops() -> None:
    guard = GuardedDriver(_StoppedClock(), deadline=1.0)
    guard.connect()
    guard.reset(chain(("a", "b")))
    with pytest.raises(ExecutionError, match="deadline"):
        for _ in range(11):
            guard.step(0.1)


def _run(tmp_path: Path, *options: str) -> tuple[int, str, dict, Path]:
    out = tmp_path / "out"
    with installed(tmp_path):
        result = CliRunner().invoke(get_cli(), ["run", "--robot", "tiny", "--out", str(out),
                                                "--timeout", "1", *options])
    summary = json.loads((out / "summary.json").read_text())
    return result.exit_code, result.output, summary, out


def _timeline_faults(out: Path) -> list[str]:
    rows = read_recording(out / "run.rrd").rows.get("/events/faults", [])
    texts = [r.values["TextLog:text"] for r in rows]
    return [str(t[0] if isinstance(t, list | tuple) else t) for t in texts]


@pytest.mark.parametrize(("spec", "success", "kinds"), [
    ("loss:p=0.3", True, {"loss"}),
    ("latency:ticks=3", True, {"latency"}),
    ("dock-fail:count=1,ticks=4", True, {"dock-fail"}),
    ("nan:at=0.1", True, {"nan"}),
    ("dropout:module=c,at=0,for=0.5", True, {"dropout"}),
    ("dropout:module=c,at=0", False, {"dropout"}),       # c never docks: safe stop
    ("noise:sigma=0.05", False, {"noise"}),              # never within 1 mm: safe stop
    ("nan:at=0", False, {"nan"}),                        # nothing to hold: safe stop
])
def test_every_fault_ends_in_recovery_or_a_safe_stop_with_three_files(
        tmp_path: Path, spec: str, success: bool, kinds: set[str]) -> None:
    code, output, summary, out = _run(tmp_path, "--faults", spec)
    assert sorted(p.name for p in out.iterdir()) == ["plan.json", "run.rrd", "summary.json"]
    assert summary["success"] is success and code == (0 if success else 1), output
    errors = [line for line in output.splitlines() if line.startswith("Error:")]
    assert len(errors) == (0 if success else 1)
    if not success:
        assert summary["reason"] and summary["reason"] in " ".join(output.split())
    assert {f["kind"] for f in summary["faults"]} == kinds
    logged = _timeline_faults(out)
    assert len(logged) == len(summary["faults"]) and all(
        text.startswith(tuple(kinds)) for text in logged)


def test_the_deadline_option_stops_a_run_and_inf_is_refused(tmp_path: Path) -> None:
    code, output, summary, _ = _run(tmp_path, "--faults", "dropout:module=c,at=0",
                                    "--deadline", "0.5")
    assert code == 1 and not summary["success"]
    assert "run deadline of 0.5 s" in summary["reason"]
    assert summary["faults"][-1]["kind"] == "deadline"
    with installed(tmp_path):
        for option in (["--timeout", "inf"], ["--deadline", "nan"], ["--rate", "1e6"],
                       ["--seed", "-1"], ["--faults", "warp"]):
            result = CliRunner().invoke(get_cli(), ["run", "--robot", "tiny", "--out",
                                                    str(tmp_path / "x"), *option])
            assert result.exit_code == 1 and len(result.output.strip().splitlines()) == 1, (
                option, result.output)
            assert not (tmp_path / "x").exists()



class _FaultListener:
    def __init__(self) -> None:
        self.seen: list[tuple[str, str]] = []

    @hookimpl
    def msrr_on_fault(self, run: Run, fault: FaultEvent) -> None:
        self.seen.append((run.robot, fault.kind))


def test_hook_msrr_on_fault(tmp_path: Path) -> None:
    with installed(tmp_path), plugins.temporary(_FaultListener()) as listener:
        prepared = prepare_run(RunRequest("tiny", out=tmp_path / "out", log=False,
                                          action_timeout=1.0,
                                          faults="dock-fail:count=1,ticks=2;nan:at=0.1"))
        result = execute_run(prepared)
    assert result.success
    # the injected NaN, the guard holding the last pose, the failed dock
    assert listener.seen == [("tiny", "nan"), ("tiny", "nan"), ("tiny", "dock-fail")]
    assert [f.kind for f in result.faults] == ["nan", "nan", "dock-fail"]
