"""Hook implementations of the FreeBOT robot plugin.

Loaded by the command line on every ``--help``: the module imports only the hook
marker; each hook imports what it answers with (the robot, its rules, joints, planners).
"""

from __future__ import annotations

from msrr.core import hookimpl


@hookimpl
def msrr_robot():
    from .robot import SPEC

    return SPEC


@hookimpl
def msrr_docking_rules(robot: str):
    from msrr.core.robot import MisoRules

    from .robot import SPEC

    return MisoRules(SPEC.name) if robot == SPEC.name else None


@hookimpl
def msrr_kinematic_nodes(robot: str, register):
    from .robot import SPEC

    if robot == SPEC.name:
        from .joints import JOINT_MODES

        for node_type in JOINT_MODES:
            register(node_type)


@hookimpl
def msrr_planners(robot: str, register):
    from .robot import SPEC

    if robot == SPEC.name:
        from msrr.core.freeform.miso import MISO_EXACT, MisoPlanner

        register(MisoPlanner())
        register(MISO_EXACT)


@hookimpl
def msrr_drivers(robot: str, register):
    from .robot import SPEC

    if robot == SPEC.name:
        from .sim import DRIVER

        register(DRIVER)


@hookimpl
def msrr_recognizers(robot: str, register):
    from .robot import SPEC

    if robot == SPEC.name:
        from .sim import recognizer

        register(recognizer())


@hookimpl
def msrr_controllers(robot: str, register):
    from .robot import SPEC

    if robot == SPEC.name:
        from .sim import controllers

        for controller in controllers():  # one per joint mode, named as its ``controller``
            register(controller)


@hookimpl
def msrr_scenarios(robot: str, register):
    from .robot import SPEC

    if robot == SPEC.name:
        from .scenarios import SCENARIOS

        for scenario in SCENARIOS:
            register(scenario)
