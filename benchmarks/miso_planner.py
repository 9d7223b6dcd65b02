"""MISO connection planning: heuristic optimality against the exact search, and its time.

Instances are pairs of random MISO trees (:func:`msrr.core.freeform.miso.random_miso_tree`,
generated like Luo and Lam's: modules join a random placed module with in-degree below
6, at most ``b`` modules branch). Two parts:

1. **Optimality**, ``n = 5..10``: ``--instances`` pairs per size with ``b = 3``; the
   heuristic's step count against the exact branch and bound (every exact run proves
   its optimum), and the flows each plan holds (steps that move a leaf to a
   neighbour of its parent, FreeSN section 4.1: a flow is one step like any other;
   both planners prefer flows among orders of equal length). Also the exact search's
   time.
2. **Time**, ``n`` from 5 to 1000 with ``b`` in ``--branching`` (default 3, 10, 50):
   the heuristic's wall time, steps and flows, and ``d``-lower-bound gap (the steps
   beyond one per mismatched module of its own pairing).

The last line is machine-readable::

    optimal_rate=... max_ms_1000=... median_ms_1000=...

Instances are drawn in order from one generator, then solved as batch tasks
(:mod:`msrr.core.app.batch`, ``--workers N`` / ``--cluster ADDRESS``; default one worker so
times compare with earlier runs): the step counts are the same for the same seed.

Usage: ``python benchmarks/miso_planner.py --seed 0 --plot docs/images/miso-planner.png``
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass

import numpy as np
from rich.console import Console
from rich.table import Table

from msrr.core.app.batch import exit_on_interrupt, run_batch
from msrr.core.console import exit_unless_installed
from msrr.core.freeform.miso import (
    MisoProblem,
    count_flows,
    random_miso_tree,
    solve_exact,
    solve_heuristic,
)

SMALL = tuple(range(5, 11))
LARGE = (5, 10, 20, 50, 100, 200, 500, 1000)


@dataclass
class Compared:
    n: int
    heuristic: int
    exact: int
    proved: bool
    exact_ms: float
    heuristic_flows: int
    exact_flows: int


@dataclass
class Timed:
    n: int
    branching: int
    ms: float
    steps: int
    lower_bound: int
    flows: int


def instance(n: int, b: int, rng: np.random.Generator) -> MisoProblem:
    return MisoProblem.from_parents(random_miso_tree(n, rng, max_branching=b),
                                    random_miso_tree(n, rng, max_branching=b))


def compare(task: tuple[int, MisoProblem]) -> Compared:
    """Heuristic against exact on one instance (a batch task)."""
    n, problem = task
    heuristic = solve_heuristic(problem)
    t0 = time.perf_counter()
    exact = solve_exact(problem)
    ms = 1e3 * (time.perf_counter() - t0)
    return Compared(n, heuristic.cost, exact.cost, exact.optimal, ms,
                    count_flows(problem.start, heuristic.steps),
                    count_flows(problem.start, exact.steps))


def timed(task: tuple[int, int, MisoProblem]) -> Timed:
    """The heuristic's time on one instance (a batch task)."""
    n, b, problem = task
    t0 = time.perf_counter()
    solution = solve_heuristic(problem)
    ms = 1e3 * (time.perf_counter() - t0)
    return Timed(n, b, ms, solution.cost, solution.lower_bound,
                 count_flows(problem.start, solution.steps))


