"""Benchmark of the FreeSN closed loop (issue 12, item 9; paper section 4.1, 10 Hz loop).

For S4N5, S6N3 and S12N6 (18 modules, 48 joint motors at 12 struts x 2 connectors x 2
wheels), one moving edge of the shipped library runs in MuJoCo under the executor's IK
tracking (:class:`msrr.core.closed_loop.PhaseTracker`), recognizer noise 2 deg and slip
0.05. Per control tick the benchmark times **recognize + IK tracking + controller
commands** (``obs -> commands``; the driver's report assembly and physics excluded) and
reports its median and 95th percentile, in wall time and in the process's CPU time (on a
shared machine the CPU time is what the tick costs one core; the wall time also counts
the other jobs' share of it), and the mean number of evaluations of eq. 6 with its
gradient in a tick's tracking solve (the tick's work, which the machine's load does not
change: the CPU time of the same work varies about 2x with the load); the **real-time factor** is simulated time over wall time,
for the physics alone and for the whole loop (reports, tick, physics). As in the
executor, the reports go through the recognizer's report filter first
(:mod:`msrr.plugins.freesn.sim.filtering`, issues 31-32); its CPU time per tick is a
column of its own beside the tick's (median and 95th percentile).
Targets at 18 modules (issue 12): tick median <= 20 ms and the simulation's real-time
factor (physics) >= 5; the loop RTF (reports + tick + physics, one core) is shown too.

Usage: ``python benchmarks/freesn_control.py [--seed N] [--ticks N] [--workers N]
[--cluster ADDRESS] [--drive holonomic|differential]`` (one batch task per library,
:mod:`msrr.core.app.batch`; the default
one worker keeps the timings those of one core alone). The last line is
``tick_median_ms_18=... tick_p95_ms_18=... tick_cpu_median_ms_18=...
filter_cpu_median_ms_18=... evaluations_per_tick_18=... rtf_loop_18=... rtf_physics_18=...``.
"""

from __future__ import annotations

import math
import time
from functools import partial
from pathlib import Path

import click
import numpy as np

from msrr.core import plugins
from msrr.core.app.batch import exit_on_interrupt, run_batch
from msrr.core.closed_loop import PhaseTracker, TrackingOptions, connection_goal, tree_for
from msrr.core.console import console, table
from msrr.core.kinematics import GroundModel
from msrr.core.library import load_library
from msrr.core.library.check import edge_cases
from msrr.plugins.freesn.sim import FreeSNMujocoDriver

LIBRARIES = Path(__file__).resolve().parents[1] / "plugins" / "freesn" / "libraries"
EDGES = {"S4N5": "S4N5:S4N5-1.1->S4N5-1.2", "S6N3": "S6N3:S6N3-1.1->S6N3-1.2",
         "S12N6": "S12N6:S12N6-4.3->S12N6-4.1"}
"""One moving edge per library (a large motion, so the tracker works every tick)."""


