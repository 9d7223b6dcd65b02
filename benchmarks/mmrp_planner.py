"""Benchmark of the MMRP hybrid planner (Wei et al. 2023) at every size (issue 17).

Per size, on seeded random pairs of legal planar MMRP trees:

* 5-9 modules: plan pairs against the exhaustive optimum (``optimum.optimum``);
* 10-20 modules: against the certified optimum of the integer program
  (``exact.certified_optimum``, HiGHS, 60 s limit each);
* 50-1,000 modules: pairs and time only; at the ``--alternatives`` sizes (500 and
  1,000) every alternative decomposition is also planned alone (``plan_hybrid(...,
  alternative=k)``, to the end, cuts included): "alone: best / first" is the mean of
  the fewest pairs over them and of the first (the largest common subconfiguration);
* cuts for motion per size (kept connections undocked and docked again so hooked
  groups can separate; each costs one dock/undock pair);
* every plan replayed by the grid checker (``check.check_plan``): collisions, turns
  included, and invalid steps must be 0;
* planning time: wall ("median ms", "p95 ms") and CPU time of the planning process
  ("median CPU ms": on a shared machine what the plan costs).

Runs in PyBullet are ``benchmarks/mmrp_sim.py``.

Usage: ``python benchmarks/mmrp_planner.py [--seed N] [--pairs N] [--mid N] [--runs N]
[--sizes 50,100,...] [--alternatives 500,1000] [--plot FILE] [--workers N]
[--cluster ADDRESS]``. The
pairs are drawn in order from one generator, then planned as batch tasks
(:mod:`msrr.core.app.batch`; ``--workers 0``, the default, uses every core): the table's
counts are the same for the same seed whichever backend runs them. The last line is
``paper_cross_probe_pairs=... optimal_rate=... max_excess=... checker_problems=...
median_ms_500=... median_ms_1000=...``.
"""

from __future__ import annotations

import statistics
import time
from pathlib import Path
from typing import Any

import click
import numpy as np

from msrr.core.app.batch import batch_options, exit_on_interrupt, run_batch
from msrr.core.configuration import Configuration
from msrr.core.console import console, exit_unless_installed, table
from msrr.core.errors import PlanningError
from msrr.core.io import load_configuration
from msrr.plugins.mmrp.check import check_plan
from msrr.plugins.mmrp.exact import certified_optimum
from msrr.plugins.mmrp.optimum import optimum
from msrr.plugins.mmrp.planner import plan_hybrid
from msrr.plugins.mmrp.random_trees import random_tree

CONFIGS = Path(__file__).resolve().parents[1] / "plugins" / "mmrp" / "configs"
SMALL = (5, 6, 7, 8, 9)
MID = (10, 12, 14, 16, 18, 20)
LARGE = (50, 100, 200, 500, 1000)


def _p95(values: list[float]) -> float:
    return float(np.percentile(values, 95)) if values else float("nan")


def _solve(task: tuple[Configuration, Configuration, int, str | None]) -> dict[str, Any]:
    """Plan one pair, replay it in the checker, and find its reference optimum (a batch
    task: a pure function of the pair, its seed and the reference kind)."""
    start, goal, seed, reference = task
    began, cpu = time.perf_counter(), time.process_time()
    result = plan_hybrid(start, goal, seed=seed)
    out: dict[str, Any] = {"ms": (time.perf_counter() - began) * 1e3,
                           "cpu_ms": (time.process_time() - cpu) * 1e3, "pairs": result.pairs,
                           "problems": len(check_plan(result.plan)),
                           "stalls": result.field.stalled,
                           "cuts": int(result.plan.stats["cut_for_motion"]),
                           "parks": int(result.plan.stats["parking_moves"])}
    if reference == "exhaustive":
        out["best"] = optimum(start, goal).pairs
    elif reference == "milp":
        exact = certified_optimum(start, goal, time_limit=60.0)
        out.update(best=exact.bound, uncertified=not exact.certified, ref_s=exact.seconds)
    elif reference == "alternatives":  # each decomposition planned alone, to the end
        each = []
        while True:
            try:
                each.append(plan_hybrid(start, goal, seed=seed, alternative=len(each)).pairs)
            except PlanningError:
                break
        out.update(alternatives=min(each), first=each[0])
    return out