def plot(compared: list[Compared], runs: list[Timed], path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4))
    rates = [np.mean([c.heuristic == c.exact for c in compared if c.n == n]) for n in SMALL]
    left.bar([str(n) for n in SMALL], rates, color="tab:blue")
    left.axhline(0.95, color="tab:red", linestyle="--", label="target 95 %")
    left.set_ylim(0.0, 1.05)
    left.set_xlabel("modules")
    left.set_ylabel("heuristic optimal (fraction)")
    left.set_title("Heuristic vs exact branch and bound")
    left.legend(loc="lower left")
    for b in sorted({r.branching for r in runs}):
        ms = [float(np.median([r.ms for r in runs if r.n == n and r.branching == b]))
              for n in LARGE]
        right.loglog(LARGE, ms, "o-", label=f"b <= {b}")
    right.axhline(10_000, color="tab:red", linestyle="--", label="10 s")
    right.set_xlabel("modules")
    right.set_ylabel("heuristic time [ms] (median)")
    right.set_title("Heuristic planning time")
    right.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    print(f"plot written to {path}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--instances", type=int, default=100,
                        help="instances per size for the optimality part (default 100)")
    parser.add_argument("--repeats", type=int, default=3,
                        help="instances per size and bound for the time part (default 3)")
    parser.add_argument("--branching", type=int, nargs="+", default=[3, 10, 50],
                        help="bounds on branching modules for the time part")
    parser.add_argument("--plot", default=None, help="save a plot to FILE")
    parser.add_argument("--workers", type=int, default=1,
                        help="worker processes (1: here; 0: one per core)")
    parser.add_argument("--cluster", default=None, metavar="ADDRESS",
                        help="run on Ray: auto, ray://HOST:PORT or local")
    args = parser.parse_args()
    if args.plot:  # before the work: a missing matplotlib is one line
        exit_unless_installed("matplotlib", "plot", "--plot")
    console = Console(highlight=False)
    console.print(f"seed={args.seed} instances={args.instances} per size (n=5..10, b<=3), "
                  f"repeats={args.repeats} per size and bound {args.branching}")
    rng = np.random.default_rng(args.seed)

    # instances drawn here in order from one generator; solved as batch tasks
    small = [(n, instance(n, 3, rng)) for n in SMALL for _ in range(args.instances)]
    large = [(n, b, instance(n, b, rng)) for b in args.branching for n in LARGE
             for _ in range(args.repeats)]
    batch = {"workers": args.workers, "cluster": args.cluster}
    with exit_on_interrupt():
        compared = run_batch(compare, small, label="exact comparisons", **batch).values()
    table = Table(title="Heuristic vs exact (fewest steps), random MISO trees, b <= 3")
    for column in ("n", "instances", "optimal", "mean extra steps", "mean exact steps",
                   "flows heur.", "flows exact", "proved", "exact median ms", "exact max ms"):
        table.add_column(column, justify="right")
    for n in SMALL:
        rows = [c for c in compared if c.n == n]
        table.add_row(str(n), str(len(rows)),
                      f"{np.mean([c.heuristic == c.exact for c in rows]):.3f}",
                      f"{np.mean([c.heuristic - c.exact for c in rows]):.3f}",
                      f"{np.mean([c.exact for c in rows]):.2f}",
                      f"{np.mean([c.heuristic_flows for c in rows]):.2f}",
                      f"{np.mean([c.exact_flows for c in rows]):.2f}",
                      f"{np.mean([c.proved for c in rows]):.2f}",
                      f"{np.median([c.exact_ms for c in rows]):.1f}",
                      f"{max(c.exact_ms for c in rows):.1f}")
    console.print(table)

    with exit_on_interrupt():
        runs = run_batch(timed, large, label="timed instances", **batch).values()
    table = Table(title="Heuristic time, random MISO trees")
    for column in ("n", "b <=", "median ms", "max ms", "mean steps", "mean flows",
                   "steps above d"):
        table.add_column(column, justify="right")
    for b in args.branching:
        for n in LARGE:
            rows = [r for r in runs if r.n == n and r.branching == b]
            table.add_row(str(n), str(b), f"{np.median([r.ms for r in rows]):.1f}",
                          f"{max(r.ms for r in rows):.1f}",
                          f"{np.mean([r.steps for r in rows]):.1f}",
                          f"{np.mean([r.flows for r in rows]):.1f}",
                          f"{np.mean([r.steps - r.lower_bound for r in rows]):.2f}")
    console.print(table)
    if args.plot:
        plot(compared, runs, args.plot)
    big = [r.ms for r in runs if r.n == LARGE[-1]]
    rate = float(np.mean([c.heuristic == c.exact for c in compared]))
    print(f"optimal_rate={rate:.3f} max_ms_1000={max(big):.1f} "
          f"median_ms_1000={float(np.median(big)):.1f}")


if __name__ == "__main__":
    main()
