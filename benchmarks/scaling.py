"""Speed-up of batch work with workers and on a local Ray cluster (issues 18 and 27).

Two workloads, each run serially (one worker, in this process), on a process pool of
``--workers`` and on a local Ray cluster of as many CPUs (started once, before the
timing; its start-up is reported on its own line), one after another in the same run:

* ``library check``: every action edge of each ``--library`` (FreeSN, default S12N6 and
  S6N3) in MuJoCo (:func:`msrr.core.app.feasibility.check_edges`, seed ``--seed``, phase
  timeout ``--timeout`` as ``platform library check``); as the command does, the shipped
  check file orders the work, longest edges first;
* ``sweep``: ``--runs`` seeds of a scenario on the kinematic driver
  (:func:`msrr.core.app.commands.sweep.sweep_run`) -- default MMRP ``series-t``.

Every backend's results are compared with the serial ones (``same`` column: the check's
edges, the sweep's CSV text). Per task the
mean and max of the tasks' own wall time, and ``bound``: the best speed-up any number of
workers could give, the serial time over its longest task (a task is not split).

Usage: ``python benchmarks/scaling.py [--library S12N6 --library S6N3] [--runs 1000]
[--workers 2] [--no-ray]``. The last line is machine-readable::

    check_S12N6_pool_2=... check_S6N3_pool_2=... sweep_pool_2=... check_S12N6_ray_2=...
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import click
import numpy as np

from msrr.core.app.batch import BatchResult, available_cores, ray_available, run_batch
from msrr.core.app.commands.sweep import SweepTask, sweep_csv, sweep_run
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
    bound = f"{batch.wall_time / times.max():.2f}" if reference is None and times.size else ""
    return [name, batch.backend, batch.workers, len(batch.keys), f"{batch.wall_time:.1f}",
            speedup, bound, f"{times.mean():.2f}" if times.size else "-",
            f"{times.max():.2f}" if times.size else "-", "yes" if same else "NO"]


def _start_ray(workers: int) -> object | None:
    """A local Ray cluster of ``workers`` CPUs (its start-up printed), or ``None``."""
    if not ray_available():
        console.print('Ray is not installed (pip install "msrr-platform[cluster]"): skipped')
        return None
    import ray

    began = time.perf_counter()
    ray.init(address="local", num_cpus=workers, include_dashboard=False,
             log_to_driver=False, logging_level="ERROR")
    console.print(f"local Ray cluster of {workers} CPUs started in "
                  f"{time.perf_counter() - began:.1f} s (not in the times below)")
    return ray


def _workloads(libraries: tuple[str, ...], timeout: float, runs: int, robot: str,
               scenario: str, seed: int) -> list[tuple[str, object]]:
    """``(name, run)`` of every workload; ``run(workers, backend)`` -> (results, batch)."""
    runner = default_runner("freesn", options=ExecutorOptions(action_timeout=timeout,
                                                              retries=0), seed=seed)
    out: list[tuple[str, object]] = []
    for library in libraries:
        cases = edge_cases(load_library(LIBRARIES / f"{library}.json"), runner.robot)
        sidecar = check_path(LIBRARIES / f"{library}.json")  # orders the work, as the command
        previous = load_check(sidecar) if sidecar.is_file() else None

        def check(count: int, backend: str, cases=cases, previous=previous
                  ) -> tuple[object, BatchResult]:
            return check_edges(cases, runner, workers=count, backend=backend, previous=previous)

        out.append((f"check {library}", check))
    tasks = [SweepTask(robot=robot, scenario=scenario, start=None, goal=None, seed=seed + k,
                       driver="kinematic") for k in range(runs)]

    def sweep(count: int, backend: str) -> tuple[object, BatchResult]:
        batch = run_batch(sweep_run, tasks, keys=[t.key for t in tasks], workers=count,
                          backend=backend, label="runs")
        return sweep_csv([r for r in batch.results if r is not None]), batch  # NaN != NaN

    out.append((f"sweep {robot} {scenario} x {runs}", sweep))
    return out


@click.command()
@click.option("--library", "libraries", multiple=True, default=("S12N6", "S6N3"),
              show_default=True, help="FreeSN library (plugins/freesn/libraries/NAME.json), "
              "repeatable.")
@click.option("--timeout", default=30.0, show_default=True,
              help="Simulated time one phase may take in the check [s] (the command's default).")
@click.option("--runs", default=1000, show_default=True, help="Seeds of the sweep.")
@click.option("--robot", default="mmrp", show_default=True, help="Robot of the sweep.")
@click.option("--scenario", default="series-t", show_default=True, help="Sweep scenario.")
@click.option("--workers", default=2, show_default=True, help="Workers of the pool and Ray.")
@click.option("--seed", default=0, show_default=True, help="Seed of the check; first sweep seed.")
@click.option("--ray/--no-ray", "use_ray", default=True, help="Include the local Ray cluster.")
def main(libraries: tuple[str, ...], timeout: float, runs: int, robot: str, scenario: str,
         workers: int, seed: int, use_ray: bool) -> None:
    console.print(f"seed {seed}; libraries {', '.join(libraries)} (timeout {timeout:g} s); "
                  f"sweep {robot} {scenario} x {runs} seeds (kinematic driver); {workers} "
                  f"workers; {available_cores()} cores, load average {_load()}")
    workloads = _workloads(libraries, timeout, runs, robot, scenario, seed)
    ray = _start_ray(workers) if use_ray else None
    backends = [("serial", 1), ("pool", workers)] + ([("ray", workers)] if ray else [])
    rows: list[list[object]] = []
    figures: dict[str, float] = {}
    for name, run in workloads:
        reference: BatchResult | None = None
        expected: object = None
        for backend, count in backends:
            result, batch = run(count, backend)  # type: ignore[operator]
            if reference is None:
                reference, expected = batch, result
            rows.append(_row(name, batch, None if backend == "serial" else reference,
                             result == expected))
            if backend != "serial":
                key = "_".join(name.split()[:2]) if name.startswith("check") else "sweep"
                figures[f"{key}_{backend}_{count}"] = reference.wall_time / batch.wall_time
    if ray is not None:
        ray.shutdown()  # type: ignore[attr-defined]
    console.print(table(f"Batch work on this machine (seed {seed})",
                        ["workload", "backend", "workers", "tasks", "wall [s]", "speed-up",
                         "bound", "task mean [s]", "task max [s]", "same"], rows))
    console.print(f"load average at the end {_load()} (other jobs share these cores: a "
                  "load above the core count lowers every speed-up)", markup=False)
    console.print(" ".join(f"{k}={v:.2f}" for k, v in figures.items()), markup=False)


if __name__ == "__main__":
    main()
