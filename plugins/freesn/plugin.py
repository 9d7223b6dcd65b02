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


@hookimpl
def msrr_drivers(robot: str, register):
    if robot == SPEC.name:
        from .sim import FreeSNMujocoDriver

        register(FreeSNMujocoDriver)


@hookimpl
def msrr_recognizers(robot: str, register):
    if robot == SPEC.name:
        from .sim import FreeSNRecognizer

        register(FreeSNRecognizer())


@hookimpl
def msrr_controllers(robot: str, register):
    if robot == SPEC.name:
        from .joints import JOINT_MODES
        from .sim import FreeSNController

        for node_type in JOINT_MODES:  # one per joint mode, named as its ``controller``
            register(FreeSNController(node_type.name))
