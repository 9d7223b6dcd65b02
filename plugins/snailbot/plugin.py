"""Hook implementations of the SnailBot robot plugin."""

from __future__ import annotations

from msrr.core import hookimpl
from msrr.core.robot import MisoRules

from .robot import SPEC


@hookimpl
def msrr_robot():
    return SPEC


@hookimpl
def msrr_docking_rules(robot: str):
    return MisoRules(SPEC.name) if robot == SPEC.name else None
