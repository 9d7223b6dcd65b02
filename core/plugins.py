"""The plugin host: one pluggy manager, the guard every hook call passes through, and a
typed, cached facade over the hooks.

Plugins load from the entry-point group ``msrr.plugins``: the robots, and the
platform's own capabilities, each a ``plugin.py`` of its own with ordinary hook
implementations (``docs/architecture.md`` lists them). The host holds no robot or
capability name.

Environment:
    ``MSRR_LOAD_PLUGINS``: comma-separated entry-point names; only these load
        (empty string: none).
    ``MSRR_TRACE_PLUGINS``: when set, every hook call is traced to stderr.

**Calls.** Every hook is called through pluggy (``pm.hook.<name>``, or a
``subset_hook_caller`` for a question put to one plugin alone), so tracing and hook
wrappers see each call. A host wrapper around every non-historic hook, called first
(:class:`_Guard`), is the one place a failure is caught: an implementation that raises
becomes a :class:`~msrr.core.errors.PluginError` naming its plugin, its entry point,
the hook, the robot and the exception.

**Failures are loud.** A capability hook that raises, or registers or answers with the
wrong type, makes every lookup of that robot raise that one-line error (the robot
refuses; nothing falls back to a weaker default); :func:`problems` lists it and
``platform plugins`` shows the plugin as failed.

**Resolved once.** Each hook's answer for a robot is cached per ``(hook, robot)``; the
cache is cleared whenever a plugin is registered or unregistered. A run resolves a
robot's :class:`~msrr.core.capabilities.Capabilities` once and hands them down: only the
application wing (:mod:`msrr.core.app`) and the built-in ``plugin.py`` modules import
this module (``tests/core/test_layers.py``).

**Order.** A capability's items come in pluggy's call order, the robot's own plugin's
first (another plugin adds, it never takes the default); the first item is the
default. An item of a ``trylast`` implementation (a fallback, such as the built-in
runtime's) yields to an item of the same name from anyone else; any other two items of
one name are an error.
"""

from __future__ import annotations

import inspect
import os
import sys
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from importlib import import_module
from importlib.metadata import entry_points
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING, Generic, TypeVar

import pluggy

from . import hookspecs
from .errors import (
    ConfigurationError,
    PluginError,
    UnknownRobotError,
    one_line,
)

# The command line loads the plugins on every --help, which must not pay for numpy,
# networkx, pydantic or scipy: the modules of robots, plans, files and capabilities
# are imported by the functions that use them (tests/core/test_cli_startup.py).
if TYPE_CHECKING:
    import click

    from .capabilities import Capabilities, Controller, DriverFactory, Planner, Recognizer
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
    "Host",
    "LoadError",
    "PluginFailure",
    "capabilities",
    "controllers",
    "create_plugin_manager",
    "describe",
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
    "planners",
    "plugin_rows",
    "problems",
    "recognizers",
    "register",
    "register_commands",
    "resolve",
    "robot",
    "robot_clashes",
    "robot_plugin",
    "robots",
    "scenarios",
    "temporary",
    "timeline_views",
]

ENTRY_POINT_GROUP = "msrr.plugins"

P = TypeVar("P")
T = TypeVar("T")


@dataclass(frozen=True)
class LoadError:
    """A plugin that was left out at load time, and why."""

    entry_point: str
    reason: str

    def __str__(self) -> str:
        return f"plugin {self.entry_point!r} not loaded: {self.reason}"


@dataclass(frozen=True)
class PluginFailure:
    """A loaded plugin whose hook raised, or registered or answered with the wrong type.

    Attributes:
        plugin: its registered name.
        entry_point: ``"msrr.plugins: <name> = <module>"``, or where it was registered
            from for plugins registered in code.
        hook: the hook whose call failed.
        robot: the robot the call was about (``None`` for ``msrr_robot`` and events).
        reason: what it did (raised what, registered what).
    """

    plugin: str
    entry_point: str
    hook: str
    robot: str | None
    reason: str

    def __str__(self) -> str:
        about = f" for robot {self.robot!r}" if self.robot else ""
        return (f"plugin {self.plugin!r} ({self.entry_point}) failed in {self.hook}{about}: "
                f"{self.reason}")


