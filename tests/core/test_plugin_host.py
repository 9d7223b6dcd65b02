"""The plugin surface itself: loading, isolation of broken plugins, every hookspec.

Every hook is exercised through the tiny robot of ``tiny_robot.py`` (an inline
plugin registered for the test), never through a built-in robot.
"""

from __future__ import annotations

import re
from pathlib import Path
from types import SimpleNamespace

import click
import numpy as np
import pytest
from click.testing import CliRunner
from tiny_robot import (
    NAME,
    SPEC,
    GoalController,
    Hinge,
    LinePlanner,
    LinkRecognizer,
    PointDriver,
    TinyRules,
    chain,
    installed,
    make_run,
    swap_plan,
)

from msrr.core import (
    DockingRuleError,
    DockingRules,
    PluginError,
    RobotSpec,
    UnknownNameError,
    UnknownRobotError,
    check_configuration,
    hookimpl,
    hookspecs,
    plugins,
)
from msrr.core.driver import Companions
from msrr.core.events import ActionStatus, Run, RunResult, Tick, TopologyEvent
from msrr.core.executor import Executor
from msrr.core.plan import Action
from msrr.core.random_configurations import random_configuration

HOOKS = sorted(name for name in dir(hookspecs) if name.startswith("msrr_"))
TESTS = Path(__file__).resolve().parents[1]


@pytest.fixture
def tiny(tmp_path: Path):
    with installed(tmp_path) as plugin:
        yield plugin


class Listener:
    """Records every run event with its payload."""

    def __init__(self) -> None:
        self.events: list[tuple] = []

    @hookimpl
    def msrr_on_run_start(self, run: Run) -> None:
        self.events.append(("start", run))

    @hookimpl
    def msrr_on_tick(self, run: Run, tick: Tick) -> None:
        self.events.append(("tick", tick))

    @hookimpl
    def msrr_on_action(self, run: Run, action: Action, status: ActionStatus) -> None:
        self.events.append(("action", action, status))

    @hookimpl
    def msrr_on_topology_change(self, run: Run, change: TopologyEvent) -> None:
        self.events.append(("topology", change))

    @hookimpl
    def msrr_on_run_end(self, run: Run, result: RunResult) -> None:
        self.events.append(("end", result))


@pytest.fixture(scope="module")
def run_events() -> tuple[Run, list[tuple]]:
    """The events of the tiny robot's swap plan (a-b undocked, c moved, b-c docked)."""
    run = make_run(swap_plan())
    with PointDriver() as driver, plugins.temporary(Listener()) as listener:
        driver.reset(run.plan.start)
        plugins.emit.run_start(run)
        result = Executor(run, driver, LinkRecognizer(), GoalController(), sink=plugins.emit).execute()
        plugins.emit.run_end(run, result)
    assert result.success
    return run, listener.events


def _of(events: list[tuple], kind: str) -> list[tuple]:
    return [e[1:] for e in events if e[0] == kind]


def test_plugin_hooks_have_tests() -> None:
    """Every hookspec has a test named ``test_hook_<hook>`` somewhere in the suite."""
    source = "\n".join(p.read_text() for p in TESTS.rglob("test_*.py"))
    missing = [h for h in HOOKS if not re.search(rf"def test_hook_{h}\b", source)]
    assert not missing, f"hooks without a test: {missing}"


def test_every_hookspec_says_what_it_receives_and_when_it_is_called() -> None:
    for name in HOOKS:
        doc = getattr(hookspecs, name).__doc__ or ""
        params = re.findall(r":param (\w+):", doc)
        assert doc.strip(), name
        assert "alled" in doc or name.startswith("msrr_on_"), f"{name}: say when it is called"
        expected = list(getattr(hookspecs, name).__code__.co_varnames[
            :getattr(hookspecs, name).__code__.co_argcount])
        assert params == expected, f"{name}: documents {params}, takes {expected}"


