"""Hook implementations of the MMRP robot plugin."""

from __future__ import annotations

from msrr.core import hookimpl

from .robot import SPEC
from .rules import MmrpRules


@hookimpl
def msrr_robot():
    return SPEC


@hookimpl
def msrr_docking_rules(robot: str):
    return MmrpRules() if robot == SPEC.name else None