class _HookFailed(PluginError):
    """Raised by the guard: ``impl`` (``None`` if no implementation could be named) failed."""

    def __init__(self, hook: str, impl: pluggy.HookImpl | None, reason: str):
        self.hook, self.impl, self.reason = hook, impl, reason
        super().__init__(f"{hook}: {reason}")


# -- the manager ----------------------------------------------------------------------


class Host(pluggy.PluginManager):
    """The ``msrr`` plugin manager: pluggy's, plus what the host keeps per manager.

    Attributes:
        load_errors: plugins left out at load time.
        entry_points: plugin name -> the entry point it was loaded from.
        answers: ``(hook, robot)`` -> the cached answer or the failure it raised;
            cleared whenever a plugin is registered or unregistered.
    """

    def __init__(self) -> None:
        super().__init__("msrr")
        self.add_hookspecs(hookspecs)
        self.load_errors: list[LoadError] = []
        self.entry_points: dict[str, str] = {}
        self.answers: dict[tuple[str, str | None], object] = {}
        self._guard = _Guard(self)
        super().register(self._guard, name=_Guard.NAME)

    def register(self, plugin: object, name: str | None = None) -> str | None:
        self.answers.clear()
        return super().register(plugin, name)

    def unregister(self, plugin: object | None = None, name: str | None = None) -> object:
        self.answers.clear()
        return super().unregister(plugin, name)

    def where(self, impl: pluggy.HookImpl) -> str:
        """Where ``impl``'s plugin came from: its entry point, or its module."""
        module = getattr(impl.plugin, "__module__", None) or getattr(impl.plugin, "__name__", "?")
        return self.entry_points.get(impl.plugin_name) or f"registered in code, {module}"

    def failure(self, error: _HookFailed, robot: str | None) -> PluginError:
        """The one-line error of a guarded failure, recorded for :func:`problems`."""
        impl = error.impl
        if impl is None:
            return PluginError(f"{error.hook}{f' for robot {robot!r}' if robot else ''}: "
                               f"{error.reason}")
        found = PluginFailure(impl.plugin_name, self.where(impl), error.hook, robot,
                              one_line(error.reason, 200))
        return _Failed(found)

    def call(self, hook: str, robot: str | None = None, *, alone: object = None,
             **kwargs: object) -> object:
        """Call ``hook`` through pluggy (only plugin ``alone``'s implementation when given,
        wrappers kept); a failure raises the recorded one-line :class:`PluginError`."""
        caller = getattr(self.hook, hook)
        if alone is not None:
            others = [i.plugin for i in caller.get_hookimpls()
                      if i.plugin is not alone and not (i.wrapper or i.hookwrapper)]
            caller = self.subset_hook_caller(hook, remove_plugins=others)
        if robot is not None:
            kwargs["robot"] = robot
        try:
            return caller(**kwargs)
        except _HookFailed as exc:
            raise self.failure(exc, robot) from None

    def cached(self, hook: str, robot: str | None, answer: Callable[[], T]) -> T:
        """``answer()`` once per ``(hook, robot)`` until the next (un)registration; a
        failure is cached too, and raised again on every lookup."""
        key = (hook, robot)
        if key in self.answers:
            found = self.answers[key]
            if found is _PENDING:
                raise PluginError(f"{hook} for robot {robot!r} was asked for while it was "
                                  "being answered (a plugin's hook needs its own answer)")
            if isinstance(found, PluginError):
                raise found
            return found  # type: ignore[return-value]
        self.answers[key] = _PENDING
        try:
            value = answer()
        except PluginError as exc:
            self.answers[key] = exc
            raise
        except BaseException:
            del self.answers[key]
            raise
        self.answers[key] = value
        return value


class _Failed(PluginError):
    """The one-line error of a :class:`PluginFailure`."""

    def __init__(self, failure: PluginFailure):
        self.failure = failure
        super().__init__(str(failure))


_PENDING = object()


