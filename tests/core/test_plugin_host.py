"""The plugin surface itself: loading, isolation of broken plugins, every hookspec."""

from __future__ import annotations

import re
from pathlib import Path
from types import SimpleNamespace

import click
import pytest

from msrr.core import (
    Configuration,
    DockingRules,
    ModuleKind,
    PluginError,
    RobotSpec,
    Scenario,
    UnknownNameError,
    UnknownRobotError,
    hookimpl,
    hookspecs,
    plugins,
)

HOOKS = sorted(name for name in dir(hookspecs) if name.startswith("msrr_"))
TESTS = Path(__file__).resolve().parents[1]

TOY = RobotSpec("toy", "Toy", (ModuleKind("cube", "C", "vertex"),))


class ToyPlugin:
    """An inline plugin that implements every capability hook for robot 'toy'."""

    def __init__(self) -> None:
        self.events: list[tuple] = []

    @hookimpl
    def msrr_robot(self):
        return TOY

    @hookimpl
    def msrr_docking_rules(self, robot):
        if robot == "toy":
            rules = DockingRules()
            rules.robot = "toy"
            return rules
        return None

    def _register(self, robot, register, *names):
        if robot == "toy":
            for name in names:
                register(SimpleNamespace(name=name, description=name))

    @hookimpl
    def msrr_kinematic_nodes(self, robot, register):
        self._register(robot, register, "hinge")

    @hookimpl
    def msrr_controllers(self, robot, register):
        self._register(robot, register, "pd")

    @hookimpl
    def msrr_recognizers(self, robot, register):
        self._register(robot, register, "camera")

    @hookimpl
    def msrr_planners(self, robot, register):
        self._register(robot, register, "greedy", "exact")

    @hookimpl
    def msrr_drivers(self, robot, register):
        self._register(robot, register, "sim")

    @hookimpl
    def msrr_scenarios(self, robot, register):
        if robot == "toy":
            register(Scenario("stack", "stack the cubes", Path("a.json"), Path("b.json"), True))

    @hookimpl
    def msrr_register_commands(self, cli):
        @cli.command("toy-hello")
        def hello() -> None:
            click.echo("hello from toy")

    @hookimpl
    def msrr_on_run_start(self, run):
        self.events.append(("start", run))

    @hookimpl
    def msrr_on_tick(self, run, tick):
        self.events.append(("tick", tick))

    @hookimpl
    def msrr_on_action(self, run, action, status):
        self.events.append(("action", action, status))

    @hookimpl
    def msrr_on_topology_change(self, run, change):
        self.events.append(("topology", change))

    @hookimpl
    def msrr_on_run_end(self, run, result):
        self.events.append(("end", result))


@pytest.fixture
def toy():
    plugin = ToyPlugin()
    with plugins.temporary(plugin, "toy-test-plugin"):
        yield plugin


def test_plugin_hooks_have_tests() -> None:
    """Every hookspec has a test named ``test_hook_<hook>`` somewhere in the suite."""
    source = "\n".join(p.read_text() for p in TESTS.rglob("test_*.py"))
    missing = [h for h in HOOKS if not re.search(rf"def test_hook_{h}\b", source)]
    assert not missing, f"hooks without a test: {missing}"


def test_hook_msrr_robot(toy) -> None:
    assert plugins.robot("toy") is TOY
    assert {"freesn", "mmrp", "freebot", "snailbot", "toy"} <= set(plugins.robots())


def test_hook_msrr_docking_rules(toy) -> None:
    assert plugins.docking_rules("toy").robot == "toy"
    assert type(plugins.docking_rules("mmrp")).__name__ == "MmrpRules"


def test_hook_msrr_kinematic_nodes(toy) -> None:
    assert list(plugins.kinematic_nodes("toy")) == ["hinge"]


def test_hook_msrr_controllers(toy) -> None:
    assert list(plugins.controllers("toy")) == ["pd"]


def test_hook_msrr_recognizers(toy) -> None:
    assert plugins.recognizers.get("toy").name == "camera"


def test_hook_msrr_planners(toy) -> None:
    assert plugins.planners.get("toy").name == "greedy"  # the first registered is the default
    assert plugins.planners.get("toy", "exact").name == "exact"
    with pytest.raises(UnknownNameError, match=r"unknown planner for robot 'toy' 'astar' \(known: exact, greedy\)"):
        plugins.planners.get("toy", "astar")


def test_hook_msrr_drivers(toy) -> None:
    assert list(plugins.drivers("toy")) == ["sim"]


