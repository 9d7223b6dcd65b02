"""msrr.core: the robot-agnostic core of the msrr modular-robot platform.

A plugin writes ``from msrr.core import hookimpl`` and implements the hooks of
:mod:`msrr.core.hookspecs`. Configurations, robot descriptions (``RobotSpec``, its
typed ``RobotDefaults`` and ``ShapeTolerance``) and errors are importable from here
directly. The file functions here are those of :mod:`msrr.core.io`, which take the
:class:`Robot` to check against as an argument;
:func:`msrr.core.plugins.load_configuration` reads a file and checks it against the
installed robot it names. The types a robot's own capabilities build (``Plan``,
``Action``, ``Driver``, ``ModuleCommand``, ``Observation``, ``Control``...) and the errors
they raise (``PlanningError``, ``ExecutionError``) are here too.

Exports load lazily (PEP 562): ``import msrr.core`` is cheap, so the console script
(:mod:`msrr.core.app.launch`) can handle signals before the heavy imports.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .lazy import lazy_exports

if TYPE_CHECKING:
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
    from .robot import (
        Body,
        DockingRules,
        DockTolerance,
        Hinge,
        ModuleKind,
        PortSpec,
        Robot,
        RobotDefaults,
        RobotSpec,
        ShapeTolerance,
        Violation,
        Wheels,
    )
    from .scenario import Scenario

_EXPORTS: dict[str, str] = {
    "Action": "plan",
    "ActionType": "plan",
    "Body": "robot",
    "check_configuration": "io",
    "Configuration": "configuration",
    "ConfigurationError": "errors",
    "ConnectionChange": "plan",
    "Control": "control",
    "DockingRuleError": "errors",
    "DockingRules": "robot",
    "DockTolerance": "robot",
    "Driver": "driver",
    "dump_configuration": "io",
    "Edge": "configuration",
    "ExecutionError": "errors",
    "Hinge": "robot",
    "hookimpl": "hookspecs",
    "hookspec": "hookspecs",
    "load_configuration": "io",
    "ModuleCommand": "driver",
    "ModuleKind": "robot",
    "MsrrError": "errors",
    "Observation": "driver",
    "parse_configuration": "io",
    "Phase": "events",
    "Plan": "plan",
    "PlanningError": "errors",
    "PluginError": "errors",
    "PortSpec": "robot",
    "Pose": "driver",
    "Robot": "robot",
    "RobotDefaults": "robot",
    "RobotSpec": "robot",
    "save_configuration": "io",
    "Scenario": "scenario",
    "ShapeTolerance": "robot",
    "Signature": "configuration",
    "unit": "configuration",
    "UnknownNameError": "errors",
    "UnknownRobotError": "errors",
    "Violation": "robot",
    "VIRTUAL": "configuration",
    "Wheels": "robot",
}
"""Public name -> the module of ``msrr.core`` that defines it (imported on first use)."""

__all__ = [
    "Action",
    "ActionType",
    "Body",
    "Configuration",
    "ConfigurationError",
    "ConnectionChange",
    "Control",
    "DockingRuleError",
    "DockTolerance",
    "DockingRules",
    "Driver",
    "Edge",
    "ExecutionError",
    "Hinge",
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
    "RobotDefaults",
    "RobotSpec",
    "Scenario",
    "ShapeTolerance",
    "Signature",
    "UnknownNameError",
    "UnknownRobotError",
    "VIRTUAL",
    "Violation",
    "Wheels",
    "check_configuration",
    "dump_configuration",
    "hookimpl",
    "hookspec",
    "load_configuration",
    "parse_configuration",
    "save_configuration",
    "unit",
]


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