class _Guard:
    """A wrapper around every non-historic hook, called before any other implementation:
    the one place an implementation's exception is caught and attributed (the frames
    of its traceback name the implementation that raised)."""

    NAME = "msrr.host"

    def __init__(self, pm: pluggy.PluginManager):
        for spec_name in (n for n in dir(hookspecs) if n.startswith("msrr_")):
            if not getattr(getattr(hookspecs, spec_name), "msrr_spec", {}).get("historic"):
                setattr(self, spec_name, self._wrapper(pm, spec_name))

    @staticmethod
    def _wrapper(pm: pluggy.PluginManager, hook: str) -> Callable[[], object]:
        @hookspecs.hookimpl(wrapper=True, tryfirst=True, specname=hook)
        def guard():  # type: ignore[no-untyped-def]
            try:
                return (yield)
            except (_HookFailed, _Failed):
                raise  # already named (a plugin asking the host about another's failure)
            except Exception as exc:  # noqa: BLE001 - every failure is named, then raised
                impls = [i for i in getattr(pm.hook, hook).get_hookimpls()
                         if i.plugin_name != _Guard.NAME]
                impl = implementation_in(_traceback_frames(exc), impls)
                raise _HookFailed(hook, impl, f"{type(exc).__name__}: {exc}") from exc
        return guard


def _traceback_frames(exc: BaseException) -> list[FrameType]:
    frames, tb = [], exc.__traceback__
    while tb is not None:
        frames.append(tb.tb_frame)
        tb = tb.tb_next
    return frames


def _calling_frames() -> list[FrameType]:
    """The frames of the current stack, outermost first."""
    frames, frame = [], sys._getframe(1)
    while frame is not None:
        frames.append(frame)
        frame = frame.f_back
    return frames[::-1]


def implementation_in(frames: Iterable[FrameType], impls: Iterable[pluggy.HookImpl]
                      ) -> pluggy.HookImpl | None:
    """The innermost of ``frames`` (outermost first) that runs one of ``impls``: its code,
    and for a method its instance, are the implementation's. Innermost, because pluggy
    throws an implementation's exception through the hook wrappers around it."""
    by_code: dict[object, list[pluggy.HookImpl]] = {}
    for impl in impls:
        function = inspect.unwrap(getattr(impl.function, "__func__", impl.function))
        by_code.setdefault(getattr(function, "__code__", None), []).append(impl)
    for frame in reversed(list(frames)):
        for impl in by_code.get(frame.f_code, ()):
            owner = getattr(impl.function, "__self__", None)
            if owner is None or frame.f_locals.get("self") is owner:
                return impl
    return None


_pm: Host | None = None


def create_plugin_manager() -> tuple[Host, list[LoadError]]:
    """A new manager with every ``msrr.plugins`` entry point loaded, and the load errors."""
    pm = Host()
    pm.load_errors = _load_entry_points(pm)
    if os.environ.get("MSRR_TRACE_PLUGINS"):
        pm.trace.root.setwriter(lambda text: sys.stderr.write(text))
        pm.enable_tracing()
    return pm, list(pm.load_errors)


def get_plugin_manager() -> Host:
    """The process-wide plugin manager, loading entry points on first use."""
    global _pm
    if _pm is None:
        _pm, _ = create_plugin_manager()
    return _pm


def _load_entry_points(pm: Host) -> list[LoadError]:
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
            pm.entry_points[ep.name] = f"{ENTRY_POINT_GROUP}: {ep.name} = {ep.value}"
    return errors


def register(plugin: object, name: str | None = None, pm: Host | None = None) -> None:
    """Register ``plugin`` and check it against the hookspecs at once.

    Raises:
        PluginError: a hookimpl has a wrong signature or names no hook; the plugin is
            not left half-registered.
    """
    pm = pm or get_plugin_manager()
    try:
        hash(plugin)
    except TypeError:
        raise PluginError(f"a {type(plugin).__name__} cannot be a plugin (the host asks each "
                          "plugin alone, by identity): register a module or an object of "
                          "a class") from None
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
def temporary(plugin: P, name: str | None = None, pm: Host | None = None) -> Iterator[P]:
    """Register ``plugin`` for the duration of a ``with`` block (tests, notebooks)."""
    pm = pm or get_plugin_manager()
    register(plugin, name, pm)
    try:
        yield plugin
    finally:
        pm.unregister(plugin)


