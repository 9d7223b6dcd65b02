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
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from importlib import import_module
from importlib.metadata import entry_points
from pathlib import Path
from typing import TYPE_CHECKING, Generic, TypeVar

import pluggy

from . import hookspecs
from .errors import (
    ConfigurationError,
    PluginError,
    UnknownNameError,
    UnknownRobotError,
    one_line,
)

# The command line loads the plugins on every --help, which must not pay for numpy,
# networkx, pydantic or scipy: the modules of robots, plans, files and the generic
# runtime are imported by the functions that use them (tests/core/test_cli_startup.py).
if TYPE_CHECKING:
    import click

    from .capabilities import Controller, DriverFactory, Planner, Recognizer
    from .configuration import Configuration
    from .events import ActionStatus, FaultEvent, Run, RunResult, Tick, TopologyEvent
    from .kinematics.node import KinematicNode
    from .library.model import Library
    from .plan import Action, Plan
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
    "libraries",
    "load_configuration",
    "load_errors",
    "load_library",
    "load_plan",
    "problems",
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
    "timeline_views",
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


@dataclass(frozen=True)
class PluginProblem:
    """A loaded plugin that broke the hook contract at a call and was disabled.

    Attributes:
        plugin: its registered name.
        entry_point: ``"msrr.plugins: <name> = <module>"``, or where it was registered
            from for plugins registered in code.
        hook: the hook whose call failed.
        reason: what it did (raised what, returned what).
    """

    plugin: str
    entry_point: str
    hook: str
    reason: str

    def __str__(self) -> str:
        return f"plugin {self.plugin!r} ({self.entry_point}) disabled: {self.hook} {self.reason}"


_pm: pluggy.PluginManager | None = None
_load_errors: list[LoadError] = []
_entry_points: dict[str, str] = {}  # plugin name -> entry point it was loaded from
_disabled: dict[str, tuple[object, PluginProblem]] = {}  # plugin name -> (plugin, problem)


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
        else:
            _entry_points[ep.name] = f"{ENTRY_POINT_GROUP}: {ep.name} = {ep.value}"
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
    registered = pm.get_name(plugin)
    try:
        yield plugin
    finally:
        pm.unregister(plugin)
        if registered is not None and _is_disabled(registered, plugin):
            del _disabled[registered]


def load_errors() -> list[LoadError]:
    """Plugins that were left out at load time."""
    get_plugin_manager()
    return list(_load_errors)


# -- robots ---------------------------------------------------------------------------


def problems() -> list[PluginProblem]:
    """Plugins disabled because a hook call raised or answered with the wrong type."""
    pm = get_plugin_manager()
    return [problem for name, (plugin, problem) in _disabled.items()
            if pm.get_plugin(name) is plugin]


def _is_disabled(name: str, plugin: object) -> bool:
    entry = _disabled.get(name)
    return entry is not None and entry[0] is plugin


def _disable(impl: pluggy.HookImpl, hook: str, reason: str) -> None:
    module = getattr(impl.plugin, "__module__", None) or getattr(impl.plugin, "__name__", "?")
    where = _entry_points.get(impl.plugin_name) or f"registered in code, {module}"
    problem = PluginProblem(impl.plugin_name, where, hook, one_line(reason, 160))
    _disabled[impl.plugin_name] = (impl.plugin, problem)


def _call_each(hook_name: str, before: Callable[[], object] | None = None, **kwargs: object
               ) -> Iterator[tuple[pluggy.HookImpl, object]]:
    """Call every enabled implementation of ``hook_name`` in pluggy's order (the last
    registered first), yielding ``(impl, answer)``; one that raises is disabled and
    skipped, so a broken plugin never stops the others. ``before`` runs before each call."""
    pm = get_plugin_manager()
    for impl in reversed(getattr(pm.hook, hook_name).get_hookimpls()):
        if _is_disabled(impl.plugin_name, impl.plugin):
            continue
        if before is not None:
            before()
        try:
            answer = impl.function(*(kwargs[name] for name in impl.argnames))
        except Exception as exc:  # noqa: BLE001 - any failure of a plugin is reported, not raised
            _disable(impl, hook_name, f"raised {type(exc).__name__}: {exc}")
            continue
        yield impl, answer


def _registered(hook_name: str, **kwargs: object) -> list[object]:
    """What every enabled implementation of a ``register``-style hook registers, in
    pluggy's order; the items of a call that raises are dropped with its plugin."""
    found: list[object] = []
    pending: list[object] = []
    for _impl, _answer in _call_each(hook_name, pending.clear, register=pending.append,
                                     **kwargs):
        found.extend(pending)
    return found


def _robot_answers() -> tuple[dict[str, RobotSpec], dict[str, list[str]]]:
    """Robots described by exactly one plugin, and robot name -> plugins for the others."""
    from .robot import RobotSpec
    claims: dict[str, list[tuple[str, RobotSpec]]] = {}
    for impl, spec in _call_each("msrr_robot"):
        if spec is None:
            continue
        if not isinstance(spec, RobotSpec):
            _disable(impl, "msrr_robot", f"returned {type(spec).__name__}, expected one "
                     "RobotSpec or None (one entry point per robot)")
            continue
        claims.setdefault(spec.name, []).append((impl.plugin_name, spec))
    unique = {name: found[0][1] for name, found in claims.items() if len(found) == 1}
    clashes = {name: sorted(plugin for plugin, _ in found)
               for name, found in claims.items() if len(found) > 1}
    return dict(sorted(unique.items())), clashes


