"""Benchmark of the generic ``mujoco`` driver: real-time factor and success by system size.

For each example robot and size ``n`` one reconfiguration runs in physics from the
robot's description alone (:func:`msrr.core.app.testing.run_physics`: the generic
recognizer, the drive controller, judged on the simulator's ground truth):

* ``cube``: a line of ``n`` wheeled cubes becomes an L -- the last cube undocks from the
  east face of the one before, drives round and docks onto its north face;
* ``hinge``: a chain of ``n`` hinges folds until its ends dock (a ring).

The plan is built directly (one undock, one dock; or one dock), since the generic
planner stops at 12 modules. The table gives the simulated and wall time of the run,
their ratio (the real-time factor of the whole loop: physics, reports, recognition,
control), the physics alone (steps per wall second of a run without commands), and the
verdict: success judged on ground truth, or the reason (a fold whose hinge no longer
moves names it, its angle, its goal and its servo's torque bound).

Usage: ``python benchmarks/generic_physics.py [--seed N] [--sizes 4,10,30]
[--robots cube,hinge] [--timeout S]``.
"""

from __future__ import annotations

import time

import click

from msrr.core import Configuration, Plan, plugins
from msrr.core.actions import detect_action
from msrr.core.app.testing import run_physics
from msrr.core.bodies import with_port_vectors
from msrr.core.generic.physics import PhysicsDriver


def _chain(robot: str, prefix: str, n: int, ports: tuple[str, str]) -> Configuration:
    """``n`` modules of ``robot``'s one kind in a row, each joined to the next by ``ports``."""
    row = Configuration(robot, name=f"{robot}-row{n}")
    for i in range(1, n + 1):
        row.add_module(f"{prefix}{i}", robot)
    for i in range(1, n):
        row.connect(f"{prefix}{i}", f"{prefix}{i + 1}", ports=ports)
    return row


def cube_plan(n: int) -> Plan:
    """A line of ``n`` cubes to an L: the last moves onto the north face of the one before."""
    spec = plugins.robot("cube")
    line = _chain("cube", "c", n, ("E", "W"))
    apart = line.copy()
    apart.disconnect(f"c{n - 1}E-c{n}W")
    goal = apart.copy()
    goal.connect(f"c{n - 1}", f"c{n}", ports=("N", "S"))
    line, apart, goal = (with_port_vectors(c, spec) for c in (line, apart, goal))
    return Plan("cube", "benchmark", line, goal,
                [detect_action(line, apart), detect_action(apart, goal)])


def hinge_plan(n: int) -> Plan:
    """A chain of ``n`` hinges to a ring: the last head docks to the first tail."""
    spec = plugins.robot("hinge")
    chain = _chain("hinge", "h", n, ("head", "tail"))
    ring = chain.copy()
    ring.connect(f"h{n}", "h1", ports=("head", "tail"))
    chain, ring = with_port_vectors(chain, spec), with_port_vectors(ring, spec)
    return Plan("hinge", "benchmark", chain, ring, [detect_action(chain, ring)])


PLANS = {"cube": cube_plan, "hinge": hinge_plan}


def physics_rate(plan: Plan, seconds: float = 2.0) -> float:
    """Simulated seconds per wall second of the bare world of ``plan.start``."""
    with PhysicsDriver(plugins.robot(plan.robot)) as driver:
        driver.reset(plan.start)
        began = time.perf_counter()
        driver.step(seconds)
        return seconds / (time.perf_counter() - began)


@click.command()
@click.option("--seed", default=0, show_default=True)
@click.option("--sizes", default="4,10,30", show_default=True)
@click.option("--robots", default="cube,hinge", show_default=True)
@click.option("--timeout", default=120.0, show_default=True, help="action timeout [s]")
def main(seed: int, sizes: str, robots: str, timeout: float) -> None:
    click.echo(f"seed {seed}")
    click.echo(f"{'robot':6} {'n':>3} {'sim s':>7} {'wall s':>7} {'RTF':>6} {'physics RTF':>11}"
               "  verdict")
    for robot in robots.split(","):
        for n in (int(s) for s in sizes.split(",")):
            plan = PLANS[robot](n)
            began = time.perf_counter()
            result = run_physics(plan, plugins.robot(robot), seed=seed, action_timeout=timeout)
            wall = time.perf_counter() - began
            simulated = result.sim_time
            verdict = "success" if result.success else f"failed: {result.reason}"
            click.echo(f"{robot:6} {n:3d} {simulated:7.1f} {wall:7.1f} "
                       f"{simulated / wall:6.2f} {physics_rate(plan):11.2f}  {verdict}")


if __name__ == "__main__":
    main()