def load_errors() -> list[LoadError]:
    """Plugins that were left out at load time."""
    return list(get_plugin_manager().load_errors)


def problems() -> list[PluginFailure]:
    """The failures found so far (hooks that raised or answered with the wrong type), one
    per plugin and hook; ``platform plugins`` resolves every robot first to find them."""
    found: dict[tuple[str, str], PluginFailure] = {}
    for answer in get_plugin_manager().answers.values():
        failures = answer.failures if isinstance(answer, _Claims) else (
            [answer.failure] if isinstance(answer, _Failed) else [])
        for failure in failures:
            found.setdefault((failure.plugin, failure.hook), failure)
    return list(found.values())


# -- robots ---------------------------------------------------------------------------


@dataclass(frozen=True)
class _Claims:
    """Every plugin's answer to ``msrr_robot``: robot name -> (plugin, spec) claims, and
    the plugins whose ``msrr_robot`` failed."""

    claims: dict[str, list[tuple[str, RobotSpec]]]
    failures: list[PluginFailure]


def _claims() -> _Claims:
    """A robot belongs to the one plugin that describes it, so ``msrr_robot`` is put to
    each plugin alone (through pluggy, the guard around it); a plugin that fails is
    recorded and the others still describe theirs."""
    from .robot import RobotSpec

    pm = get_plugin_manager()

    def ask() -> _Claims:
        claims: dict[str, list[tuple[str, RobotSpec]]] = {}
        failures: list[PluginFailure] = []
        for impl in reversed(pm.hook.msrr_robot.get_hookimpls()):
            if impl.wrapper or impl.hookwrapper:
                continue
            try:
                answers = pm.call("msrr_robot", alone=impl.plugin)
            except _Failed as exc:
                failures.append(exc.failure)
                continue
            for spec in answers:  # type: ignore[attr-defined]
                if not isinstance(spec, RobotSpec):
                    failures.append(PluginFailure(
                        impl.plugin_name, pm.where(impl), "msrr_robot", None,
                        f"returned {type(spec).__name__}, expected one RobotSpec or None "
                        "(one entry point per robot)"))
                    continue
                claims.setdefault(spec.name, []).append((impl.plugin_name, spec))
        return _Claims(dict(sorted(claims.items())), failures)

    return pm.cached("msrr_robot", None, ask)


def robots() -> dict[str, RobotSpec]:
    """Every robot described by exactly one plugin, by name (sorted); see
    :func:`robot_clashes` and :func:`problems` for the others."""
    return {name: found[0][1] for name, found in _claims().claims.items() if len(found) == 1}


def robot_clashes() -> dict[str, list[str]]:
    """Robot name -> the plugins that all describe it (such robots are refused)."""
    return {name: sorted(plugin for plugin, _ in found)
            for name, found in _claims().claims.items() if len(found) > 1}


def _owner(name: str) -> str:
    """The plugin that describes robot ``name``.

    Raises:
        UnknownRobotError: no plugin describes it (listing the known ones, and naming
            the plugins whose ``msrr_robot`` failed).
        PluginError: two plugins describe it (naming both).
    """
    found = _claims()
    claims = found.claims.get(name, [])
    if len(claims) > 1:
        owners = ", ".join(repr(plugin) for plugin, _ in sorted(claims))
        raise PluginError(f"robot {name!r} is described by plugins {owners}; it is refused "
                          "until one of them is removed")
    if not claims:
        error = UnknownRobotError(name, robots())
        if found.failures:
            raise PluginError(f"{error}; {'; '.join(map(str, found.failures))}")
        raise error
    return claims[0][0]


def robot_plugin(name: str) -> object:
    """The plugin (module or object) that describes robot ``name`` (raises as
    :func:`_owner`)."""
    return get_plugin_manager().get_plugin(_owner(name))


def robot(name: str) -> RobotSpec:
    """The description of robot ``name`` (raises as :func:`_owner`)."""
    _owner(name)
    return _claims().claims[name][0][1]