def test_hook_msrr_robot(tiny) -> None:
    assert plugins.robot(NAME) is SPEC and NAME in plugins.robots()

    class Several:
        @hookimpl
        def msrr_robot(self):
            return [RobotSpec("one", "One", ()), RobotSpec("two", "Two", ())]

    with plugins.temporary(Several(), "several"):  # named; the robots of others still work
        assert NAME in plugins.robots() and "one" not in plugins.robots()
        assert [str(p) for p in plugins.problems()] == [
            "plugin 'several' (registered in code, test_plugin_host) failed in msrr_robot: "
            "returned list, expected one RobotSpec or None (one entry point per robot)"]
        with pytest.raises(PluginError, match=r"unknown robot 'one' .*plugin 'several'"):
            plugins.robot("one")  # the robot it may have meant: the failure is said
    assert plugins.problems() == []


def test_a_register_hook_that_raises_makes_its_robot_refuse(tiny, tmp_path: Path) -> None:
    class Good:
        @hookimpl
        def msrr_libraries(self, robot, register):
            register(tmp_path / "kept.json")

    class Broken:
        @hookimpl
        def msrr_libraries(self, robot, register):
            register(tmp_path / "dropped.json")
            raise RuntimeError("library index unreadable")

    line = ("plugin 'broken' (registered in code, test_plugin_host) failed in msrr_libraries "
            "for robot 'tiny': RuntimeError: library index unreadable")
    with plugins.temporary(Good(), "good"), plugins.temporary(Broken(), "broken"):
        for lookup in (plugins.libraries, plugins.resolve, plugins.planners, plugins.drivers):
            with pytest.raises(PluginError) as info:
                lookup(NAME)
            assert str(info.value) == line  # never the other plugins' items alone
        assert [str(p) for p in plugins.problems()] == [line]
    assert plugins.problems() == []
    assert plugins.libraries(NAME) == []  # the cache was cleared with the plugins


def test_hook_msrr_docking_rules(tiny) -> None:
    assert isinstance(plugins.docking_rules(NAME), TinyRules)

    class RobotOnly:
        @hookimpl
        def msrr_robot(self):
            return RobotSpec("bare", "Bare", SPEC.module_kinds)

    with plugins.temporary(RobotOnly()):
        assert type(plugins.docking_rules("bare")) is DockingRules  # permissive default

    class Raising:
        @hookimpl
        def msrr_docking_rules(self, robot):
            raise RuntimeError("rules table missing")

    class Wrong:
        @hookimpl
        def msrr_docking_rules(self, robot):
            return "strict"

    for plugin, reason in ((Raising(), "RuntimeError: rules table missing"),
                           (Wrong(), "returned str, expected DockingRules or None")):
        with plugins.temporary(plugin, "rules"):  # refused, never relaxed to the default
            with pytest.raises(PluginError, match=f"plugin 'rules' .* failed in "
                               f"msrr_docking_rules for robot 'tiny': {reason}"):
                plugins.resolve(NAME)
            with pytest.raises(PluginError, match="msrr_docking_rules"):
                plugins.docking_rules(NAME)


def test_hook_msrr_kinematic_nodes(tiny) -> None:
    assert plugins.kinematic_nodes(NAME) == {"tiny_hinge": Hinge}
    assert set(plugins.resolve(NAME).joint_modes) == {"fixed", "tiny_hinge"}

    class NotANode:
        @hookimpl
        def msrr_kinematic_nodes(self, robot, register):
            register(SimpleNamespace(name="wobble"))

    refused = ("plugin 'nodes' .* failed in msrr_kinematic_nodes for robot 'tiny': "
               "PluginError: joint mode 'wobble' is not a subclass of KinematicNode")
    with plugins.temporary(NotANode(), "nodes"), pytest.raises(PluginError, match=refused):
        plugins.kinematic_nodes(NAME)


def test_hook_msrr_controllers(tiny) -> None:
    assert isinstance(plugins.controllers.get(NAME), GoalController)


