"""Hook specifications of the ``msrr`` plugin system (pluggy project name ``msrr``).

A plugin is a module or object with functions decorated by ``@hookimpl``
(``from msrr.core import hookimpl``) whose names are the hooks below. Plugins load
from the entry-point group ``msrr.plugins``; the built-in robots register through
that same group.

Capability hooks receive the robot's name, so one plugin can serve a robot fully
while another adds a joint mode, planner or simulator to any robot. They hand the
plugin a typed registrar (:class:`Register`) instead of expecting a returned list:
call ``register(item)`` once per item; ``item.name`` must be unique for that robot,
and the first registered item is the default. What each capability registers is a
protocol of :mod:`msrr.core.capabilities`.

Every hook is typed with what it receives and returns; ``docs/writing-a-plugin.md``
shows each signature (a test keeps the two in step). The host calls every hook through
pluggy; an implementation that raises, or registers or answers with the wrong type, is
named in one line (plugin, entry point, hook, exception) and the robot it was asked
about refuses every command: nothing falls back to a weaker default.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Protocol, TypeVar

import pluggy

# Only type checkers need these: every plugin imports this module when it loads, and
# plugins load on every command's --help, which must not pay for numpy, networkx,
# pydantic or scipy (benchmarks/cli_startup.py; tests/core/test_cli_startup.py).
if TYPE_CHECKING:
    from pathlib import Path

    import click

    from .capabilities import Controller, DriverFactory, Planner, Recognizer
    from .events import ActionStatus, FaultEvent, Run, RunResult, Tick, TopologyEvent
    from .kinematics.node import KinematicNode
    from .plan import Action
    from .robot import DockingRules, RobotSpec
    from .scenario import Scenario

__all__ = ["Register", "hookimpl", "hookspec"]

hookspec = pluggy.HookspecMarker("msrr")
hookimpl = pluggy.HookimplMarker("msrr")

T_contra = TypeVar("T_contra", contravariant=True)


class Register(Protocol[T_contra]):
    """The registrar a capability hook receives: ``register(item)``, once per item.

    ``Register[Planner]`` accepts planners only; the host checks each item against
    the capability's protocol and refuses, naming the plugin and the hook, an item that
    does not fit. ``register.registered`` lists the items registered so far in order (the
    robot's own plugin's first, ``trylast`` fallbacks' last): a hook wrapper reads it
    after its ``yield`` (the link driver takes the robot's default driver from it).
    """

    def __call__(self, item: T_contra, /) -> None: ...

    @property
    def registered(self) -> Sequence[object]: ...


# -------------------------------------------------------------------------------------
# Robot description
# -------------------------------------------------------------------------------------


@hookspec
def msrr_robot() -> RobotSpec | None:
    """Describe the robot this plugin provides.

    Called whenever the host lists robots (``platform robots``, resolving a robot
    for a command, validating a file).

    One plugin describes at most one robot. A package with several robots declares
    one entry point per robot (as this repository does for ``freesn``, ``mmrp``,
    ``freebot`` and ``snailbot``), so each can be listed, loaded and left out alone.

    :return: a :class:`~msrr.core.robot.RobotSpec`, or ``None`` when the plugin
        provides no robot (a planner-only or listener plugin).
    """


@hookspec(firstresult=True)
def msrr_docking_rules(robot: str) -> DockingRules | None:
    """Return the docking rules of ``robot``: legal port pairs, topologies, actions.

    Called once when the host resolves ``robot`` (:func:`msrr.core.plugins.capabilities`),
    e.g. before a configuration of it is validated. The first plugin that answers
    wins; when no plugin answers, the permissive :class:`~msrr.core.robot.DockingRules`
    apply (an implementation that raises is an error, never an empty answer).

    :param robot: the robot's name.
    :return: a :class:`~msrr.core.robot.DockingRules`, or ``None`` if this plugin
        does not define the rules of ``robot``.
    """


# -------------------------------------------------------------------------------------
# Capabilities (registrar hooks)
# -------------------------------------------------------------------------------------


@hookspec
def msrr_kinematic_nodes(robot: str, register: Register[type[KinematicNode]]) -> None:
    """Register the joint modes (kinematic node types) available for ``robot``.

    Called when the host resolves ``robot`` (kinematic trees, libraries, matching)
    and when ``platform robots`` lists capabilities.

    :param robot: the robot's name.
    :param register: call ``register(node_type)`` with each
        :class:`~msrr.core.kinematics.node.KinematicNode` subclass; ``name`` is the
        joint mode named in tree files.
    """


@hookspec
def msrr_controllers(robot: str, register: Register[Controller]) -> None:
    """Register controllers that turn actions and observations into module commands.

    Called when ``platform run`` prepares a run of ``robot``; the first registered
    controller drives it.

    :param robot: the robot's name.
    :param register: call ``register(controller)`` with a
        :class:`~msrr.core.control.Controller`.
    """


@hookspec
def msrr_recognizers(robot: str, register: Register[Recognizer]) -> None:
    """Register configuration recognizers: driver sensor data to a :class:`Configuration`.

    Called when ``platform run`` prepares a run of ``robot``; the executor then
    calls the first registered recognizer on every tick.

    :param robot: the robot's name.
    :param register: call ``register(recognizer)`` with a
        :class:`~msrr.core.capabilities.Recognizer`.
    """


@hookspec
def msrr_planners(robot: str, register: Register[Planner]) -> None:
    """Register planners (library-driven, MCS hybrid, ...) for ``robot``.

    Called by ``platform plan`` and ``platform run`` (``--planner NAME``, default
    the first registered) and by ``platform robots``.

    :param robot: the robot's name.
    :param register: call ``register(planner)`` with a
        :class:`~msrr.core.capabilities.Planner`.
    """


@hookspec
def msrr_drivers(robot: str, register: Register[DriverFactory]) -> None:
    """Register simulation and hardware drivers for ``robot``.

    Called by ``platform run`` to pick a driver (``--driver NAME``, default the
    first registered) and by ``platform robots``.

    :param robot: the robot's name.
    :param register: call ``register(factory)`` with a
        :class:`~msrr.core.driver.DriverFactory` (a :class:`~msrr.core.driver.Driver`
        subclass works), called as ``factory(gui=..., seed=...)``.
    """


@hookspec
def msrr_scenarios(robot: str, register: Register[Scenario]) -> None:
    """Register named runs for ``platform run --robot ROBOT --scenario NAME``.

    Called by ``platform run`` and ``platform robots``.

    :param robot: the robot's name.
    :param register: call ``register(scenario)`` with a
        :class:`~msrr.core.scenario.Scenario`; the one with ``default=True`` (else
        the first) runs when no scenario is named.
    """


@hookspec
def msrr_libraries(robot: str, register: Register[Path]) -> None:
    """Register the behavior library files of ``robot`` (FreeSN paper, section 6).

    A robot that registers libraries gets the core's ``library`` planner
    (:class:`~msrr.core.library.planner.LibraryPlanner`: match, shortest action path,
    remap; behaviors with ``platform run --behavior``), after its own planners. Called
    when the robot's planners are listed.

    :param robot: the robot's name.
    :param register: call ``register(path)`` with each library file (``platform library
        build`` output, one or more sub-libraries); a check file beside it
        (``<name>.check.json``, ``platform library check``) sets the edges' feasibility.
    """


@hookspec(historic=True)
def msrr_register_commands(cli: click.Group) -> None:
    """Add subcommands to the ``platform`` command line.

    Historic: called once when the CLI is built, and again for every plugin
    registered later, so a late plugin still gets its commands.

    :param cli: the top-level click group; use ``@cli.command()``.
    """


# -------------------------------------------------------------------------------------
# Run events (listeners such as the rerun timeline); payloads are read-only
# -------------------------------------------------------------------------------------


@hookspec
def msrr_on_run_start(run: Run) -> None:
    """A run starts: the plan is made and the driver is connected and reset (a run
    stopped before its driver was ready still fires it, just before ``msrr_on_run_end``,
    so listeners write complete files).

    :param run: the :class:`~msrr.core.events.Run` (robot, scenario, plan, output
        folder, recording path).
    """


@hookspec
def msrr_on_tick(run: Run, tick: Tick) -> None:
    """One control tick has been executed.

    :param run: the run.
    :param tick: the :class:`~msrr.core.events.Tick` (index, simulated time,
        observation with module poses, recognized configuration, commands, errors).
    """


@hookspec
def msrr_on_action(run: Run, action: Action, status: ActionStatus) -> None:
    """An action changes status.

    :param run: the run.
    :param action: the :class:`~msrr.core.plan.Action` (one of ``run.plan.actions``).
    :param status: ``STARTED``, ``SUCCEEDED``, ``RETRYING``, ``REDOCKING`` (a
        connection broke unplanned and is being docked again) or ``FAILED``.
    """


@hookspec
def msrr_on_topology_change(run: Run, change: TopologyEvent) -> None:
    """A connection was made or broken, as recognized from the driver's data.

    :param run: the run.
    :param change: the :class:`~msrr.core.events.TopologyEvent` (``"dock"`` or
        ``"undock"``, the connection with its ports, tick, simulated time).
    """


@hookspec
def msrr_on_fault(run: Run, fault: FaultEvent) -> None:
    """A fault happened: injected by ``platform run --faults`` or caught by the guard
    around every driver (a NaN reading held, the run's deadline reached).

    :param run: the run.
    :param fault: the :class:`~msrr.core.events.FaultEvent` (kind, one line, simulated
        time, whether the run carries on).
    """


@hookspec
def msrr_on_run_end(run: Run, result: RunResult) -> None:
    """A run ended, successfully, by failure or interrupted; always the last event.

    :param run: the run.
    :param result: the :class:`~msrr.core.events.RunResult` (success, counts, times,
        reason on failure).
    """


# -------------------------------------------------------------------------------------
# Timeline (the rerun recording of a run)
# -------------------------------------------------------------------------------------


@hookspec
def msrr_timeline_views(run: Run, register: Register[Any]) -> None:
    """Add views to the viewer layout (blueprint) of a run's rerun recording.

    Called once per recorded run, when the timeline sends its blueprint (at the first
    tick). The views join the tabs under the plots; they may show the timeline's own
    entities (``commands/<id>/<joint>``, ``world/...``, see ``docs/running.md``).

    :param run: the :class:`~msrr.core.events.Run` being recorded (robot, spec, plan).
    :param register: call ``register(view)`` with each ``rerun.blueprint`` view or
        container (``rrb.TimeSeriesView(...)``, ``rrb.Spatial2DView(...)``...).
    """
