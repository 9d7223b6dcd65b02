"""Issue 30, items 4 and 6: every driver declares its options (types, bounds, units);
unknown and ill-typed options, faults naming unknown modules and contradictory flags are
refused in one line before anything is written, and refused input leaves no run folder."""

from __future__ import annotations

import math
import os
from dataclasses import fields
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner
from tiny_robot import PointDriver, installed

from msrr.core import hookimpl, plugins
from msrr.core.app.cli import get_cli
from msrr.core.driver import (
    Driver,
    DriverOption,
    check_driver_options,
    declared_options,
)
from msrr.core.errors import ConfigurationError, PluginError
from msrr.core.faults import check_fault_modules, parse_faults

# -- the declaration -------------------------------------------------------------------


NOISE = DriverOption("noise", float, "angle noise", "rad", 0.0, 0.5)


@pytest.mark.parametrize("given, expected", [
    ("0.1", 0.1), ("0", 0.0), (0.25, 0.25), (0, 0.0), ("5e-1", 0.5), (" 0.2 ", 0.2)])
def test_a_float_option_takes_numbers_within_its_bounds(given: object, expected: float) -> None:
    assert NOISE.parse(given) == expected


@pytest.mark.parametrize("given", ["abc", "", "nan", "inf", "-0.1", "0.51", True, "true",
                                   "1e999", float("nan")])
def test_a_float_option_refuses_other_values_in_one_line(given: object) -> None:
    with pytest.raises(ConfigurationError) as caught:
        NOISE.parse(given)
    assert str(caught.value).startswith("--driver-option: noise=")
    assert str(caught.value).endswith("must be a number [rad] in [0, 0.5]")


def test_int_bool_str_and_open_bounds() -> None:
    count = DriverOption("count", int, low=1, high=10)
    assert count.parse("3") == 3 and count.parse("4.0") == 4 and count.parse(7) == 7
    for bad in ("3.5", "0", "11", "x", True, "18446744073709551616"):
        with pytest.raises(ConfigurationError, match="count=.*must be a whole number in"):
            count.parse(bad)
    flag = DriverOption("fast", bool)
    assert flag.parse("true") is True and flag.parse("False") is False and flag.parse(True)
    with pytest.raises(ConfigurationError, match="must be true or false"):
        flag.parse("1")
    mode = DriverOption("mode", str, choices=("a", "b"))
    assert mode.parse("a") == "a"
    with pytest.raises(ConfigurationError, match="must be text one of a, b"):
        mode.parse("c")
    gain = DriverOption("gain", float, low=0.0, low_open=True)
    assert gain.bounds == "> 0"
    with pytest.raises(ConfigurationError):
        gain.parse("0")


@pytest.mark.parametrize("bad", [
    dict(name="no name"), dict(name="seed"), dict(type=list), dict(low=math.inf),
    dict(low=2.0, high=1.0), dict(low=True)])
def test_a_malformed_declaration_is_the_plugins_error(bad: dict[str, Any]) -> None:
    with pytest.raises(PluginError):
        DriverOption(**{"name": "x", "type": float, **bad})


def test_checking_options_against_a_declaration() -> None:
    class Declared:
        name = "sim"
        options = (NOISE, DriverOption("steps", int, low=1))

    assert check_driver_options(Declared, [("noise", "0.1"), ("steps", "3")]) == (
        ("noise", 0.1), ("steps", 3))
    for given, message in (
            ([("nope", "1")], "unknown option 'nope' of driver 'sim' (known: noise, steps; "
                              "see platform robots --options)"),
            ([("noise", "0.1"), ("noise", "0.2")], "noise given twice"),
            ([("seed", "3")], "seed is not a driver option; use --seed"),
            ([("gui", "true")], "gui is not a driver option; use --gui")):
        with pytest.raises(ConfigurationError) as caught:
            check_driver_options(Declared, given)
        assert str(caught.value) == f"--driver-option: {message}"


def test_a_factory_without_a_declaration_gets_what_was_given() -> None:
    class Undeclared:
        name = "link"

    assert declared_options(Undeclared) is None
    assert check_driver_options(Undeclared, [("system", "s.json"), ("handshake", "2.5"),
                                             ("n", "3"), ("on", "true")]) == (
        ("system", "s.json"), ("handshake", 2.5), ("n", 3), ("on", True))


def test_a_driver_subclass_takes_no_options_unless_it_declares_them() -> None:
    assert PointDriver.options == () == Driver.options
    with pytest.raises(ConfigurationError, match="unknown option 'reach' of driver 'points' "
                                                 r"\(known: none"):
        check_driver_options(PointDriver, [("reach", "2")])


def test_every_built_in_driver_declares_its_options() -> None:
    undeclared = []
    for robot in ("mmrp", "freesn", "freebot", "snailbot"):
        for name, factory in plugins.capabilities(robot).drivers.items():
            if declared_options(factory) is None:
                undeclared.append(f"{robot} {name}")
    assert undeclared == ["mmrp link", "freesn link", "freebot link", "snailbot link"]


def test_every_simulation_option_but_the_seed_is_declared() -> None:
    from msrr.core.freeform.world import FreeformOptions
    from msrr.plugins.freesn.sim.driver import FreeSNMujocoDriver
    from msrr.plugins.freesn.sim.options import SimOptions

    for options in (FreeformOptions, SimOptions):
        declared = {o.name: o for o in options.driver_options()}
        assert set(declared) == {f.name for f in fields(options)} - {"seed"}
        for f in fields(options):  # each default is within its own bounds
            if f.name != "seed":
                assert declared[f.name].parse(f.default) == f.default
                assert declared[f.name].default == f.default
    assert FreeSNMujocoDriver.options == SimOptions.driver_options()