def test_hook_msrr_recognizers(tiny) -> None:
    recognizer = plugins.recognizers.get(NAME)
    assert recognizer.recognize({"a": {"T": ("b", "B")}, "b": {"B": ("a", "T")}}) == chain(
        ("a", "b"), modules="ab")


def test_hook_msrr_planners(tiny) -> None:
    class Second:
        @hookimpl
        def msrr_planners(self, robot, register):
            if robot == NAME:
                planner = LinePlanner()
                planner.name = "exact"
                register(planner)

    assert plugins.planners.get(NAME).name == "line"
    with plugins.temporary(Second()):
        # another plugin adds a planner; the robot's own plugin keeps the default
        assert list(plugins.planners(NAME)) == ["line", "exact", "generic"]  # core's last
        assert plugins.planners.get(NAME).name == "line"  # the first item is the default
        assert plugins.planners.get(NAME, "line").name == "line"
        with pytest.raises(UnknownNameError, match=r"unknown planner for robot 'tiny' 'astar' "
                                                   r"\(known: exact, generic, line\)"):
            plugins.planners.get(NAME, "astar")


def test_items_that_do_not_fit_the_capability_are_refused(tiny) -> None:
    class Shapeless:
        @hookimpl
        def msrr_planners(self, robot, register):
            register(SimpleNamespace(name="nap", description="no plan method"))

    refused = ("plugin 'shapeless' .* failed in msrr_planners for robot 'tiny': "
               "PluginError: planner 'nap' is not Planner")
    with plugins.temporary(Shapeless(), "shapeless"), pytest.raises(PluginError, match=refused):
        plugins.planners(NAME)


def test_hook_msrr_drivers(tiny) -> None:
    drivers = plugins.drivers(NAME)
    assert list(drivers) == ["points", "kinematic", "link"] and drivers["points"] is PointDriver
    with plugins.drivers.get(NAME)(gui=False, seed=0) as driver:
        assert driver.is_connected


class _OtherDriver:
    """Another plugin's driver for the tiny robot (only its name matters here)."""

    name = "other"
    description = "a driver another plugin adds"
    companions = Companions()
    layout = None

    def __call__(self, **options: object) -> PointDriver:
        return PointDriver(**options)


class _AddsADriver:
    @hookimpl
    def msrr_drivers(self, robot: str, register) -> None:
        if robot == NAME:
            register(_OtherDriver())


def test_another_plugins_driver_never_becomes_the_default(tiny) -> None:
    with plugins.temporary(_AddsADriver()):  # registered last: pluggy calls it first
        assert list(plugins.drivers(NAME)) == ["points", "other", "kinematic", "link"]
        assert plugins.drivers.get(NAME) is PointDriver


def test_hook_msrr_scenarios(tiny, tmp_path: Path) -> None:
    scenario = plugins.scenarios(NAME)["swap"]
    assert scenario.default and scenario.start == tmp_path / "start.json"
    assert plugins.load_configuration(scenario.goal) == chain(("b", "c"), name="bc")


class _Hello:
    def __init__(self, word: str):
        self.word = word

    @hookimpl
    def msrr_register_commands(self, cli: click.Group) -> None:
        @cli.command(f"say-{self.word}")
        def say() -> None:
            click.echo(f"{self.word} from a plugin")


def test_hook_msrr_register_commands() -> None:
    """Historic: plugins registered before and after the CLI is built both add commands."""
    pm, _ = plugins.create_plugin_manager()
    plugins.register(_Hello("early"), pm=pm)
    group = click.Group()
    plugins.register_commands(group, pm)
    assert "say-early" in group.commands and "say-late" not in group.commands
    plugins.register(_Hello("late"), pm=pm)
    result = CliRunner().invoke(group, ["say-late"])
    assert result.exit_code == 0 and result.output == "late from a plugin\n"