def measure(name: str, seed: int, ticks: int, rate: float = 10.0, drive: str = "holonomic"
            ) -> dict[str, float]:
    """Time ``ticks`` control ticks of ``name``'s edge (a batch task: one library each)."""
    robot = plugins.resolve("freesn")
    case = next(c for c in edge_cases(load_library(LIBRARIES / f"{name}.json"), robot)
                if c.key == EDGES[name])
    recognizer = plugins.recognizers.get("freesn")
    controller = plugins.controllers.get("freesn")
    tick_s, cpu_s, filter_s, evaluations, physics_s = [], [], [], [], 0.0
    with FreeSNMujocoDriver(noise=math.radians(2.0), slip=0.05, seed=seed,
                            connector_drive=drive) as driver:
        driver.reset(case.start)
        report_filter = recognizer.report_filter()
        current = recognizer.recognize(report_filter.update(driver.get_observation()).sensors)
        tree = tree_for(current, case.action.kinematic_tree, robot.default_joint_mode())
        tracker = PhaseTracker(tree, connection_goal(current, case.target), TrackingOptions(),
                               seed=seed, ground=GroundModel.for_configuration(current,
                                                                               robot.spec))
        began = time.perf_counter()
        for _ in range(ticks):
            observation = driver.get_observation()
            c0 = time.process_time()
            observation = report_filter.update(observation)
            filter_s.append(time.process_time() - c0)
            t0, c0 = time.perf_counter(), time.process_time()
            current = recognizer.recognize(observation.sensors)
            joint = tracker.step(current)
            commands = controller.commands(joint, observation, yaw=0.0)
            tick_s.append(time.perf_counter() - t0)
            cpu_s.append(time.process_time() - c0)
            evaluations.append(tracker.last.problem.evaluations
                               if tracker.last is not None and tracker.last.problem else 0)
            driver.send_action(commands)
            t1 = time.perf_counter()
            driver.step(1.0 / rate)
            physics_s += time.perf_counter() - t1
        loop_s = time.perf_counter() - began
        sim = driver.time
        modules = len(case.start.modules())
    ms = np.array(tick_s[1:]) * 1e3   # the first tick is the initial solve with restarts
    cpu = np.array(cpu_s[1:]) * 1e3
    return {"modules": modules, "first_ms": tick_s[0] * 1e3, "median_ms": float(np.median(ms)),
            "p95_ms": float(np.percentile(ms, 95)), "cpu_median_ms": float(np.median(cpu)),
            "cpu_p95_ms": float(np.percentile(cpu, 95)),
            "filter_cpu_median_ms": float(np.median(filter_s[1:]) * 1e3),
            "filter_cpu_p95_ms": float(np.percentile(filter_s[1:], 95) * 1e3),
            "evaluations": float(np.mean(evaluations[1:])), "rtf_physics": sim / physics_s,
            "rtf_loop": sim / loop_s, "sim_s": sim}


@click.command()
@click.option("--seed", default=0, show_default=True)
@click.option("--ticks", default=60, show_default=True, help="Control ticks per library.")
@click.option("--workers", type=click.IntRange(min=0), default=1, show_default=True,
              help="Worker processes, one library each (1: here, so the times are of one "
                   "core alone; 0: one per core).")
@click.option("--cluster", default=None, metavar="ADDRESS",
              help="Run on Ray: auto, ray://HOST:PORT or local.")
@click.option("--drive", type=click.Choice(["holonomic", "differential"]), default="holonomic",
              show_default=True, help="The connectors' model (the world's connector_drive).")
def main(seed: int, ticks: int, workers: int, cluster: str | None, drive: str) -> None:
    console.print(f"seed {seed}, {ticks} ticks at 10 Hz per library, noise 2 deg, slip 0.05, "
                  f"{drive} connectors")
    rows, results = [], {}
    with exit_on_interrupt():
        measured = run_batch(partial(measure, seed=seed, ticks=ticks, drive=drive), list(EDGES),
                             keys=list(EDGES), workers=workers, cluster=cluster,
                             label="libraries").values()
    for name, r in zip(EDGES, measured, strict=True):
        results[name] = r
        rows.append([name, EDGES[name].split(":", 1)[1], r["modules"], f"{r['first_ms']:.1f}",
                     f"{r['median_ms']:.2f}", f"{r['p95_ms']:.2f}", f"{r['cpu_median_ms']:.2f}",
                     f"{r['cpu_p95_ms']:.2f}", f"{r['filter_cpu_median_ms']:.2f}",
                     f"{r['filter_cpu_p95_ms']:.2f}", f"{r['evaluations']:.1f}",
                     f"{r['rtf_physics']:.1f}",
                     f"{r['rtf_loop']:.1f}"])
    console.print(table("FreeSN control tick (report filter; recognize + IK tracking + "
                        "commands)",
                        ["library", "edge", "modules", "first tick [ms]", "median [ms]",
                         "p95 [ms]", "CPU median [ms]", "CPU p95 [ms]",
                         "filter CPU median [ms]", "filter CPU p95 [ms]", "evals / tick",
                         "RTF physics",
                         "RTF loop"], rows))
    big = results["S12N6"]
    console.print(f"tick_median_ms_18={big['median_ms']:.2f} tick_p95_ms_18={big['p95_ms']:.2f} "
                  f"tick_cpu_median_ms_18={big['cpu_median_ms']:.2f} "
                  f"filter_cpu_median_ms_18={big['filter_cpu_median_ms']:.2f} "
                  f"evaluations_per_tick_18={big['evaluations']:.1f} "
                  f"rtf_loop_18={big['rtf_loop']:.1f} rtf_physics_18={big['rtf_physics']:.1f}")


if __name__ == "__main__":
    main()
