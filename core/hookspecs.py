"""Hook specifications of the ``msrr`` plugin system (pluggy project name ``msrr``).

A plugin is a module or object with functions decorated by ``@hookimpl``
(``from msrr.core import hookimpl``) whose names are the hooks below. Plugins load
from the entry-point group ``msrr.plugins``; the built-in robots register through
that same group.

Capability hooks receive the robot's name, so one plugin can serve a robot fully
while another adds a joint mode, planner or simulator to any robot. Most of them
hand the plugin a ``register`` callable instead of expecting a returned list: call
``register(item)`` once per item; ``item.name`` must be unique for that robot.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import pluggy

if TYPE_CHECKING:
    import click

    from .robot import DockingRules, RobotSpec

__all__ = ["Register", "hookimpl", "hookspec"]

hookspec = pluggy.HookspecMarker("msrr")
hookimpl = pluggy.HookimplMarker("msrr")

Register = Callable[[Any], None]
"""The registrar a capability hook receives: ``register(item)``."""


# -------------------------------------------------------------------------------------
# Robot description
# -------------------------------------------------------------------------------------


@hookspec
def msrr_robot() -> RobotSpec | list[RobotSpec] | None:
    """Describe the robot(s) this plugin provides.

    Called whenever the host lists robots (``platform robots``, ``--robot`` choices,
    validating a file).

    :return: a :class:`~msrr.core.robot.RobotSpec`, a list of them, or ``None``
        when the plugin provides no robot (a planner-only plugin).
    """


@hookspec(firstresult=True)
def msrr_docking_rules(robot: str) -> DockingRules | None:
    """Return the docking rules of ``robot``: legal port pairs, topologies, actions.

    Called when a configuration of ``robot`` is validated or an action is checked.
    The first plugin that answers wins.

    :param robot: the robot's name.
    :return: a :class:`~msrr.core.robot.DockingRules`, or ``None`` if this plugin
        does not define the rules of ``robot``.
    """


# -------------------------------------------------------------------------------------
# Capabilities (registrar hooks)
# -------------------------------------------------------------------------------------


@hookspec
def msrr_kinematic_nodes(robot: str, register: Register) -> None:
    """Register the joint modes (kinematic node types) available for ``robot``.

    Called when kinematic trees are built or the robot's capabilities are listed.

    :param robot: the robot's name.
    :param register: call ``register(node_type)`` for each kinematic node type.
    """


@hookspec
def msrr_controllers(robot: str, register: Register) -> None:
    """Register controllers that turn kinematic-node targets into module commands.

    Called when the executor prepares a run of ``robot``.

    :param robot: the robot's name.
    :param register: call ``register(controller)``; ``controller.name`` is the
        controller id named by kinematic node types.
    """


@hookspec
def msrr_recognizers(robot: str, register: Register) -> None:
    """Register configuration recognizers: driver data to :class:`Configuration`.

    Called when a run starts and whenever the executor needs the current
    configuration. The first registered recognizer is the default.

    :param robot: the robot's name.
    :param register: call ``register(recognizer)``.
    """


@hookspec
def msrr_planners(robot: str, register: Register) -> None:
    """Register planners (library-driven, MCS hybrid, ...) for ``robot``.

    Called by ``platform plan`` and ``platform run``.

    :param robot: the robot's name.
    :param register: call ``register(planner)``.
    """


@hookspec
def msrr_drivers(robot: str, register: Register) -> None:
    """Register simulation and hardware drivers for ``robot``.

    Called by ``platform run`` to pick a driver (``--driver`` or the default).

    :param robot: the robot's name.
    :param register: call ``register(driver_factory)``.
    """


@hookspec
def msrr_scenarios(robot: str, register: Register) -> None:
    """Register named runs for ``platform run --robot ROBOT --scenario NAME``.

    :param robot: the robot's name.
    :param register: call ``register(scenario)`` with a
        :class:`~msrr.core.scenario.Scenario`.
    """


@hookspec
def msrr_register_commands(cli: click.Group) -> None:
    """Add subcommands to the ``platform`` command line.

    Called once when the CLI is built, before arguments are parsed.

    :param cli: the top-level click group; use ``@cli.command()``.
    """


# -------------------------------------------------------------------------------------
# Run events (listeners such as the rerun timeline)
# -------------------------------------------------------------------------------------


@hookspec
def msrr_on_run_start(run: Any) -> None:
    """A run starts: the plan is made and the driver is connected.

    :param run: the :class:`~msrr.core.events.Run` (robot, scenario, plan, output folder,
        recording path).
    """


@hookspec
def msrr_on_tick(run: Any, tick: Any) -> None:
    """One control tick has been executed.

    :param run: the run.
    :param tick: the :class:`~msrr.core.events.Tick` (index, simulated time, observation
        with module poses, recognized configuration, commands, errors).
    """


@hookspec
def msrr_on_action(run: Any, action: Any, status: str) -> None:
    """An action changes status.

    :param run: the run.
    :param action: the :class:`~msrr.core.plan.Action`.
    :param status: an :class:`~msrr.core.events.ActionStatus`: ``"started"``,
        ``"succeeded"``, ``"retrying"`` or ``"failed"``.
    """


@hookspec
def msrr_on_topology_change(run: Any, change: Any) -> None:
    """A connection was made or broken (dock, undock, connection, disconnection).

    :param run: the run.
    :param change: the :class:`~msrr.core.events.TopologyEvent` (``"dock"`` or
        ``"undock"``, the connection with its ports, tick, simulated time).
    """


@hookspec
def msrr_on_run_end(run: Any, result: Any) -> None:
    """A run ended, successfully or not.

    :param run: the run.
    :param result: the :class:`~msrr.core.events.RunResult` (success, counts, times,
        reason on failure).
    """