def robots() -> dict[str, RobotSpec]:
    """Every robot described by exactly one enabled plugin, by name (sorted).

    A plugin whose ``msrr_robot`` raises or answers with anything but one
    :class:`RobotSpec` or ``None`` is disabled (see :func:`problems`); a robot two
    plugins describe is left out (see :func:`robot_clashes`); the others stay usable.
    """
    return _robot_answers()[0]


def _robot_owner(name: str) -> str | None:
    """The plugin that describes robot ``name``."""
    from .robot import RobotSpec

    for impl, spec in _call_each("msrr_robot"):
        if isinstance(spec, RobotSpec) and spec.name == name:
            return impl.plugin_name
    return None


def robot_clashes() -> dict[str, list[str]]:
    """Robot name -> the plugins that all describe it (such robots are refused)."""
    return _robot_answers()[1]


def robot(name: str) -> RobotSpec:
    """The robot called ``name``.

    Raises:
        UnknownRobotError: no enabled plugin describes it (listing the known ones).
        PluginError: two plugins describe it (naming both).
    """
    known, clashes = _robot_answers()
    if name in clashes:
        raise PluginError(f"robot {name!r} is described by plugins {', '.join(map(repr, clashes[name]))}"
                          "; it is refused until one of them is removed")
    try:
        return known[name]
    except KeyError:
        raise UnknownRobotError(name, known) from None


def docking_rules(name: str) -> DockingRules:
    """Docking rules of robot ``name`` (permissive defaults if no plugin defines them)."""
    from .robot import DockingRules

    robot(name)
    for impl, rules in _call_each("msrr_docking_rules", robot=name):
        if rules is None:
            continue
        if not isinstance(rules, DockingRules):
            _disable(impl, "msrr_docking_rules", f"returned {type(rules).__name__}, "
                     "expected DockingRules or None")
            continue
        return rules  # firstresult: the first answer that is not None
    return DockingRules()


def resolve(name: str) -> Robot:
    """Everything the pure layers need of robot ``name``: spec, rules, joint modes."""
    from .kinematics.node import FixedNode
    from .robot import Robot
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
        PluginError: two plugins describe the robot the file names.
    """
    from . import io

    config = io.load_configuration(path)
    try:
        io.check_configuration(config, _robot_of(config.robot, path))
    except ConfigurationError as exc:
        raise exc.at(str(path)) from None
    return config


def _robot_of(name: str, path: str | os.PathLike[str]) -> Robot:
    """:func:`resolve`, with an unknown or refused robot named as the file's field."""
    try:
        return resolve(name)
    except UnknownRobotError as exc:
        raise UnknownRobotError(name, exc.choices, source=str(path), field="robot") from None
    except PluginError as exc:
        raise PluginError(f"{path}: robot: {exc}") from None


def load_library(path: str | os.PathLike[str]) -> Library:
    """Read a library file and validate it whole against the installed robot it names
    (:func:`msrr.core.library.storage.library_from_model`).

    Raises:
        LibraryError: naming the file and the field.
    """
    from .library import storage

    return storage.load_library(path, lambda name: _robot_of(name, path))


def load_plan(path: str | os.PathLike[str]) -> Plan:
    """Read a plan file and validate it against the installed robot it names
    (:func:`msrr.core.plan.check_plan`).

    Raises:
        ConfigurationError: naming the file and the field.
    """
    from . import plan

    return plan.load_plan(path, lambda name: _robot_of(name, path))


# -- capabilities ---------------------------------------------------------------------

T = TypeVar("T")


