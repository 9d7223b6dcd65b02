"""Benchmark of the MMRP hybrid planner (Wei et al. 2023) at every size (issue 17).

Per size, on seeded random pairs of legal planar MMRP trees:

* 5-9 modules: plan pairs against the exhaustive optimum (``optimum.optimum``);
* 10-20 modules: against the certified optimum of the integer program
  (``exact.certified_optimum``, HiGHS, 60 s limit each);
* 50-1,000 modules: pairs and time only;
* every plan replayed by the grid checker (``check.check_plan``): collisions and
  invalid steps must be 0;
* ``--sim N``: N random 30-module reconfigurations run in the PyBullet simulation
  (``platform run``), success rate and simulated time.

Usage: ``python benchmarks/mmrp_planner.py [--seed N] [--pairs N] [--mid N] [--runs N]
[--sizes 50,100,...] [--sim N] [--plot FILE] [--workers N] [--cluster ADDRESS]``. The
pairs are drawn in order from one generator, then planned as batch tasks
(:mod:`msrr.core.app.batch`; ``--workers 0``, the default, uses every core): the table's
counts are the same for the same seed whichever backend runs them. The last line is
``paper_cross_probe_pairs=... optimal_rate=... max_excess=... checker_problems=...
median_ms_500=... median_ms_1000=...``.
"""

from __future__ import annotations

import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import click
import numpy as np

from msrr.core.app.batch import batch_options, exit_on_interrupt, run_batch
from msrr.core.configuration import Configuration
from msrr.core.console import console, exit_unless_installed, table
from msrr.core.io import load_configuration, save_configuration
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
    began = time.perf_counter()
    result = plan_hybrid(start, goal, seed=seed)
    out: dict[str, Any] = {"ms": (time.perf_counter() - began) * 1e3, "pairs": result.pairs,
                           "problems": len(check_plan(result.plan)),
                           "stalls": result.field.stalled,
                           "cuts": int(result.plan.stats["cut_for_motion"]),
                           "parks": int(result.plan.stats["parking_moves"])}
    if reference == "exhaustive":
        out["best"] = optimum(start, goal).pairs
    elif reference == "milp":
        exact = certified_optimum(start, goal, time_limit=60.0)
        out.update(best=exact.bound, uncertified=not exact.certified, ref_s=exact.seconds)
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
    row = [n, count, f"{statistics.mean(found):.2f}",
           f"{statistics.mean(best):.2f}" if best else "-",
           f"{sum(d == 0 for d in diff) / len(diff):.3f}" if diff else "-",
           f"{statistics.mean(diff):.3f} / {max(diff)}" if diff else "-",
           problems, stalls, cuts, parks, f"{statistics.median(ms):.1f}", f"{_p95(ms):.1f}",
           (f"{uncertified} / {max(ref_s):.1f}" if reference == "milp" else "-")]
    return row, summary


def _simulate(count: int, rng: np.random.Generator) -> list[list]:
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(count):
            start, goal = random_tree(30, rng, name="start"), random_tree(30, rng, name="goal")
            a, b = Path(tmp) / f"start{k}.json", Path(tmp) / f"goal{k}.json"
            save_configuration(start, a)
            save_configuration(goal, b)
            out = Path(tmp) / f"run{k}"
            began = time.perf_counter()
            done = subprocess.run([sys.executable, "-c", "from msrr.core.app.cli import main; main()",
                                   "run", "--robot",
                                   "mmrp", "--from", str(a), "--to", str(b), "--out", str(out),
                                   "--no-log"], capture_output=True, text=True)
            wall = time.perf_counter() - began
            summary = out / "summary.json"
            data = json.loads(summary.read_text()) if summary.exists() else {}
            rows.append([k, done.returncode == 0 and bool(data.get("success")),
                         data.get("docks", "-"), data.get("undocks", "-"),
                         f"{data.get('sim_time_s', float('nan')):.1f}", f"{wall:.1f}"])
    return rows


@click.command()
@click.option("--seed", default=2023, show_default=True, help="Seed of the random pairs.")
@click.option("--pairs", "n_pairs", default=120, show_default=True,
              help="Random pairs per size of 5-9 modules (exhaustive optimum).")
@click.option("--mid", "n_mid", default=5, show_default=True,
              help="Random pairs per size of 10-20 modules (certified optimum).")
@click.option("--runs", default=9, show_default=True, help="Random pairs per large size.")
@click.option("--sizes", default=",".join(map(str, LARGE)), show_default=True,
              help="Large sizes, comma-separated.")
@click.option("--sim", "n_sim", default=0, show_default=True,
              help="30-module runs in the PyBullet simulation.")
@click.option("--plot", type=click.Path(path_type=Path), default=None,
              help="Save a plot of time and optimality gap per size to this file.")
@batch_options
def main(seed: int, n_pairs: int, n_mid: int, runs: int, sizes: str, n_sim: int,
         plot: Path | None, workers: int, cluster: str | None) -> None:
    if plot is not None:  # before the work: a missing matplotlib is one line
        exit_unless_installed("matplotlib", "plot", "--plot")
    console.print(f"seed={seed}")
    rng = np.random.default_rng(seed)
    paper = plan_hybrid(load_configuration(CONFIGS / "cross.json"),
                        load_configuration(CONFIGS / "probe.json")).pairs
    rows, summaries = [], []
    plan = [(n, n_pairs, "exhaustive") for n in SMALL] + \
           [(n, n_mid, "milp") for n in MID if n_mid] + \
           [(int(n), runs, None) for n in sizes.split(",") if n]
    for n, count, reference in plan:
        row, summary = _run_size(n, count, rng, reference,
                                 {"workers": workers, "cluster": cluster})
        rows.append(row)
        summaries.append(summary)
        console.print(f"  {n} modules done", style="dim")
    console.print(table(
        "MMRP mcs-hybrid planner vs the proven optimum",
        ["modules", "pairs run", "mean plan pairs", "mean optimum pairs", "optimal rate",
         "gap mean / max", "checker problems", "field fallback", "cuts", "parking legs",
         "median ms", "p95 ms", "uncertified / max MILP s"], rows))
    if n_sim:
        sim_rows = _simulate(n_sim, rng)
        console.print(table("30-module random reconfigurations in PyBullet",
                            ["run", "success", "docks", "undocks", "sim time [s]", "wall [s]"],
                            sim_rows))
        console.print(f"sim success rate {sum(r[1] for r in sim_rows) / len(sim_rows):.2f}")
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
