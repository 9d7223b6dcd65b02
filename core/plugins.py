"""The plugin host: one pluggy manager and a typed facade over its hooks.

Plugins load from the entry-point group ``msrr.plugins`` (the built-in robots
too). A plugin that fails to import, or implements a hook that does not exist or
with a wrong signature, is left out and reported with its entry-point name and
the reason; the others still load.

Environment:
    ``MSRR_LOAD_PLUGINS``: comma-separated entry-point names; only these load
        (empty string: none).
    ``MSRR_TRACE_PLUGINS``: when set, every hook call is traced to stderr.

Core code calls the functions of this module (``robots()``, ``planners(robot)``,
``emit.run_start(run)``...), never ``pm.hook`` directly. This is the top of the
core's import graph: kinematics, matching, library and file code never import it;
they receive the :class:`~msrr.core.robot.Robot` that :func:`resolve` builds.

The capability lookups are typed facades (:class:`Capability`): ``planners`` is a
``Capability[Planner]``, so ``planners("mmrp")`` is a ``dict[str, Planner]`` and
``planners.get("mmrp")`` a :class:`~msrr.core.capabilities.Planner`.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from importlib.metadata import entry_points
from typing import Generic, TypeVar

import click
import pluggy

from . import generic, hookspecs, io
from .capabilities import Controller, DriverFactory, Planner, Recognizer
from .configuration import Configuration
from .errors import ConfigurationError, PluginError, UnknownNameError, UnknownRobotError
from .events import ActionStatus, Run, RunResult, Tick, TopologyEvent
from .kinematics.node import FixedNode, KinematicNode
from .plan import Action
from .robot import DockingRules, Robot, RobotSpec
from .scenario import Scenario

__all__ = [
    "ENTRY_POINT_GROUP",
    "Capability",
    "LoadError",
    "controllers",
    "create_plugin_manager",
    "docking_rules",
    "drivers",
    "emit",
    "get_plugin_manager",
    "kinematic_nodes",
    "load_configuration",
    "load_errors",
    "planners",
    "plugin_rows",
    "recognizers",
    "register",
    "register_commands",
    "resolve",
    "robot",
    "robots",
    "scenarios",
    "temporary",
]

ENTRY_POINT_GROUP = "msrr.plugins"

P = TypeVar("P")


@dataclass(frozen=True)
class LoadError:
    """A plugin that was left out, and why."""

    entry_point: str
    reason: str

    def __str__(self) -> str:
        return f"plugin {self.entry_point!r} not loaded: {self.reason}"


_pm: pluggy.PluginManager | None = None
_load_errors: list[LoadError] = []


def create_plugin_manager() -> tuple[pluggy.PluginManager, list[LoadError]]:
    """A new manager with every ``msrr.plugins`` entry point loaded, and the load errors."""
    pm = pluggy.PluginManager("msrr")
    pm.add_hookspecs(hookspecs)
    errors = _load_entry_points(pm)
    if os.environ.get("MSRR_TRACE_PLUGINS"):
        pm.trace.root.setwriter(lambda text: sys.stderr.write(text))
        pm.enable_tracing()
    return pm, errors


def get_plugin_manager() -> pluggy.PluginManager:
    """The process-wide plugin manager, loading entry points on first use."""
    global _pm, _load_errors
    if _pm is None:
        _pm, _load_errors = create_plugin_manager()
    return _pm


def _load_entry_points(pm: pluggy.PluginManager) -> list[LoadError]:
    errors: list[LoadError] = []
    wanted = os.environ.get("MSRR_LOAD_PLUGINS")
    allowed = None if wanted is None else {n.strip() for n in wanted.split(",") if n.strip()}
    for ep in sorted(entry_points(group=ENTRY_POINT_GROUP), key=lambda e: e.name):
        if allowed is not None and ep.name not in allowed:
            continue
        if pm.get_plugin(ep.name) is not None:
            continue
        try:
            plugin = ep.load()
        except Exception as exc:  # noqa: BLE001 - any import failure is reported, not raised
            errors.append(LoadError(ep.name, f"import of {ep.value} failed: "
                                    f"{type(exc).__name__}: {exc}"))
            continue
        try:
            register(plugin, ep.name, pm)
        except PluginError as exc:
            errors.append(LoadError(ep.name, str(exc)))
    return errors


def register(plugin: object, name: str | None = None,
             pm: pluggy.PluginManager | None = None) -> None:
    """Register ``plugin`` and check it against the hookspecs at once.

    Raises:
        PluginError: a hookimpl has a wrong signature or names no hook; the plugin is
            not left half-registered.
    """
    pm = pm or get_plugin_manager()
    try:
        pm.register(plugin, name=name)
    except (pluggy.PluginValidationError, ValueError) as exc:
        raise PluginError(str(exc).splitlines()[0]) from None
    unknown = [caller.name for caller in pm.get_hookcallers(plugin) or []
               if not caller.has_spec()]
    if unknown:
        pm.unregister(plugin)
        raise PluginError(f"implements unknown hook(s) {', '.join(sorted(unknown))}")


@contextmanager
def temporary(plugin: P, name: str | None = None,
              pm: pluggy.PluginManager | None = None) -> Iterator[P]:
    """Register ``plugin`` for the duration of a ``with`` block (tests, notebooks)."""
    pm = pm or get_plugin_manager()
    register(plugin, name, pm)
    try:
        yield plugin
    finally:
        pm.unregister(plugin)


def load_errors() -> list[LoadError]:
    """Plugins that were left out at load time."""
    get_plugin_manager()
    return list(_load_errors)


# -- robots ---------------------------------------------------------------------------


def robots() -> dict[str, RobotSpec]:
    """Every robot described by a loaded plugin, by name (sorted).

    Raises:
        PluginError: a plugin answered ``msrr_robot`` with something other than one
            :class:`RobotSpec` or ``None``, or two plugins describe the same robot.
    """
    found: dict[str, RobotSpec] = {}
    hook = get_plugin_manager().hook.msrr_robot
    for spec in hook():
        if not isinstance(spec, RobotSpec):
            culprit = next((impl.plugin_name for impl in hook.get_hookimpls()
                            if not isinstance(impl.function(), RobotSpec | None)), "?")
            raise PluginError(f"plugin {culprit!r}: msrr_robot returned {type(spec).__name__}, "
                              "expected one RobotSpec or None (one entry point per robot)")
        if spec.name in found:
            raise PluginError(f"two plugins describe robot {spec.name!r}")
        found[spec.name] = spec
    return dict(sorted(found.items()))


def robot(name: str) -> RobotSpec:
    """The robot called ``name``; raises :class:`UnknownRobotError` listing the known ones."""
    known = robots()
    try:
        return known[name]
    except KeyError:
        raise UnknownRobotError(name, known) from None


def docking_rules(name: str) -> DockingRules:
    """Docking rules of robot ``name`` (permissive defaults if no plugin defines them)."""
    robot(name)
    rules = get_plugin_manager().hook.msrr_docking_rules(robot=name)
    return rules if rules is not None else DockingRules()


def resolve(name: str) -> Robot:
    """Everything the pure layers need of robot ``name``: spec, rules, joint modes."""
    modes: dict[str, type] = {"fixed": FixedNode}
    modes.update(kinematic_nodes(name))
    return Robot(robot(name), docking_rules(name), modes)


def load_configuration(path: str | os.PathLike[str]) -> Configuration:
    """Read a configuration file and validate it against the installed robot it names.

    The one "load and check" of the top layer (CLI commands, ``platform run``); the
    pure layers call :func:`msrr.core.io.load_configuration` with a :class:`Robot`.

    Raises:
        ConfigurationError: missing file, bad JSON, a wrong field or a broken rule,
            naming the file and the field.
        UnknownRobotError: the file names a robot no installed plugin describes.
    """
    config = io.load_configuration(path)
    try:
        io.check_configuration(config, resolve(config.robot))
    except ConfigurationError as exc:
        raise exc.at(str(path)) from None
    return config


# -- capabilities ---------------------------------------------------------------------

T = TypeVar("T")


class Capability(Generic[T]):
    """The items of one capability hook for one robot: ``planners("mmrp")`` is a
    ``dict[str, Planner]`` in registration order, ``planners.get("mmrp")`` the default.

    Each registered item is checked against ``accepts`` (a protocol or class; for
    joint modes a base class the item must subclass) when it is registered.
    """

    def __init__(self, hook_name: str, what: str, accepts: type, subclass: bool = False):
        self.hook_name = hook_name
        self.what = what
        self.accepts = accepts
        self.subclass = subclass

    def _fits(self, item: object) -> bool:
        if self.subclass:
            return isinstance(item, type) and issubclass(item, self.accepts)
        return isinstance(item, self.accepts)

    def __call__(self, robot_name: str) -> dict[str, T]:
        """Everything registered for ``robot_name``, by name, in registration order; for
        planners, drivers, recognizers and controllers then the generic runtime's items
        (:mod:`msrr.core.generic`) under names the robot's own do not take.

        Raises:
            UnknownRobotError: no plugin describes ``robot_name``.
            PluginError: an item without a name, of the wrong type, or a duplicate name.
        """
        robot(robot_name)
        found: dict[str, T] = {}

        def add(item: T, /) -> None:
            name = getattr(item, "name", None)
            if not isinstance(name, str) or not name:
                raise PluginError(f"{self.hook_name}: registered {self.what} {item!r} has no name")
            if not self._fits(item):
                need = "a subclass of " if self.subclass else ""
                raise PluginError(f"{self.hook_name}: {self.what} {name!r} is not "
                                  f"{need}{self.accepts.__name__}")
            if name in found:
                raise PluginError(f"{self.hook_name}: two {self.what}s named {name!r} "
                                  f"for robot {robot_name!r}")
            found[name] = item

        getattr(get_plugin_manager().hook, self.hook_name)(robot=robot_name, register=add)
        if self.hook_name in generic.HOOKS:  # the generic runtime, after the robot's own
            for item in generic.capabilities(self.hook_name, resolve(robot_name)):
                found.setdefault(item.name, item)  # type: ignore[attr-defined]
        return found

    def get(self, robot_name: str, name: str | None = None) -> T:
        """One item by name, or the first registered (the default) when ``name`` is None.

        Raises:
            UnknownNameError: no such item (listing the known ones), or none at all.
        """
        items = self(robot_name)
        if name is None:
            if not items:
                raise UnknownNameError(f"{self.what} for robot {robot_name!r}", "(default)", ())
            return next(iter(items.values()))
        try:
            return items[name]
        except KeyError:
            raise UnknownNameError(f"{self.what} for robot {robot_name!r}", name, items) from None


kinematic_nodes: Capability[type[KinematicNode]] = Capability(
    "msrr_kinematic_nodes", "joint mode", KinematicNode, subclass=True)
controllers: Capability[Controller] = Capability("msrr_controllers", "controller", Controller)
recognizers: Capability[Recognizer] = Capability("msrr_recognizers", "recognizer", Recognizer)
planners: Capability[Planner] = Capability("msrr_planners", "planner", Planner)
drivers: Capability[DriverFactory] = Capability("msrr_drivers", "driver", DriverFactory)
scenarios: Capability[Scenario] = Capability("msrr_scenarios", "scenario", Scenario)


def register_commands(cli: click.Group, pm: pluggy.PluginManager | None = None) -> None:
    """Let plugins add subcommands to ``cli``, now and whenever a plugin registers later
    (``msrr_register_commands`` is historic)."""
    (pm or get_plugin_manager()).hook.msrr_register_commands.call_historic(kwargs={"cli": cli})


# -- events ---------------------------------------------------------------------------


class _Events:
    """Typed calls of the event hooks; every listener plugin receives each event."""

    def run_start(self, run: Run) -> None:
        get_plugin_manager().hook.msrr_on_run_start(run=run)

    def tick(self, run: Run, tick: Tick) -> None:
        get_plugin_manager().hook.msrr_on_tick(run=run, tick=tick)

    def action(self, run: Run, action: Action, status: ActionStatus) -> None:
        get_plugin_manager().hook.msrr_on_action(run=run, action=action, status=status)

    def topology_change(self, run: Run, change: TopologyEvent) -> None:
        get_plugin_manager().hook.msrr_on_topology_change(run=run, change=change)

    def run_end(self, run: Run, result: RunResult) -> None:
        get_plugin_manager().hook.msrr_on_run_end(run=run, result=result)


emit = _Events()


# -- introspection --------------------------------------------------------------------


def plugin_rows() -> list[tuple[str, str, list[str]]]:
    """``(plugin name, module, hooks it implements)`` for every loaded plugin."""
    pm = get_plugin_manager()
    rows = []
    for name, plugin in sorted(pm.list_name_plugin(), key=lambda item: str(item[0])):
        hooks = sorted(caller.name for caller in pm.get_hookcallers(plugin) or [])
        rows.append((str(name), getattr(plugin, "__name__", type(plugin).__name__), hooks))
    return rows
