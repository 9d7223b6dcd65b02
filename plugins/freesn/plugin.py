"""Hook implementations of the FreeSN robot plugin."""

from __future__ import annotations

from msrr.core import hookimpl

from .robot import SPEC
from .rules import FreeSNRules


@hookimpl
def msrr_robot():
    return SPEC


@hookimpl
def msrr_docking_rules(robot: str):
    return FreeSNRules() if robot == SPEC.name else None


@hookimpl
def msrr_kinematic_nodes(robot: str, register):
    if robot == SPEC.name:
        from .joints import JOINT_MODES

        for node_type in JOINT_MODES:
            register(node_type)
