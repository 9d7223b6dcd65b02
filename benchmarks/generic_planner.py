"""Benchmark of the generic planner (exact A* over dock/undock steps) by system size.

Per robot and size, seeded random pairs of legal configurations with the same module
ids (``msrr.core.random_configurations``) are planned with
:class:`msrr.core.generic.GenericPlanner`; the table gives the median and largest time,
configurations explored, plan length and the lower bound ``|links xor goal links|``
(equal when no temporary dock is needed), how many goals no legal sequence reaches,
and how many pairs hit a limit (``PlanningError``). It measures where the stated size limit (``MAX_MODULES``,
``MAX_PORTS``, ``MAX_EXPANSIONS``) sits.

A robot name followed by ``+connected`` plans under the same port pairs but with
loops allowed and ``stay_connected`` (every intermediate configuration one group), the
hard case: a change then needs a temporary dock first, and A* explores more.

Usage: ``python benchmarks/generic_planner.py [--seed N] [--pairs N]
[--robots hinge,mmrp,hinge+connected] [--sizes 3,4,6,8,10,12]``.
"""

from __future__ import annotations

import statistics
import time
from dataclasses import replace

import click
import numpy as np

from msrr.core import Configuration, DockingRules, PlanningError, Robot, Violation, plugins
from msrr.core.generic import MAX_EXPANSIONS, MAX_MODULES, MAX_PORTS, GenericPlanner
from msrr.core.generic.planner import links_of
from msrr.core.random_configurations import random_configuration
from msrr.core.robot import port_reuse_violations


class LoopsAllowed(DockingRules):
    """A robot's port pairs, each port once, loops allowed."""

    def __init__(self, rules: DockingRules):
        self.rules = rules

    def ports_compatible(self, source_kind: str, source_port: str | None,
                         target_kind: str, target_port: str | None) -> bool:
        return self.rules.ports_compatible(source_kind, source_port, target_kind, target_port)

    def check_topology(self, config: Configuration) -> list[Violation]:
        return port_reuse_violations(config)


def _robot(name: str) -> tuple[Robot, Robot]:
    """(robot that plans, robot whose rules make the random configurations)."""
    base, _, mode = name.partition("+")
    robot = plugins.resolve(base)
    if mode == "connected":
        spec = replace(robot.spec, defaults=replace(robot.spec.defaults, stay_connected=True))
        return Robot(spec, LoopsAllowed(robot.rules), robot.joint_modes), robot
    return robot, robot


@click.command()
@click.option("--seed", default=0, show_default=True)
@click.option("--pairs", default=10, show_default=True, help="Pairs per robot and size.")
@click.option("--robots", default="hinge,mmrp", show_default=True)
@click.option("--sizes", default="3,4,6,8,10,12", show_default=True)
def main(seed: int, pairs: int, robots: str, sizes: str) -> None:
    print(f"seed={seed} pairs={pairs} limits: {MAX_MODULES} modules, {MAX_PORTS} ports, "
          f"{MAX_EXPANSIONS} expansions")
    print(f"{'robot':16} {'n':>3} {'ports':>5} {'median ms':>10} {'max ms':>9} "
          f"{'explored':>9} {'actions':>8} {'bound':>6} {'unreachable':>11} {'limit hit':>9}")
    for name in robots.split(","):
        robot, source = _robot(name)
        planner = GenericPlanner(robot)
        for n in (int(s) for s in sizes.split(",")):
            rng = np.random.default_rng(seed)
            times, explored, lengths, bounds, failed, unreachable = [], [], [], [], 0, 0
            for _ in range(pairs):
                start = random_configuration(source.spec, source.rules, n, rng)
                goal = random_configuration(source.spec, source.rules, n, rng)
                began = time.perf_counter()
                try:
                    plan = planner.plan(start, goal)
                except PlanningError as exc:
                    if "no sequence" in str(exc):
                        unreachable += 1
                    else:
                        failed += 1
                    continue
                times.append((time.perf_counter() - began) * 1e3)
                explored.append(plan.stats.get("expanded", 0))
                lengths.append(len(plan.actions))
                bounds.append(len(links_of(start).keys() ^ links_of(goal).keys()))
            ports = n * len(robot.spec.module_kinds[0].ports)
            if times:
                print(f"{name:16} {n:3d} {ports:5d} {statistics.median(times):10.1f} "
                      f"{max(times):9.1f} {statistics.median(explored):9.0f} "
                      f"{statistics.median(lengths):8.1f} {statistics.median(bounds):6.1f} "
                      f"{unreachable:11d} {failed:6d}/{pairs}")
            else:
                print(f"{name:16} {n:3d} {ports:5d} {'-':>10} {'-':>9} {'-':>9} {'-':>8} "
                      f"{'-':>6} {unreachable:11d} {failed:6d}/{pairs}")


if __name__ == "__main__":
    main()
