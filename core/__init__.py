"""msrr.core: the robot-agnostic core of the msrr modular-robot platform.

A plugin writes ``from msrr.core import hookimpl`` and implements the hooks of
:mod:`msrr.core.hookspecs`. Configurations, robot descriptions and errors are
importable from here directly. The file functions here are those of
:mod:`msrr.core.io`, which take the :class:`Robot` to check against as an argument;
:func:`msrr.core.plugins.load_configuration` reads a file and checks it against the
installed robot it names. The types a robot's own capabilities build (``Plan``,
``Action``, ``Driver``, ``ModuleCommand``, ``Observation``, ``Control``...) and the errors
they raise (``PlanningError``, ``ExecutionError``) are here too.
"""

from .configuration import VIRTUAL, Configuration, Edge, Signature, unit
from .control import Control
from .driver import Driver, ModuleCommand, Observation, Pose
from .errors import (
    ConfigurationError,
    DockingRuleError,
    ExecutionError,
    MsrrError,
    PlanningError,
    PluginError,
    UnknownNameError,
    UnknownRobotError,
)
from .events import Phase
from .hookspecs import hookimpl, hookspec
from .io import (
    check_configuration,
    dump_configuration,
    load_configuration,
    parse_configuration,
    save_configuration,
)
from .plan import Action, ActionType, ConnectionChange, Plan
from .robot import DockingRules, ModuleKind, PortSpec, Robot, RobotSpec, Violation
from .scenario import Scenario

__all__ = [
    "Action",
    "ActionType",
    "Configuration",
    "ConfigurationError",
    "ConnectionChange",
    "Control",
    "DockingRuleError",
    "DockingRules",
    "Driver",
    "Edge",
    "ExecutionError",
    "ModuleCommand",
    "ModuleKind",
    "MsrrError",
    "Observation",
    "Phase",
    "Plan",
    "PlanningError",
    "PluginError",
    "PortSpec",
    "Pose",
    "Robot",
    "RobotSpec",
    "Scenario",
    "Signature",
    "UnknownNameError",
    "UnknownRobotError",
    "VIRTUAL",
    "Violation",
    "check_configuration",
    "dump_configuration",
    "hookimpl",
    "hookspec",
    "load_configuration",
    "parse_configuration",
    "save_configuration",
    "unit",
]