def test_hook_msrr_on_run_start(run_events) -> None:
    run, events = run_events
    assert events[0] == ("start", run)


def test_hook_msrr_on_tick(run_events) -> None:
    _, events = run_events
    ticks = [t for (t,) in _of(events, "tick")]
    assert ticks and all(isinstance(t, Tick) for t in ticks)
    assert [t.index for t in ticks] == list(range(len(ticks)))
    assert ticks[-1].configuration == chain(("b", "c"))


def test_hook_msrr_on_action(run_events) -> None:
    run, events = run_events
    statuses = [(run.plan.actions.index(a), s) for a, s in _of(events, "action")]
    assert statuses == [(i, s) for i in range(3)
                        for s in (ActionStatus.STARTED, ActionStatus.SUCCEEDED)]


def test_hook_msrr_on_topology_change(run_events) -> None:
    _, events = run_events
    changes = [c for (c,) in _of(events, "topology")]
    assert [(c.kind, str(c.change), c.expected) for c in changes] == [
        ("undock", "aT-bB", True), ("dock", "bT-cB", True)]


def test_hook_msrr_on_run_end(run_events) -> None:
    _, events = run_events
    assert events[-1][0] == "end" and isinstance(events[-1][1], RunResult)
    assert events[-1][1].success and events[-1][1].docks == 1


def test_unknown_robot_lists_the_known_ones(tiny) -> None:
    with pytest.raises(UnknownRobotError, match=r"unknown robot 'tank' \(known: .*tiny"):
        plugins.robot("tank")
    with pytest.raises(UnknownRobotError):
        plugins.planners("tank")


def test_duplicate_names_are_refused(tiny) -> None:
    class Twin:
        @hookimpl
        def msrr_planners(self, robot, register):
            if robot == NAME:
                register(LinePlanner())

    with plugins.temporary(Twin(), "twin"):  # the robot refuses, naming the intruder
        with pytest.raises(PluginError, match="plugin 'twin' .* registered a planner named "
                           "'line' that plugin 'tiny-robot' registers too"):
            plugins.planners(NAME)
        problem = plugins.problems()[0]
        assert problem.plugin == "twin" and "named 'line'" in problem.reason


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


class _Plugin:
    """A plugin object with the given attributes (hashable, as every plugin must be)."""

    def __init__(self, **hooks: object):
        vars(self).update(hooks)


def test_an_unhashable_plugin_is_refused_in_one_line() -> None:
    with pytest.raises(PluginError, match="a SimpleNamespace cannot be a plugin"):
        plugins.register(SimpleNamespace(msrr_robot=hookimpl(lambda: SPEC)), "ns")


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
    good = _Plugin(msrr_robot=hookimpl(lambda: SPEC))

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


def test_a_plugin_whose_hook_raises_is_named_by_its_entry_point(monkeypatch) -> None:
    good = _Plugin(msrr_robot=hookimpl(lambda: SPEC))

    def explode():
        raise ValueError("no robot today")

    bad = _Plugin(msrr_robot=hookimpl(explode))
    monkeypatch.setattr(plugins, "entry_points",
                        lambda group: [_EntryPoint("good", good), _EntryPoint("exploding", bad)])
    monkeypatch.delenv("MSRR_LOAD_PLUGINS", raising=False)
    pm, errors = plugins.create_plugin_manager()
    monkeypatch.setattr(plugins, "_pm", pm)
    assert errors == [] and list(plugins.robots()) == [NAME]  # the good one still works
    assert [str(p) for p in plugins.problems()] == [
        "plugin 'exploding' (msrr.plugins: exploding = fake:exploding) failed in msrr_robot: "
        "ValueError: no robot today"]


def test_msrr_load_plugins_restricts_loading(monkeypatch) -> None:
    points = [_EntryPoint("a", _Plugin()), _EntryPoint("b", _Plugin())]
    monkeypatch.setattr(plugins, "entry_points", lambda group: points)
    monkeypatch.setenv("MSRR_LOAD_PLUGINS", "b")
    pm, errors = plugins.create_plugin_manager()
    assert [name for name, _ in pm.list_name_plugin()] == ["msrr.host", "b"] and errors == []