class Capability(Generic[T]):
    """The items of one capability hook for one robot: ``planners("mmrp")`` is a
    ``dict[str, Planner]`` in registration order, ``planners.get("mmrp")`` the default.

    Each registered item is checked against ``accepts`` (a protocol or class; for
    joint modes a base class the item must subclass) when it is registered. It is named
    ``"module:Class"`` within ``msrr.core`` and imported at the first check, so loading
    the plugin host imports no robot code.
    """

    def __init__(self, hook_name: str, what: str, accepts: str, subclass: bool = False):
        self.hook_name = hook_name
        self.what = what
        self._accepts = accepts
        self.subclass = subclass

    @property
    def accepts(self) -> type:
        """The protocol or class every registered item must fit."""
        module, name = self._accepts.split(":")
        return getattr(import_module(f".{module}", __package__), name)

    def _fits(self, item: object) -> bool:
        if self.subclass:
            return isinstance(item, type) and issubclass(item, self.accepts)
        return isinstance(item, self.accepts)

    def __call__(self, robot_name: str) -> dict[str, T]:
        """Everything registered for ``robot_name``, by name: the robot's own plugin's items
        first, in registration order, then other plugins' (they add, they never take the
        default); for planners, drivers, recognizers and controllers then the generic
        runtime's items (:mod:`msrr.core.generic`) under names not taken.

        A plugin that registers an item without a name, of the wrong type or under a
        name already taken, or whose hook raises, is disabled (:func:`problems`) and
        its items are left out; the other plugins' items are still returned.

        Raises:
            UnknownRobotError: no plugin describes ``robot_name``.
        """
        robot(robot_name)
        found: dict[str, T] = {}
        pending: list[T] = []

        def add(item: T, /) -> None:
            name = getattr(item, "name", None)
            if not isinstance(name, str) or not name:
                raise PluginError(f"{self.hook_name}: registered {self.what} {item!r} has no name")
            if not self._fits(item):
                need = "a subclass of " if self.subclass else ""
                raise PluginError(f"{self.hook_name}: {self.what} {name!r} is not "
                                  f"{need}{self.accepts.__name__}")
            if any(getattr(p, "name", None) == name for p in pending):
                raise PluginError(f"{self.hook_name}: two {self.what}s named {name!r} "
                                  f"for robot {robot_name!r}")
            pending.append(item)

        # a plugin whose call raises (a bad item included) is disabled, its items dropped;
        # of two plugins registering one name, the later registered (called first) is
        owners: dict[str, pluggy.HookImpl] = {}
        for impl, _answer in _call_each(self.hook_name, pending.clear, robot=robot_name,
                                        register=add):
            for item in pending:
                name = item.name  # type: ignore[attr-defined]
                if name in owners:
                    intruder = owners[name]
                    _disable(intruder, self.hook_name, f"registered a {self.what} named "
                             f"{name!r} that plugin {impl.plugin_name!r} also registers")
                    for taken in [n for n, o in owners.items() if o is intruder]:
                        del owners[taken], found[taken]
                found[name] = item
                owners[name] = impl
        # the robot's own plugin's items first: another plugin may add, never take the default
        own = _robot_owner(robot_name)
        found = {name: item for name, item in sorted(
            found.items(), key=lambda entry: owners[entry[0]].plugin_name != own)}
        from . import generic
        from .link import link_driver_factory

        if self.hook_name == "msrr_planners" and "library" not in found:
            paths = libraries(robot_name)   # the core's library planner, before the generic
            if paths:
                from .library.planner import LibraryPlanner

                found["library"] = LibraryPlanner(resolve(robot_name), paths)  # type: ignore[assignment]
        if self.hook_name in generic.HOOKS:  # the generic runtime, after the robot's own
            for item in generic.capabilities(self.hook_name, resolve(robot_name)):
                found.setdefault(item.name, item)  # type: ignore[attr-defined]
            if self.hook_name == "msrr_drivers":  # the network link to any robot's modules
                first = next(iter(found.values()))
                found.setdefault("link", link_driver_factory(  # type: ignore[arg-type]
                    resolve(robot_name).spec, first))  # type: ignore[arg-type]
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
    "msrr_kinematic_nodes", "joint mode", "kinematics.node:KinematicNode", subclass=True)
controllers: Capability[Controller] = Capability("msrr_controllers", "controller",
                                                 "capabilities:Controller")
recognizers: Capability[Recognizer] = Capability("msrr_recognizers", "recognizer",
                                                 "capabilities:Recognizer")
planners: Capability[Planner] = Capability("msrr_planners", "planner", "capabilities:Planner")
drivers: Capability[DriverFactory] = Capability("msrr_drivers", "driver",
                                                "capabilities:DriverFactory")
scenarios: Capability[Scenario] = Capability("msrr_scenarios", "scenario", "scenario:Scenario")


def libraries(robot_name: str) -> list[Path]:
    """The behavior library files registered for ``robot_name`` (``msrr_libraries``), in
    pluggy's call order; a plugin that raises is disabled and reported.

    Raises:
        UnknownRobotError: no plugin describes ``robot_name``.
    """
    robot(robot_name)
    return [Path(p) for p in _registered("msrr_libraries", robot=robot_name)]  # type: ignore[arg-type]


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

    def fault(self, run: Run, fault: FaultEvent) -> None:
        get_plugin_manager().hook.msrr_on_fault(run=run, fault=fault)

    def run_end(self, run: Run, result: RunResult) -> None:
        get_plugin_manager().hook.msrr_on_run_end(run=run, result=result)


emit = _Events()


def timeline_views(run: Run) -> list[object]:
    """The viewer views plugins add to ``run``'s recording (``msrr_timeline_views``), in
    pluggy's call order; a plugin that raises is disabled and reported, never fatal."""
    return _registered("msrr_timeline_views", run=run)


# -- introspection --------------------------------------------------------------------


def plugin_rows() -> list[tuple[str, str, list[str]]]:
    """``(plugin name, module, hooks it implements)`` for every loaded plugin."""
    pm = get_plugin_manager()
    rows = []
    for name, plugin in sorted(pm.list_name_plugin(), key=lambda item: str(item[0])):
        hooks = sorted(caller.name for caller in pm.get_hookcallers(plugin) or [])
        rows.append((str(name), getattr(plugin, "__name__", type(plugin).__name__), hooks))
    return rows
