"""Hook implementations of the FreeBOT robot plugin."""

from __future__ import annotations

from msrr.core import hookimpl
from msrr.core.miso import MISO_EXACT, MisoPlanner
from msrr.core.robot import MisoRules

from .joints import JOINT_MODES
from .robot import SPEC


@hookimpl
def msrr_robot():
    return SPEC


@hookimpl
def msrr_docking_rules(robot: str):
    return MisoRules(SPEC.name) if robot == SPEC.name else None


@hookimpl
def msrr_kinematic_nodes(robot: str, register):
    if robot == SPEC.name:
        for node_type in JOINT_MODES:
            register(node_type)


@hookimpl
def msrr_planners(robot: str, register):
    if robot == SPEC.name:
        register(MisoPlanner())
        register(MISO_EXACT)