def test_installed_plugins_load_without_errors() -> None:
    assert plugins.load_errors() == []


def test_configurations_validate_against_their_robot(robot_name: str) -> None:
    """Random legal configurations of every installed robot pass its own check, and fail
    against another robot and with a module kind the robot does not have."""
    robot = plugins.resolve(robot_name)
    other = plugins.resolve(next(n for n in plugins.robots() if n != robot_name))
    rng = np.random.default_rng(7)
    for size in (1, 4, 9):
        config = random_configuration(robot.spec, robot.rules, size, rng)
        check_configuration(config, robot)
        with pytest.raises(DockingRuleError, match=f"is {robot_name!r}, expected "
                                                   f"{other.name!r}") as info:
            check_configuration(config, other)
        assert info.value.field == "robot"
        alien = config.copy()
        alien.add_module("x1", "alien")
        with pytest.raises(DockingRuleError, match="unknown module kind 'alien'") as info:
            check_configuration(alien, robot)
        assert info.value.field == "module x1"


# -- resolved once ---------------------------------------------------------------------


CAPABILITY_HOOKS = ("msrr_docking_rules", "msrr_kinematic_nodes", "msrr_controllers",
                    "msrr_recognizers", "msrr_planners", "msrr_drivers", "msrr_scenarios",
                    "msrr_libraries")


def test_a_run_asks_each_capability_hook_once(tiny, tmp_path: Path) -> None:
    """One ``prepare_run`` and its run, with a recording: every capability hook is called
    once for the robot, ``msrr_robot`` once per plugin, and all through pluggy (a hook
    call monitor sees them)."""
    from collections import Counter

    from msrr.core.app.run import RunRequest, execute_run, prepare_run

    pm = plugins.get_plugin_manager()
    calls: Counter[tuple[str, object]] = Counter()
    undo = pm.add_hookcall_monitoring(
        lambda hook, impls, kwargs: calls.update([(hook, kwargs.get("robot"))]),
        lambda outcome, hook, impls, kwargs: None)
    try:
        prepared = prepare_run(RunRequest(robot=NAME, out=tmp_path / "run"))
        result = execute_run(prepared)
    finally:
        undo()
    assert result.success, result.reason
    describers = [i for i in pm.hook.msrr_robot.get_hookimpls() if not i.wrapper]
    assert calls[("msrr_robot", None)] == len(describers)
    assert {hook: calls[(hook, NAME)] for hook in CAPABILITY_HOOKS} == dict.fromkeys(
        CAPABILITY_HOOKS, 1)
    assert calls[("msrr_timeline_views", None)] == 1 and calls[("msrr_on_run_end", None)] == 1


def test_the_cache_is_cleared_when_a_plugin_comes_or_goes(tiny) -> None:
    first = plugins.capabilities(NAME)
    assert plugins.capabilities(NAME) is first  # resolved once

    class Adds:
        @hookimpl
        def msrr_planners(self, robot, register):
            planner = LinePlanner()
            planner.name = "added"
            register(planner)

    with plugins.temporary(Adds()):
        assert "added" in plugins.capabilities(NAME).planners
    assert "added" not in plugins.capabilities(NAME).planners


def test_hook_wrappers_see_capability_calls_and_what_was_registered(tiny) -> None:
    """A third-party hook wrapper wraps the host's calls (they go through pluggy) and
    reads ``register.registered`` after its ``yield``."""
    seen: list[list[str]] = []

    class Watcher:
        @hookimpl(wrapper=True)
        def msrr_planners(self, robot, register):
            answers = yield
            seen.append([p.name for p in register.registered])
            return answers

    with plugins.temporary(Watcher()):
        plugins.planners(NAME)
    assert seen == [["line", "generic"]]
