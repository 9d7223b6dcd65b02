"""Benchmark of the MMRP hybrid planner (Wei et al. 2023) against the exact optimum.

* the paper's cross -> probe case (Table 4: 3 dock/undock pairs);
* seeded random pairs of legal planar MMRP trees of 5-9 modules: the plan's pair count
  against the exact optimum (``msrr.plugins.mmrp.optimum``);
* 20, 50 and 100 modules: planning time.

Usage: ``python benchmarks/mmrp_planner.py [--seed N] [--pairs N] [--runs N] [--plot FILE]``.
The last line is ``paper_cross_probe_pairs=... optimal_rate=... mean_excess=... plan_ms_100=...``.
"""

from __future__ import annotations

import statistics
import time
from pathlib import Path

import click
import numpy as np

from msrr.core.cli import console, table
from msrr.core.io import load_configuration
from msrr.plugins.mmrp.optimum import optimum
from msrr.plugins.mmrp.planner import plan_hybrid
from msrr.plugins.mmrp.random_trees import random_tree

CONFIGS = Path(__file__).resolve().parents[1] / "plugins" / "mmrp" / "configs"
SMALL = (5, 6, 7, 8, 9)
LARGE = (20, 50, 100)


def _timed(start, goal, seed: int) -> tuple[int, float, bool]:
    began = time.perf_counter()
    result = plan_hybrid(start, goal, seed=seed)
    return result.pairs, (time.perf_counter() - began) * 1e3, result.field.stalled


@click.command()
@click.option("--seed", default=2023, show_default=True, help="Seed of the random pairs.")
@click.option("--pairs", "n_pairs", default=60, show_default=True,
              help="Random pairs per size of 5-9 modules.")
@click.option("--runs", default=9, show_default=True, help="Random pairs per large size.")
@click.option("--plot", type=click.Path(path_type=Path), default=None,
              help="Save a plot of pairs and time per size to this file.")
def main(seed: int, n_pairs: int, runs: int, plot: Path | None) -> None:
    console.print(f"seed={seed}")
    rng = np.random.default_rng(seed)
    paper = plan_hybrid(load_configuration(CONFIGS / "cross.json"),
                        load_configuration(CONFIGS / "probe.json")).pairs
    series_t = plan_hybrid(load_configuration(CONFIGS / "series.json"),
                           load_configuration(CONFIGS / "t.json")).pairs
    rows, excess, hits, sizes, times = [], [], 0, [], []
    for n in SMALL:
        found, best, ms, stalls = [], [], [], 0
        for _ in range(n_pairs):
            start, goal = random_tree(n, rng), random_tree(n, rng)
            pairs, elapsed, stalled = _timed(start, goal, int(rng.integers(1 << 31)))
            found.append(pairs)
            best.append(optimum(start, goal).pairs)
            ms.append(elapsed)
            stalls += stalled
        diff = [a - b for a, b in zip(found, best, strict=True)]
        if min(diff) < 0:
            raise SystemExit(f"plan below the exact optimum at {n} modules: a solver bug")
        hits += sum(d == 0 for d in diff)
        excess += diff
        sizes.append(n)
        times.append(statistics.median(ms))
        rows.append([n, n_pairs, f"{statistics.mean(found):.2f}", f"{statistics.mean(best):.2f}",
                     f"{sum(d == 0 for d in diff) / n_pairs:.3f}", f"{statistics.mean(diff):.3f}",
                     stalls, f"{statistics.median(ms):.1f}"])
    medians = {}
    for n in LARGE:
        found, ms, stalls = [], [], 0
        for _ in range(runs):
            start, goal = random_tree(n, rng), random_tree(n, rng)
            pairs, elapsed, stalled = _timed(start, goal, int(rng.integers(1 << 31)))
            found.append(pairs)
            ms.append(elapsed)
            stalls += stalled
        medians[n] = statistics.median(ms)
        sizes.append(n)
        times.append(medians[n])
        rows.append([n, runs, f"{statistics.mean(found):.2f}", "-", "-", "-", stalls,
                     f"{medians[n]:.1f}"])
    console.print(table("MMRP hybrid planner vs exact optimum",
                        ["modules", "pairs run", "mean plan pairs", "mean optimum pairs",
                         "optimal rate", "mean excess", "field stalls", "median plan ms"], rows))
    console.print(f"series->T pairs={series_t} (paper Fig. 18: 2)")
    if plot is not None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(5, 3.5))
        ax.loglog(sizes, times, "o-")
        ax.set_xlabel("modules")
        ax.set_ylabel("median planning time [ms]")
        ax.set_title("MMRP mcs-hybrid planner")
        fig.tight_layout()
        fig.savefig(plot)
        console.print(f"plot written to {plot}")
    rate = hits / len(excess)
    print(f"paper_cross_probe_pairs={paper} optimal_rate={rate:.3f} "
          f"mean_excess={statistics.mean(excess):.3f} plan_ms_100={medians[100]:.1f}")


if __name__ == "__main__":
    main()