def test_hook_msrr_scenarios(toy) -> None:
    assert plugins.scenarios("toy")["stack"].default


def test_hook_msrr_register_commands(toy) -> None:
    from click.testing import CliRunner

    from msrr.core.cli import cli

    group = click.Group(commands=dict(cli.commands))
    plugins.register_commands(group)
    result = CliRunner().invoke(group, ["toy-hello"])
    assert result.output == "hello from toy\n"


def test_hook_msrr_on_run_start(toy) -> None:
    plugins.emit.run_start("run-1")
    assert toy.events == [("start", "run-1")]


def test_hook_msrr_on_tick(toy) -> None:
    plugins.emit.tick("run-1", 7)
    assert toy.events == [("tick", 7)]


def test_hook_msrr_on_action(toy) -> None:
    plugins.emit.action("run-1", "dock", "started")
    assert toy.events == [("action", "dock", "started")]


def test_hook_msrr_on_topology_change(toy) -> None:
    plugins.emit.topology_change("run-1", "1T-2B")
    assert toy.events == [("topology", "1T-2B")]


def test_hook_msrr_on_run_end(toy) -> None:
    plugins.emit.run_end("run-1", "ok")
    assert toy.events == [("end", "ok")]


def test_unknown_robot_lists_the_known_ones() -> None:
    with pytest.raises(UnknownRobotError, match=r"unknown robot 'tank' \(known: .*freesn.*mmrp"):
        plugins.robot("tank")
    with pytest.raises(UnknownRobotError):
        plugins.planners("tank")


def test_duplicate_names_are_refused(toy) -> None:
    class Twin:
        @hookimpl
        def msrr_planners(self, robot, register):
            if robot == "toy":
                register(SimpleNamespace(name="greedy"))

    with plugins.temporary(Twin()), pytest.raises(PluginError, match="two planners named 'greedy'"):
        plugins.planners("toy")


def test_misspelled_hook_is_refused_and_not_left_registered() -> None:
    class Typo:
        @hookimpl
        def msrr_robots(self):
            return None

    plugin = Typo()
    with pytest.raises(PluginError, match="unknown hook.*msrr_robots"):
        plugins.register(plugin, "typo")
    assert not plugins.get_plugin_manager().is_registered(plugin)


def test_wrong_signature_is_refused() -> None:
    class Wrong:
        @hookimpl
        def msrr_planners(self, robot, register, extra):
            pass

    with pytest.raises(PluginError, match="msrr_planners"):
        plugins.register(Wrong(), "wrong")


class _EntryPoint:
    def __init__(self, name: str, target):
        self.name = name
        self.value = f"fake:{name}"
        self._target = target

    def load(self):
        if isinstance(self._target, Exception):
            raise self._target
        return self._target


def test_broken_plugins_are_reported_and_others_still_load(monkeypatch) -> None:
    good = SimpleNamespace(msrr_robot=hookimpl(lambda: TOY))

    class Misspelled:
        @hookimpl
        def msrr_robto(self):
            return None

    points = [_EntryPoint("good", good), _EntryPoint("broken", ImportError("no module named x")),
              _EntryPoint("typo", Misspelled())]
    monkeypatch.setattr(plugins, "entry_points", lambda group: points)
    monkeypatch.delenv("MSRR_LOAD_PLUGINS", raising=False)
    pm, errors = plugins.create_plugin_manager()
    assert pm.get_plugin("good") is good
    assert [(e.entry_point, e.reason) for e in errors] == [
        ("broken", "import of fake:broken failed: ImportError: no module named x"),
        ("typo", "implements unknown hook(s) msrr_robto"),
    ]


def test_msrr_load_plugins_restricts_loading(monkeypatch) -> None:
    points = [_EntryPoint("a", SimpleNamespace()), _EntryPoint("b", SimpleNamespace())]
    monkeypatch.setattr(plugins, "entry_points", lambda group: points)
    monkeypatch.setenv("MSRR_LOAD_PLUGINS", "b")
    pm, errors = plugins.create_plugin_manager()
    assert [name for name, _ in pm.list_name_plugin()] == ["b"] and errors == []


def test_builtin_robots_load_through_entry_points() -> None:
    names = {name for name, _ in plugins.get_plugin_manager().list_name_plugin()}
    assert {"freesn", "mmrp", "freebot", "snailbot"} <= names
    assert plugins.load_errors() == []


def test_configurations_validate_against_their_robot(robot_name: str) -> None:
    spec = plugins.robot(robot_name)
    assert spec.name == robot_name and spec.module_kinds
    assert isinstance(Configuration(robot_name).signature().label(spec), str)
