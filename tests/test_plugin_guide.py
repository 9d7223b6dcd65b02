"""The plugin guide, followed literally: its code blocks are the example plugin, which
registers, validates, runs through ``platform run`` and passes the conformance suite.

Every fenced block of ``docs/writing-a-plugin.md`` whose info string names a file
(```` ```python file=msrr_example_hinge/plugin.py ````) is written into an empty folder,
blocks of one file joined by two blank lines. The package is imported from there and
registered with the plugin host under its entry-point name (in place of the installed
example, for the test), then used through click's ``CliRunner``.
"""

from __future__ import annotations

import importlib
import re
import sys
import tomllib
from collections.abc import Iterator
from pathlib import Path

import pytest
from click.testing import CliRunner

from msrr.core import Action, ActionType, Phase, plugins
from msrr.core.app.cli import get_cli
from msrr.core.app.testing import FakeDriver, check_robot

from msrr_test_support import ROOT

GUIDE = ROOT / "docs/writing-a-plugin.md"
EXAMPLE = ROOT / "examples/msrr-example-hinge"
BLOCK = re.compile(r"^```\w+ file=(\S+)\n(.*?)^```$", re.MULTILINE | re.DOTALL)


def guide_files(text: str) -> dict[str, str]:
    """File path -> content, from the guide's code blocks that name a file."""
    files: dict[str, list[str]] = {}
    for path, body in BLOCK.findall(text):
        files.setdefault(path, []).append(body)
    return {path: "\n\n".join(parts) for path, parts in files.items()}


@pytest.fixture(scope="module")
def package(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """The guide's package, written into an empty folder and registered in place of the
    installed example (same entry-point name), then unregistered again."""
    folder = tmp_path_factory.mktemp("guide") / "msrr-example-hinge"
    for path, content in guide_files(GUIDE.read_text()).items():
        (folder / path).parent.mkdir(parents=True, exist_ok=True)
        (folder / path).write_text(content)
    entry = tomllib.loads((folder / "pyproject.toml").read_text())["project"][
        "entry-points"]["msrr.plugins"]
    (name, target), = entry.items()
    pm = plugins.get_plugin_manager()
    installed = pm.unregister(name=name)
    saved = {m: sys.modules.pop(m) for m in list(sys.modules) if m.startswith("msrr_example_hinge")}
    sys.path.insert(0, str(folder))
    try:
        module = importlib.import_module(target)
        assert Path(module.__file__).is_relative_to(folder), "the guide's package, not another"
        plugins.register(module, name)
        yield folder
    finally:
        pm.unregister(name=name)
        sys.path.remove(str(folder))
        for m in [m for m in sys.modules if m.startswith("msrr_example_hinge")]:
            del sys.modules[m]
        sys.modules.update(saved)
        if installed is not None:
            pm.register(installed, name=name)


def test_the_guide_builds_exactly_the_example_plugin() -> None:
    files = guide_files(GUIDE.read_text())
    shipped = {str(p.relative_to(EXAMPLE)): p.read_text() for p in sorted(EXAMPLE.rglob("*"))
               if p.is_file() and "egg-info" not in str(p) and "__pycache__" not in str(p)
               and p.name != "README.md"}
    assert sorted(files) == sorted(shipped)
    for path, content in files.items():
        assert content == shipped[path], f"{path} differs from the guide's code blocks"


def test_the_guide_robot_runs_from_a_to_b_on_the_generic_runtime(package: Path,
                                                                   tmp_path: Path) -> None:
    configs = package / "msrr_example_hinge/configs"
    runner = CliRunner()
    listed = runner.invoke(get_cli(), ["robots", "--markdown"])
    row = next(line for line in listed.output.splitlines() if line.startswith("| hinge |"))
    assert "generic*" in row and "kinematic*" in row
    result = runner.invoke(get_cli(), [
        "run", "--robot", "hinge", "--from", str(configs / "chain3.json"),
        "--to", str(configs / "chain3-reversed.json"), "--out", str(tmp_path / "run"),
        "--no-log"])
    assert result.exit_code == 0, result.output
    assert "4 actions by generic" in result.output and "driver kinematic" in result.output
    summary = (tmp_path / "run/summary.json").read_text()
    assert '"success": true' in summary and '"docks": 2' in summary


def test_the_guide_robot_passes_the_conformance_suite(package: Path) -> None:
    report = check_robot("hinge")
    assert "run chain3.json -> chain3-reversed.json in the kinematic driver" in report.passed
    test_file = package / "tests/test_hinge.py"
    namespace: dict = {}
    exec(compile(test_file.read_text(), str(test_file), "exec"), namespace)  # noqa: S102
    namespace["test_hinge_conforms"]()


def test_the_example_scenario_runs(package: Path, tmp_path: Path) -> None:
    result = CliRunner().invoke(get_cli(), ["run", "--robot", "hinge", "--scenario", "reverse",
                                            "--out", str(tmp_path / "run"), "--no-log"])
    assert result.exit_code == 0, result.output
    assert "hinge reverse" in result.output


def test_every_other_hook_of_the_guide_works(package: Path, tmp_path: Path) -> None:
    extras = importlib.import_module("msrr_example_hinge.extras")
    cli = get_cli()
    try:
        with plugins.temporary(extras, "hinge-extras"):
            robot = plugins.resolve("hinge")
            assert robot.joint_modes["hinge"] is importlib.import_module(
                "msrr_example_hinge.joints").HingeJoint
            assert list(plugins.planners("hinge")) == ["undock-then-dock", "generic"]
            assert list(plugins.drivers("hinge")) == ["fast", "kinematic", "mujoco", "link"]
            start = plugins.load_configuration(package / "msrr_example_hinge/configs/chain3.json")
            goal = plugins.load_configuration(
                package / "msrr_example_hinge/configs/chain3-reversed.json")
            plan = plugins.planners.get("hinge").plan(start, goal)
            assert [a.note for a in plan.actions] == [
                "undock h1head-h2tail", "undock h2head-h3tail", "dock h3head-h2tail",
                "dock h2head-h1tail"]
            extras.LOG.clear()
            result = CliRunner().invoke(cli, ["run", "--robot", "hinge", "--scenario", "reverse",
                                              "--out", str(tmp_path / "run"), "--no-log"])
            assert result.exit_code == 0, result.output
            assert "by undock-then-dock" in result.output and "driver fast" in result.output
            assert extras.LOG[0] == "start reverse: 4 actions"
            assert extras.LOG[1] == "first tick in phase release"
            assert "dock h2tail-h3head" in extras.LOG and extras.LOG[-1] == "end: success"
            made = CliRunner().invoke(cli, ["hinge-chain", "4", str(tmp_path / "c4.json")])
            assert made.exit_code == 0 and plugins.load_configuration(
                tmp_path / "c4.json").signature().count("hinge") == 4
            with plugins.drivers.get("hinge")() as driver:
                driver.reset(goal)
                seen = extras.HeadToTail().recognize(driver.get_observation().sensors)
            assert {(e.source, e.target) for e in seen.edges()} == {("h3", "h2"), ("h2", "h1")}
            moving = Action(ActionType.MOVING, start, goals={"h1": [0.0, 1.0, 0.5]})
            world = FakeDriver(robot.spec)
            with world:
                world.reset(start)
                observation = world.get_observation()
            control = extras.Straight().control(moving, Phase.MOVE, observation)
            assert control.commands["h1"].joints == {"x": 0.0, "y": 1.0, "yaw": 0.5}
            assert not control.reached and control.errors["h1"] > 0
    finally:
        cli.commands.pop("hinge-chain", None)