def docking_rules(name: str) -> DockingRules:
    """Docking rules of robot ``name``: the first plugin's answer (``firstresult``), the
    permissive :class:`DockingRules` when no plugin defines any.

    Raises:
        PluginError: a plugin's ``msrr_docking_rules`` raised or answered with another
            type (naming it); never relaxed to the permissive rules.
    """
    from .robot import DockingRules

    pm = get_plugin_manager()
    robot(name)

    def ask() -> DockingRules:
        rules = pm.call("msrr_docking_rules", name)
        if rules is None:
            return DockingRules()
        if isinstance(rules, DockingRules):
            return rules
        impl = next(i for i in reversed(pm.hook.msrr_docking_rules.get_hookimpls())
                    if not (i.wrapper or i.hookwrapper)
                    and pm.call("msrr_docking_rules", name, alone=i.plugin) is not None)
        raise _Failed(PluginFailure(impl.plugin_name, pm.where(impl), "msrr_docking_rules",
                                    name, f"returned {type(rules).__name__}, expected "
                                    "DockingRules or None"))

    return pm.cached("msrr_docking_rules", name, ask)


def describe(name: str) -> Robot:
    """What the pure layers need of robot ``name``: spec, rules and joint modes.

    The built-in runtime's plugins ask this while the robot's other capabilities are
    being resolved; commands use :func:`resolve`, which refuses a robot any of whose
    hooks fails.
    """
    from .kinematics.node import FixedNode
    from .robot import Robot

    def ask() -> Robot:
        modes: dict[str, type] = {"fixed": FixedNode}
        modes.update(kinematic_nodes.items(name))
        return Robot(robot(name), docking_rules(name), modes)

    return get_plugin_manager().cached("describe", name, ask)


def capabilities(name: str) -> Capabilities:
    """Everything robot ``name`` has, every hook asked once (then cached).

    Raises:
        UnknownRobotError: no plugin describes it.
        PluginError: any hook of any plugin failed for it (naming plugin, entry point,
            hook and exception): the robot refuses.
    """
    from .capabilities import Capabilities

    def ask() -> Capabilities:
        return Capabilities(
            robot=describe(name), controllers=controllers.items(name),
            recognizers=recognizers.items(name), planners=planners.items(name),
            drivers=drivers.items(name), scenarios=scenarios.items(name),
            libraries=tuple(libraries(name)))

    return get_plugin_manager().cached("capabilities", name, ask)


def resolve(name: str) -> Robot:
    """Robot ``name``'s spec, rules and joint modes, once every one of its hooks answered
    (:func:`capabilities`): a robot with a failing plugin refuses every command."""
    return capabilities(name).robot


# -- files checked against their robot ------------------------------------------------


def load_configuration(path: str | os.PathLike[str]) -> Configuration:
    """Read a configuration file and validate it against the installed robot it names.

    The one "load and check" of the application wing; the pure layers call
    :func:`msrr.core.io.load_configuration` with a :class:`Robot`.

    Raises:
        ConfigurationError: missing file, bad JSON, a wrong field or a broken rule,
            naming the file and the field.
        UnknownRobotError: the file names a robot no installed plugin describes.
        PluginError: the robot's plugins fail or clash.
    """
    from . import io
    from .bodies import with_port_vectors

    config = io.load_configuration(path)
    robot = _robot_of(config.robot, path)
    try:
        io.check_configuration(config, robot)
    except ConfigurationError as exc:
        raise exc.at(str(path)) from None
    return with_port_vectors(config, robot.spec)


def _robot_of(name: str, path: str | os.PathLike[str]) -> Robot:
    """:func:`resolve`, with an unknown or refused robot named as the file's field."""
    try:
        return resolve(name)
    except UnknownRobotError as exc:
        raise UnknownRobotError(name, exc.choices, source=str(path), field="robot") from None
    except PluginError as exc:
        raise PluginError(f"{path}: robot: {exc}") from None


def load_library(path: str | os.PathLike[str]) -> Library:
    """Read a library file and validate it whole against the installed robot it names.

    Raises:
        LibraryError: naming the file and the field.
    """
    from .library import storage

    return storage.load_library(path, lambda name: _robot_of(name, path))