def test_the_driver_options_table() -> None:
    result = CliRunner().invoke(get_cli(), ["robots", "--options"])
    assert result.exit_code == 0
    assert "physics_rate" in result.output and "a number [Hz] in [30, 2000]" in result.output
    assert "mmrp link: options not declared (passed on unchecked)" in result.output


# -- faults naming modules -----------------------------------------------------------------


def test_a_fault_naming_an_unknown_module_is_refused() -> None:
    check_fault_modules(parse_faults("dropout:module=a;nan:at=1;nan:module=b"), {"a", "b"})
    for spec in ("dropout:module=99", "loss:p=0.1;nan:module=99"):
        with pytest.raises(ConfigurationError, match=r"--faults: fault \d \(.*\): no module "
                                                     "'99' in the run's start configuration "
                                                     r"\(modules: a, b\)"):
            check_fault_modules(parse_faults(spec), {"a", "b"})


# -- refused before anything is written ------------------------------------------------------


def _run(tmp_path: Path, *args: str) -> tuple[int, list[str]]:
    folder = tmp_path / "scenario"
    folder.mkdir(exist_ok=True)
    with installed(folder):
        result = CliRunner().invoke(get_cli(), ["run", "--robot", "tiny", "--out",
                                                str(tmp_path / "run"), *args])
    assert result.exception is None or isinstance(result.exception, SystemExit), \
        result.exception
    return result.exit_code, result.output.strip().splitlines()


@pytest.mark.parametrize("args, says", [
    (["--driver-option", "nope=1"], "unknown option 'nope' of driver 'points'"),
    (["--driver-option", "noise=abc"], "unknown option 'noise'"),
    (["--driver", "kinematic", "--driver-option", "speed=abc"], "speed=abc: must be a number"),
    (["--driver", "kinematic", "--driver-option", "speed=-1"], "speed=-1: must be"),
    (["--driver", "kinematic", "--driver-option", "nope=1"], "unknown option 'nope'"),
    (["--driver-option", "seed=1"], "use --seed"),
    (["--driver-option", "x"], "'x' is not KEY=VALUE"),
    (["--faults", "dropout:module=99"], "no module '99'"),
    (["--faults", "nan:module=99"], "no module '99'"),
    (["--system", "missing.json"], "missing.json: no such file"),
    (["--system", ""], "--system: is empty"),
    (["--system", "SYSTEM"], "holds null, not a JSON object"),
    (["--system", "EMPTY"], "invalid JSON"),
    (["--system", "missing.json", "--driver", "points"], "--system: is the link driver's"),
    (["--driver", "kinematic", "--gui"], ""),
])
def test_refused_input_leaves_no_run_folder(tmp_path: Path, args: list[str], says: str,
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("DISPLAY", ":0")  # --gui: refused by the driver, not for the display
    (tmp_path / "null.json").write_text("null")
    (tmp_path / "empty.json").write_text("")
    args = [{"SYSTEM": str(tmp_path / "null.json"), "EMPTY": str(tmp_path / "empty.json")}
            .get(a, a) for a in args]
    code, lines = _run(tmp_path, *args)
    assert code in (1, 2) and len(lines) == 1 and lines[0].startswith("Error:"), lines
    assert says in lines[0]
    assert not (tmp_path / "run").exists()


def test_a_factory_that_refuses_its_options_is_one_line_before_the_folder(
        tmp_path: Path) -> None:
    class Picky:
        name = "picky"
        description = "takes no keyword it does not know"
        companions = PointDriver.companions
        layout = None

        def __call__(self, *, gui: bool = False, seed: int = 0) -> Driver:
            return PointDriver()

    class Plugin:
        @hookimpl
        def msrr_drivers(self, robot: str, register) -> None:
            if robot == "tiny":
                register(Picky())

    with plugins.temporary(Plugin(), "picky"):
        code, lines = _run(tmp_path, "--driver", "picky", "--driver-option", "reach=2")
    assert code == 1 and len(lines) == 1, lines
    assert lines[0].startswith("Error: --driver-option: driver 'picky' refused its options: "
                               "TypeError:")
    assert not (tmp_path / "run").exists()


def test_good_options_still_run(tmp_path: Path) -> None:
    code, lines = _run(tmp_path, "--driver", "kinematic", "--driver-option", "speed=2",
                       "--no-log", "--faults", "dropout:module=c,at=1000")
    assert code == 0, lines
    assert sorted(os.listdir(tmp_path / "run")) == ["plan.json", "summary.json"]


def test_sweep_prepares_its_runs_with_the_same_checks(tmp_path: Path) -> None:
    folder = tmp_path / "scenario"
    folder.mkdir()
    with installed(folder):
        result = CliRunner().invoke(get_cli(), [
            "sweep", "--robot", "tiny", "--runs", "1", "--workers", "1", "--out",
            str(tmp_path / "sweep"), "--driver-option", "nope=1"])
    assert result.exit_code == 1
    assert "unknown option 'nope' of driver 'points'" in result.output
    assert not (tmp_path / "sweep").exists()
