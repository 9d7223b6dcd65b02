"""Speed-up of batch work with workers and on a local Ray cluster (issue 18).

Two workloads, each run serially (one worker, in this process), on a process pool of
``--workers`` and on a local Ray cluster of as many CPUs (started once, before the
timing; its start-up is reported on its own line):

* ``library check``: every action edge of a FreeSN library in MuJoCo
  (:func:`msrr.core.app.feasibility.check_edges`, seed ``--seed``, phase timeout
  ``--timeout``) -- default S12N6, 14 edges; as ``platform library check`` does, the
  shipped check file (when there is one) orders the work, longest edges first;
* ``sweep``: ``--runs`` seeds of a scenario on the kinematic driver
  (:func:`msrr.core.app.commands.sweep.sweep_run`) -- default MMRP ``series-t``.

Every backend's results are compared with the serial ones (``same`` column). Per-task
costs (mean and max of the tasks' own wall time) feed ``docs/scaling.md``. Target: the
library check at least 1.7 x as fast with two workers as with one, on two cores.

Usage: ``python benchmarks/scaling.py [--library S12N6] [--runs 100] [--workers 2]
[--no-ray]``. The last line is machine-readable::

    check_speedup_2=... sweep_speedup_2=... check_speedup_ray=... sweep_speedup_ray=...
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import click
import numpy as np

from msrr.core.app.batch import BatchResult, available_cores, ray_available, run_batch
from msrr.core.app.commands.sweep import SweepTask, sweep_run
from msrr.core.app.feasibility import check_edges, default_runner
from msrr.core.console import console, table
from msrr.core.executor import ExecutorOptions
from msrr.core.library.check import check_path, edge_cases, load_check
from msrr.core.plugins import load_library

LIBRARIES = Path(__file__).resolve().parents[1] / "plugins" / "freesn" / "libraries"


def _load() -> str:
    """The 1, 5 and 15 minute load averages."""
    return " ".join(f"{x:.1f}" for x in os.getloadavg())


def _row(name: str, batch: BatchResult, reference: BatchResult | None,
         same: bool) -> list[object]:
    times = np.array([t for t in batch.task_times if np.isfinite(t)])
    speedup = "1.00" if reference is None else f"{reference.wall_time / batch.wall_time:.2f}"
    return [name, batch.backend, batch.workers, len(batch.keys), f"{batch.wall_time:.1f}",
            speedup, f"{times.mean():.2f}" if times.size else "-",
            f"{times.max():.2f}" if times.size else "-", "yes" if same else "NO"]


@click.command()
@click.option("--library", default="S12N6", show_default=True,
              help="FreeSN library name (plugins/freesn/libraries/NAME.json).")
@click.option("--timeout", default=20.0, show_default=True,
              help="Simulated time one phase may take in the check [s].")
@click.option("--runs", default=100, show_default=True, help="Seeds of the sweep.")
@click.option("--robot", default="mmrp", show_default=True, help="Robot of the sweep.")
@click.option("--scenario", default="series-t", show_default=True, help="Sweep scenario.")
@click.option("--workers", default=2, show_default=True, help="Workers of the pool and Ray.")
@click.option("--seed", default=0, show_default=True, help="Seed of the check; first sweep seed.")
@click.option("--ray/--no-ray", "use_ray", default=True, help="Include the local Ray cluster.")
def main(library: str, timeout: float, runs: int, robot: str, scenario: str, workers: int,
         seed: int, use_ray: bool) -> None:
    console.print(f"seed {seed}; library {library} (timeout {timeout:g} s); sweep {robot} "
                  f"{scenario} x {runs} seeds (kinematic driver); {workers} workers; "
                  f"{available_cores()} cores, load average {_load()}")
    runner = default_runner("freesn", options=ExecutorOptions(action_timeout=timeout,
                                                              retries=0), seed=seed)
    cases = edge_cases(load_library(LIBRARIES / f"{library}.json"), runner.robot)
    sidecar = check_path(LIBRARIES / f"{library}.json")  # orders the work, as the command does
    previous = load_check(sidecar) if sidecar.is_file() else None
    tasks = [SweepTask(robot=robot, scenario=scenario, start=None, goal=None, seed=seed + k,
                       driver="kinematic") for k in range(runs)]
    backends = [("serial", 1), ("pool", workers)]
    ray = None
    if use_ray and ray_available():
        import ray
        began = time.perf_counter()
        ray.init(address="local", num_cpus=workers, include_dashboard=False,
                 log_to_driver=False, logging_level="ERROR", _node_ip_address="127.0.0.1")
        console.print(f"local Ray cluster of {workers} CPUs started in "
                      f"{time.perf_counter() - began:.1f} s (not in the times below)")
        backends.append(("ray", workers))
    elif use_ray:
        console.print('Ray is not installed (pip install "msrr-platform[cluster]"): skipped')
    rows: list[list[object]] = []
    figures: dict[str, float] = {}
    for name in ("library check", "sweep"):
        reference: BatchResult | None = None
        for backend, count in backends:
            if name == "library check":
                checks, batch = check_edges(cases, runner, workers=count, backend=backend,
                                            previous=previous)
                result: object = checks
            else:
                batch = run_batch(sweep_run, tasks, keys=[t.key for t in tasks],
                                  workers=count, backend=backend, label="runs")
                result = batch.results
            if reference is None:
                reference, expected = batch, result
            rows.append(_row(name, batch, None if backend == "serial" else reference,
                             result == expected))
            if backend != "serial":
                label = "check" if name == "library check" else "sweep"
                key = f"{label}_speedup_{count if backend == 'pool' else 'ray'}"
                figures[key] = reference.wall_time / batch.wall_time
    if ray is not None:
        ray.shutdown()
    console.print(table(f"Batch work on this machine (seed {seed})",
                        ["workload", "backend", "workers", "tasks", "wall [s]", "speed-up",
                         "task mean [s]", "task max [s]", "same"], rows))
    console.print(f"load average at the end {_load()} (other jobs share these cores: a "
                  "load above the core count lowers every speed-up)", markup=False)
    console.print(" ".join(f"{k}={v:.2f}" for k, v in figures.items()), markup=False)


if __name__ == "__main__":
    main()