def load_plan(path: str | os.PathLike[str]) -> Plan:
    """Read a plan file and validate it against the installed robot it names.

    Raises:
        ConfigurationError: naming the file and the field.
    """
    from . import plan

    return plan.load_plan(path, lambda name: _robot_of(name, path))


# -- capabilities ---------------------------------------------------------------------


class _Registrar:
    """The ``register`` a registrar hook receives: checks each item as it comes, notes the
    implementation that registered it (the frame on the stack that runs it), and shows
    what is registered so far in order (:attr:`registered`, for hook wrappers).

    The order: the robot's own plugin's items, then other plugins', then ``trylast``
    fallbacks', then hook wrappers' (registered after every other), each in pluggy's
    call order.
    """

    def __init__(self, hook: str, impls: list[pluggy.HookImpl],
                 check: Callable[[object], str | None], owner: str | None = None):
        self.hook = hook
        self.impls = impls
        self.check = check
        self.owner = owner
        self.entries: list[tuple[pluggy.HookImpl | None, object]] = []

    def __call__(self, item: object, /) -> None:
        problem = self.check(item)
        if problem is not None:
            raise PluginError(problem)
        self.entries.append((implementation_in(_calling_frames(), self.impls), item))

    def ordered(self) -> list[tuple[pluggy.HookImpl | None, object]]:
        """The entries in capability order (see the class docstring)."""
        def rank(entry: tuple[pluggy.HookImpl | None, object]) -> int:
            impl = entry[0]
            if impl is not None and impl.plugin_name == self.owner:
                return 0
            if impl is not None and (impl.wrapper or impl.hookwrapper):
                return 3
            return 2 if impl is None or impl.trylast else 1
        return sorted(self.entries, key=rank)

    @property
    def registered(self) -> list[object]:
        """The items registered so far, in capability order."""
        return [item for _, item in self.ordered()]


def _registered(hook: str, check: Callable[[object], str | None], robot: str | None = None,
                **kwargs: object) -> _Registrar:
    """Call registrar hook ``hook`` through pluggy; the registrar holds what it registered."""
    pm = get_plugin_manager()
    registrar = _Registrar(hook, getattr(pm.hook, hook).get_hookimpls(), check,
                           None if robot is None else _owner(robot))
    pm.call(hook, robot, register=registrar, **kwargs)
    return registrar


