"""msrr.core: the robot-agnostic core of the msrr modular-robot platform.

A plugin writes ``from msrr.core import hookimpl`` and implements the hooks of
:mod:`msrr.core.hookspecs`. Configurations, robot descriptions and errors are
importable from here directly. The file functions here are those of
:mod:`msrr.core.io`, which take the :class:`Robot` to check against as an argument;
:func:`msrr.core.plugins.load_configuration` reads a file and checks it against the
installed robot it names.
"""

from .configuration import VIRTUAL, Configuration, Edge, Signature, unit
from .errors import (
    ConfigurationError,
    DockingRuleError,
    MsrrError,
    PluginError,
    UnknownNameError,
    UnknownRobotError,
)
from .hookspecs import hookimpl, hookspec
from .io import (
    check_configuration,
    dump_configuration,
    load_configuration,
    parse_configuration,
    save_configuration,
)
from .robot import DockingRules, ModuleKind, PortSpec, Robot, RobotSpec, Violation
from .scenario import Scenario

__all__ = [
    "VIRTUAL",
    "Configuration",
    "ConfigurationError",
    "DockingRuleError",
    "DockingRules",
    "Edge",
    "ModuleKind",
    "MsrrError",
    "PluginError",
    "PortSpec",
    "Robot",
    "RobotSpec",
    "Scenario",
    "Signature",
    "UnknownNameError",
    "UnknownRobotError",
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