def _run_size(n: int, count: int, rng: np.random.Generator, reference: str | None,
              batch: dict[str, Any]) -> tuple[list, dict]:
    # the pairs and their seeds are drawn here, in order, from one generator
    tasks = []
    for _ in range(count):
        start, goal = random_tree(n, rng), random_tree(n, rng)
        tasks.append((start, goal, int(rng.integers(1 << 31)), reference))
    with exit_on_interrupt():
        done = run_batch(_solve, tasks, label=f"{n}-module pairs", **batch).values()
    found, ms = [d["pairs"] for d in done], [d["ms"] for d in done]
    best = [d["best"] for d in done if "best" in d]
    problems, stalls = sum(d["problems"] for d in done), sum(d["stalls"] for d in done)
    cuts, parks = sum(d["cuts"] for d in done), sum(d["parks"] for d in done)
    uncertified = sum(d.get("uncertified", False) for d in done)
    ref_s = [d["ref_s"] for d in done if "ref_s" in d]
    diff = [a - b for a, b in zip(found, best, strict=True)] if best else []
    if diff and min(diff) < 0:
        raise SystemExit(f"plan below the proven optimum at {n} modules: a solver bug")
    summary = {"n": n, "count": count, "ms": ms, "diff": diff, "problems": problems,
               "mean_pairs": statistics.mean(found)}
    alone = [d["alternatives"] for d in done if "alternatives" in d]
    paper = [d["first"] for d in done if "first" in d]
    row = [n, count, f"{statistics.mean(found):.2f}",
           f"{statistics.mean(best):.2f}" if best else "-",
           f"{sum(d == 0 for d in diff) / len(diff):.3f}" if diff else "-",
           f"{statistics.mean(diff):.3f} / {max(diff)}" if diff else "-",
           problems, stalls, cuts, f"{cuts / count:.2f}", parks,
           f"{statistics.mean(alone):.2f} / {statistics.mean(paper):.2f}" if alone else "-",
           f"{statistics.median(ms):.1f}", f"{_p95(ms):.1f}",
           f"{statistics.median(d['cpu_ms'] for d in done):.1f}",
           (f"{uncertified} / {max(ref_s):.1f}" if reference == "milp" else "-")]
    return row, summary


@click.command()
@click.option("--seed", default=2023, show_default=True, help="Seed of the random pairs.")
@click.option("--pairs", "n_pairs", default=120, show_default=True,
              help="Random pairs per size of 5-9 modules (exhaustive optimum).")
@click.option("--mid", "n_mid", default=5, show_default=True,
              help="Random pairs per size of 10-20 modules (certified optimum).")
@click.option("--runs", default=9, show_default=True, help="Random pairs per large size.")
@click.option("--sizes", default=",".join(map(str, LARGE)), show_default=True,
              help="Large sizes, comma-separated.")
@click.option("--alternatives", default="500,1000", show_default=True,
              help="Sizes at which every alternative decomposition is also planned alone.")
@click.option("--plot", type=click.Path(path_type=Path), default=None,
              help="Save a plot of time and optimality gap per size to this file.")
@batch_options
def main(seed: int, n_pairs: int, n_mid: int, runs: int, sizes: str, alternatives: str,
         plot: Path | None, workers: int, cluster: str | None) -> None:
    if plot is not None:  # before the work: a missing matplotlib is one line
        exit_unless_installed("matplotlib", "plot", "--plot")
    console.print(f"seed={seed}")
    rng = np.random.default_rng(seed)
    paper = plan_hybrid(load_configuration(CONFIGS / "cross.json"),
                        load_configuration(CONFIGS / "probe.json")).pairs
    rows, summaries = [], []
    each = {int(n) for n in alternatives.split(",") if n}
    plan = [(n, n_pairs, "exhaustive") for n in SMALL] + \
           [(n, n_mid, "milp") for n in MID if n_mid] + \
           [(int(n), runs, "alternatives" if int(n) in each else None)
            for n in sizes.split(",") if n]
    for n, count, reference in plan:
        row, summary = _run_size(n, count, rng, reference,
                                 {"workers": workers, "cluster": cluster})
        rows.append(row)
        summaries.append(summary)
        console.print(f"  {n} modules done", style="dim")
    console.print(table(
        "MMRP mcs-hybrid planner vs the proven optimum",
        ["modules", "pairs run", "mean plan pairs", "mean optimum pairs", "optimal rate",
         "gap mean / max", "checker problems", "field fallback", "cuts",
         "cuts per plan", "parking legs", "alone: best / first", "median ms", "p95 ms",
         "median CPU ms", "uncertified / max MILP s"], rows))
    small = [d for s in summaries if s["n"] in SMALL for d in s["diff"]]
    medians = {s["n"]: statistics.median(s["ms"]) for s in summaries}
    if plot is not None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, (left, right) = plt.subplots(1, 2, figsize=(9, 3.5))
        ns = [s["n"] for s in summaries]
        left.loglog(ns, [statistics.median(s["ms"]) for s in summaries], "o-", label="median")
        left.loglog(ns, [_p95(s["ms"]) for s in summaries], "s--", label="95th percentile")
        left.set_xlabel("modules")
        left.set_ylabel("planning time [ms]")
        left.legend()
        with_ref = [s for s in summaries if s["diff"]]
        right.plot([s["n"] for s in with_ref], [statistics.mean(s["diff"]) for s in with_ref],
                   "o-", label="mean")
        right.plot([s["n"] for s in with_ref], [max(s["diff"]) for s in with_ref], "s--",
                   label="max")
        right.set_xlabel("modules")
        right.set_ylabel("pairs over the proven optimum")
        right.set_ylim(-0.05, 1.5)
        right.legend()
        fig.suptitle(f"MMRP mcs-hybrid planner (seed {seed})")
        fig.tight_layout()
        fig.savefig(plot)
        console.print(f"plot written to {plot}")
    problems = sum(s["problems"] for s in summaries)
    print(f"paper_cross_probe_pairs={paper} "
          f"optimal_rate={sum(d == 0 for d in small) / max(len(small), 1):.4f} "
          f"max_excess={max(small, default=0)} checker_problems={problems} "
          f"median_ms_500={medians.get(500, float('nan')):.1f} "
          f"median_ms_1000={medians.get(1000, float('nan')):.1f}")


if __name__ == "__main__":
    main()