class Capability(Generic[T]):
    """The items of one registrar hook for one robot: ``planners(ROBOT)`` is a
    ``dict[str, Planner]`` in order (the default first), ``planners.get(ROBOT)`` the
    default.

    Each item is checked against ``accepts`` (a protocol or class; for joint modes a base
    class the item must subclass) as it is registered. It is named ``"module:Class"``
    within ``msrr.core`` and imported at the first check, so loading the host imports no
    robot code.
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

    def _problem(self, item: object) -> str | None:
        name = getattr(item, "name", None)
        if not isinstance(name, str) or not name:
            return f"registered {self.what} {item!r} has no name"
        fits = (isinstance(item, type) and issubclass(item, self.accepts) if self.subclass
                else isinstance(item, self.accepts))
        if not fits:
            need = "a subclass of " if self.subclass else ""
            return f"{self.what} {name!r} is not {need}{self.accepts.__name__}"
        return None

    def items(self, robot_name: str) -> dict[str, T]:
        """Everything registered for ``robot_name``, by name, the robot's own plugin's
        items first (see the module docstring for the order and for names taken twice).

        Raises:
            UnknownRobotError: no plugin describes ``robot_name``.
            PluginError: a plugin's hook failed, registered an item that does not fit,
                or an item under a name another plugin registers too.
        """
        pm = get_plugin_manager()
        _owner(robot_name)

        def ask() -> dict[str, T]:
            entries = _registered(self.hook_name, self._problem, robot_name).ordered()
            found: dict[str, T] = {}
            by: dict[str, pluggy.HookImpl | None] = {}
            for impl, item in entries:
                name = item.name  # type: ignore[attr-defined]
                if name not in found:
                    found[name], by[name] = item, impl  # type: ignore[assignment]
                elif impl is None or not impl.trylast:
                    first = by[name]
                    raise _Failed(PluginFailure(
                        impl.plugin_name if impl else "?", pm.where(impl) if impl else "?",
                        self.hook_name, robot_name,
                        f"registered a {self.what} named {name!r} that plugin "
                        f"{first.plugin_name if first else '?'!r} registers too"))
            return found

        return pm.cached(self.hook_name, robot_name, ask)

    def __call__(self, robot_name: str) -> dict[str, T]:
        """The items, once every hook of the robot answered (:func:`capabilities`): a
        robot with a failing plugin refuses."""
        capabilities(robot_name)
        return self.items(robot_name)

    def get(self, robot_name: str, name: str | None = None) -> T:
        """One item by name, or the first registered (the default) when ``name`` is None.

        Raises:
            UnknownNameError: no such item (listing the known ones), or none at all.
        """
        from .capabilities import pick

        return pick(self(robot_name), self.what, robot_name, name)  # type: ignore[no-any-return]


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


def _is_path(item: object) -> str | None:
    return None if isinstance(item, str | os.PathLike) else (
        f"registered {type(item).__name__} {item!r}, expected a library file path")


def libraries(robot_name: str) -> list[Path]:
    """The behavior library files registered for ``robot_name`` (``msrr_libraries``).

    Raises:
        UnknownRobotError: no plugin describes ``robot_name``.
        PluginError: a plugin's hook failed or registered something else than a path.
    """
    _owner(robot_name)
    return get_plugin_manager().cached("msrr_libraries", robot_name, lambda: [
        Path(item) for item in _registered("msrr_libraries", _is_path, robot_name).registered])  # type: ignore[arg-type]


def register_commands(cli: click.Group, pm: Host | None = None) -> None:
    """Let plugins add subcommands to ``cli``, now and whenever a plugin registers later
    (``msrr_register_commands`` is historic)."""
    (pm or get_plugin_manager()).hook.msrr_register_commands.call_historic(kwargs={"cli": cli})


# -- events ---------------------------------------------------------------------------


class _Events:
    """Typed calls of the event hooks (an :class:`~msrr.core.events.EventSink`): every
    listener receives each event; one that raises fails the run, named."""

    def _call(self, hook: str, **kwargs: object) -> None:
        get_plugin_manager().call(hook, **kwargs)

    def run_start(self, run: Run) -> None:
        self._call("msrr_on_run_start", run=run)

    def tick(self, run: Run, tick: Tick) -> None:
        self._call("msrr_on_tick", run=run, tick=tick)

    def action(self, run: Run, action: Action, status: ActionStatus) -> None:
        self._call("msrr_on_action", run=run, action=action, status=status)

    def topology_change(self, run: Run, change: TopologyEvent) -> None:
        self._call("msrr_on_topology_change", run=run, change=change)

    def fault(self, run: Run, fault: FaultEvent) -> None:
        self._call("msrr_on_fault", run=run, fault=fault)

    def run_end(self, run: Run, result: RunResult) -> None:
        self._call("msrr_on_run_end", run=run, result=result)


emit = _Events()


def timeline_views(run: Run) -> list[object]:
    """The viewer views plugins add to ``run``'s recording (``msrr_timeline_views``), in
    pluggy's call order.

    Raises:
        PluginError: a plugin's hook failed (naming it).
    """
    return _registered("msrr_timeline_views", lambda item: None, run=run).registered


# -- introspection --------------------------------------------------------------------


def plugin_rows() -> list[tuple[str, str, list[str]]]:
    """``(plugin name, module, hooks it implements)`` for every loaded plugin (the host's
    own guard left out)."""
    pm = get_plugin_manager()
    rows = []
    for name, plugin in sorted(pm.list_name_plugin(), key=lambda item: str(item[0])):
        if name == _Guard.NAME:
            continue
        hooks = sorted(caller.name for caller in pm.get_hookcallers(plugin) or [])
        rows.append((str(name), getattr(plugin, "__name__", type(plugin).__name__), hooks))
    return rows

