"""Hook implementations of the MMRP robot plugin.

Loaded by the command line on every ``--help``: the module imports only the hook
marker; each hook imports what it answers with (the robot, its rules, planners).
"""

from __future__ import annotations

from pathlib import Path

from msrr.core import hookimpl


@hookimpl
def msrr_robot():
    from .robot import SPEC

    return SPEC


@hookimpl
def msrr_docking_rules(robot: str):
    from .robot import SPEC
    from .rules import MmrpRules

    return MmrpRules() if robot == SPEC.name else None


CONFIGS = Path(__file__).parent / "configs"


@hookimpl
def msrr_planners(robot: str, register):
    from .robot import SPEC

    if robot == SPEC.name:
        from .planner import McsHybridPlanner

        register(McsHybridPlanner())


@hookimpl
def msrr_recognizers(robot: str, register):
    from .robot import SPEC

    if robot == SPEC.name:
        from .recognition import DistributedRecognizer

        register(DistributedRecognizer())


@hookimpl
def msrr_scenarios(robot: str, register):
    from .robot import SPEC

    if robot == SPEC.name:
        from msrr.core.scenario import Scenario

        register(Scenario(name="cross-probe",
                          description="cross to probe, 9 modules (paper Figs. 11-15)",
                          start=CONFIGS / "cross.json", goal=CONFIGS / "probe.json",
                          default=True))
        register(Scenario(name="series-t",
                          description="series to T, 4 modules (paper Figs. 17-18)",
                          start=CONFIGS / "series.json", goal=CONFIGS / "t.json"))
        register(Scenario(name="random-30",
                          description="random 30-module tree to another (issue 17, ~17 min "
                                      "simulated)",
                          start=CONFIGS / "random30-start.json",
                          goal=CONFIGS / "random30-goal.json"))


@hookimpl
def msrr_drivers(robot: str, register):
    from .robot import SPEC

    if robot == SPEC.name:
        from .sim import MmrpSimDriver

        register(MmrpSimDriver)


@hookimpl
def msrr_controllers(robot: str, register):
    from .robot import SPEC

    if robot == SPEC.name:
        from .sim import MmrpController

        register(MmrpController())
