"""Full-body IK time against tree size and angular distance (FreeSN paper, section 7.1, Fig. 17).

For every size from 2 to 30 edges, ``--pairs`` random tree-shaped FreeSN
configurations (struts between node modules, random unit vectors), each with the
default kinematic tree (fixed root at the centre, opposite-steering joints). The
target of a pair is the forward kinematics of the start at a random ``sigma``, scaled
so that the RMS angle between corresponding vectors is 24 degrees, seen from a
horizontal frame turned by a random yaw. :func:`~msrr.core.kinematics.solve_ik` runs
with its default options (tolerance 0.5 deg, eq. 8 yaw start, L-BFGS-B with the
analytic gradient, sampled restarts); a pair counts as solved when the RMS angle
residual is below 1 degree.

Also measured, at 30 edges: the same solver with scipy's finite-difference gradient on
the first ``--fd-pairs`` pairs, and the time against the angular distance of the pair
(Fig. 17, right). The last line is machine-readable::

    exponent=... fd_speedup_30=... success=... median_ms_30=...

``exponent`` is the slope of log(median time) against log(edges).

Usage: ``python benchmarks/ik_scaling.py --pairs 100 --seed 0 --plot fig17.png``
(``--clock cpu`` times each solve by this process's CPU time, for a shared machine).
Pairs are drawn in order from one generator, then solved as batch tasks
(:mod:`msrr.core.app.batch`, ``--workers N`` / ``--cluster ADDRESS``; default one worker so
times compare with earlier runs): success, iterations and restarts are the same for the
same seed whichever backend solves them.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass

import numpy as np
from rich.console import Console
from rich.table import Table

from msrr.core import Configuration, plugins
from msrr.core.alignment import angles_between, rot_z
from msrr.core.app.batch import exit_on_interrupt, run_batch
from msrr.core.console import exit_unless_installed
from msrr.core.kinematics import (
    IKOptions,
    KinematicTree,
    default_tree,
    forward,
    solve_ik,
    tree_vectors,
)
from msrr.core.random_configurations import random_configuration

NEAR_RMS_DEG = 24.0
SOLVED_DEG = 1.0
DISTANCES_DEG = (6.0, 12.0, 24.0, 36.0, 48.0, 60.0)


@dataclass
class Pair:
    tree: KinematicTree
    start: Configuration
    target: Configuration
    rms_deg: float


@dataclass
class Run:
    edges: int
    ms: float
    solved: bool
    iterations: int
    restarts: int
    rms_deg: float        # residual after the solve
    distance_deg: float   # RMS angle between start and target


def make_pair(n_edges: int, rng: np.random.Generator, rms_deg: float) -> Pair:
    """A random tree with ``n_edges`` struts and a target at RMS angle ``rms_deg``."""
    robot = plugins.resolve("freesn")
    start = random_configuration(robot.spec, robot.rules, n_edges + 1, rng)
    tree = default_tree(start, robot.default_joint_mode())
    direction = rng.normal(size=tree.dim)
    z0 = tree_vectors(tree, start)[0]

    def rms(scale: float) -> float:
        z = forward(tree, start, scale * direction).Z
        return float(np.sqrt(np.mean(angles_between(z, z0) ** 2)))

    lo, hi = 0.0, 1.0
    while rms(hi) < np.deg2rad(rms_deg) and hi < 64:
        hi *= 2.0
    for _ in range(40):  # bisection on the scale of sigma
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if rms(mid) < np.deg2rad(rms_deg) else (lo, mid)
    moved = forward(tree, start, lo * direction)
    turn = rot_z(rng.uniform(-np.pi, np.pi))
    target = start.with_vectors(z={e: turn @ v for e, v in moved.z.items()},
                                x={e: turn @ v for e, v in moved.x.items()})
    return Pair(tree, start, target, float(np.rad2deg(rms(lo))))


CLOCKS = {"wall": time.perf_counter, "cpu": time.process_time}


def solve(pair: Pair, seed: int, gradient: str = "analytic", clock: str = "wall") -> Run:
    options = IKOptions(seed=seed, gradient=gradient)  # type: ignore[arg-type]
    tick = CLOCKS[clock]
    started = tick()
    sol = solve_ik(pair.tree, pair.start, pair.target, options)
    ms = (tick() - started) * 1e3
    rms_deg = float(np.rad2deg(sol.rms_angle))
    return Run(len(pair.tree.edges), ms, rms_deg < SOLVED_DEG, sol.iterations, sol.restarts,
               rms_deg, pair.rms_deg)


_warmed = False


def solve_task(task: tuple[Pair, int, str, str]) -> Run:
    """:func:`solve` as a batch task ``(pair, seed, gradient, clock)``; the first call in a
    process solves once unmeasured (thread pools, imports)."""
    global _warmed
    if not _warmed:
        solve(*task)
        _warmed = True
    return solve(*task)


def solve_all(tasks: list[tuple[Pair, int, str, str]], batch: dict[str, object],
              label: str) -> list[Run]:
    """Every task in order, on the backend ``batch`` selects (``workers``, ``cluster``)."""
    with exit_on_interrupt():
        return run_batch(solve_task, tasks, label=label, **batch).values()  # type: ignore[arg-type]


def fit_exponent(edges: list[int], medians: list[float]) -> float:
    """Slope of log(median time) against log(edges), least squares."""
    return float(np.polyfit(np.log(edges), np.log(medians), 1)[0])


def plot(by_size: dict[int, list[Run]], by_distance: dict[float, list[Run]], exponent: float,
         path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4))
    sizes = sorted(by_size)
    medians = [np.median([r.ms for r in by_size[n]]) for n in sizes]
    p95 = [np.percentile([r.ms for r in by_size[n]], 95) for n in sizes]
    left.plot(sizes, medians, "o-", label="median")
    left.plot(sizes, p95, "s--", alpha=0.6, label="95th percentile")
    coef = np.polyfit(np.log(sizes), np.log(medians), 1)
    left.plot(sizes, np.exp(np.polyval(coef, np.log(sizes))), "k:",
              label=f"fit: time ~ edges^{exponent:.2f}")
    left.set_xscale("log")
    left.set_yscale("log")
    ticks = [n for n in (2, 3, 5, 10, 20, 30) if sizes[0] <= n <= sizes[-1]]
    left.set_xticks(ticks, [str(n) for n in ticks])
    top = max(p95)
    yticks = [t for t in (1, 2, 3, 5, 10, 20, 30, 50, 100, 200) if min(medians) / 1.5 <= t <= top * 1.5]
    left.set_yticks(yticks, [str(t) for t in yticks])
    left.minorticks_off()
    left.set_xlabel("edges (struts)")
    left.set_ylabel("IK time [ms]")
    left.set_title(f"near-random pairs, RMS {NEAR_RMS_DEG:.0f} deg")
    left.legend()
    for runs in by_distance.values():
        right.scatter([r.distance_deg for r in runs], [r.ms for r in runs], s=8, alpha=0.4,
                      color="tab:blue")
    right.plot(sorted(by_distance), [np.median([r.ms for r in by_distance[d]])
                                     for d in sorted(by_distance)], "o-", color="tab:red",
               label="median")
    right.set_xlabel("RMS angle between start and target [deg]")
    right.set_ylabel("IK time [ms]")
    right.set_title("30 edges")
    right.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    print(f"plot written to {path}")


def parse_args() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=100, help="pairs per size (default 100)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--plot", default=None, help="save a Fig. 17-style plot to FILE")
    parser.add_argument("--min-edges", type=int, default=2)
    parser.add_argument("--max-edges", type=int, default=30)
    parser.add_argument("--fd-pairs", type=int, default=20,
                        help="30-edge pairs also solved with finite differences (default 20)")
    parser.add_argument("--distance-pairs", type=int, default=25,
                        help="30-edge pairs per angular distance (default 25)")
    parser.add_argument("--clock", choices=sorted(CLOCKS), default="wall",
                        help="time solves by wall clock (default) or by this process's CPU "
                             "time (steadier on a machine shared with other jobs)")
    parser.add_argument("--workers", type=int, default=1,
                        help="worker processes (1: here; 0: one per core)")
    parser.add_argument("--cluster", default=None, metavar="ADDRESS",
                        help="run on Ray: auto, ray://HOST:PORT or local")
    return parser.parse_args()


def run_sizes(args: argparse.Namespace, sizes: list[int], batch: dict[str, object],
              console: Console) -> tuple[dict[int, list[Pair]], dict[int, list[Run]]]:
    """Fig. 17, left: ``--pairs`` near-random pairs per size, solved; prints the table."""
    rng = np.random.default_rng(args.seed)
    # pairs drawn here in order from one generator, solved as batch tasks
    pairs_by_size = {n: [make_pair(n, rng, NEAR_RMS_DEG) for _ in range(args.pairs)]
                     for n in sizes}
    solved = iter(solve_all([(p, args.seed + i, "analytic", args.clock) for n in sizes
                             for i, p in enumerate(pairs_by_size[n])], batch, "pairs"))
    by_size = {n: [next(solved) for _ in pairs_by_size[n]] for n in sizes}
    table = Table(title="Full-body IK, near-random pairs (Fig. 17, left)")
    for column in ("edges", "median ms", "p95 ms", "success", "iterations", "restarts"):
        table.add_column(column, justify="right")
    for n in sizes:
        runs = by_size[n]
        ms = [r.ms for r in runs]
        table.add_row(str(n), f"{np.median(ms):.2f}", f"{np.percentile(ms, 95):.2f}",
                      f"{np.mean([r.solved for r in runs]):.3f}",
                      f"{np.median([r.iterations for r in runs]):.0f}",
                      f"{np.mean([r.restarts for r in runs]):.2f}")
    console.print(table)
    return pairs_by_size, by_size


def run_gradients(pairs: list[Pair], args: argparse.Namespace, batch: dict[str, object],
                  console: Console) -> float:
    """The first ``--fd-pairs`` of ``pairs`` solved with the analytic and the finite-difference
    gradient; prints both and returns the time ratio (finite differences / analytic)."""
    fd_pairs = pairs[: args.fd_pairs]
    both = solve_all([(p, args.seed + i, gradient, args.clock) for gradient in
                      ("analytic", "finite_difference") for i, p in enumerate(fd_pairs)],
                     batch, "gradients")
    analytic, numeric = both[:len(fd_pairs)], both[len(fd_pairs):]
    fd_speedup = sum(r.ms for r in numeric) / sum(r.ms for r in analytic)
    console.print(f"finite differences vs analytic gradient, {args.max_edges} edges, "
                  f"{len(fd_pairs)} pairs: {sum(r.ms for r in numeric) / len(fd_pairs):.1f} ms "
                  f"vs {sum(r.ms for r in analytic) / len(fd_pairs):.2f} ms per solve "
                  f"(solved {np.mean([r.solved for r in numeric]):.2f} vs "
                  f"{np.mean([r.solved for r in analytic]):.2f})")
    return fd_speedup


def run_distances(args: argparse.Namespace, batch: dict[str, object], console: Console
                  ) -> dict[float, list[Run]]:
    """Fig. 17, right: ``--distance-pairs`` pairs per angular distance at the largest size,
    solved; prints the table."""
    by_distance: dict[float, list[Run]] = {}
    distance_rng = np.random.default_rng(args.seed + 2)
    table = Table(title=f"Time against angular distance, {args.max_edges} edges "
                        "(Fig. 17, right)")
    for column in ("RMS deg", "median ms", "p95 ms", "success", "iterations"):
        table.add_column(column, justify="right")
    tasks = [(make_pair(args.max_edges, distance_rng, distance), args.seed + i, "analytic",
              args.clock) for distance in DISTANCES_DEG for i in range(args.distance_pairs)]
    solved = iter(solve_all(tasks, batch, "distances"))
    for distance in DISTANCES_DEG:
        runs = [next(solved) for _ in range(args.distance_pairs)]
        by_distance[distance] = runs
        ms = [r.ms for r in runs]
        table.add_row(f"{distance:.0f}", f"{np.median(ms):.2f}",
                      f"{np.percentile(ms, 95):.2f}", f"{np.mean([r.solved for r in runs]):.3f}",
                      f"{np.median([r.iterations for r in runs]):.0f}")
    console.print(table)
    return by_distance


def main() -> None:
    args = parse_args()
    if args.plot:  # before the work: a missing matplotlib is one line
        exit_unless_installed("matplotlib", "plot", "--plot")
    console = Console(highlight=False)
    console.print(f"seed={args.seed} pairs={args.pairs} per size, edges "
                  f"{args.min_edges}..{args.max_edges}, target RMS {NEAR_RMS_DEG:.0f} deg, "
                  f"solved below {SOLVED_DEG:.0f} deg, {args.clock} clock")
    warm = make_pair(5, np.random.default_rng(args.seed + 1), NEAR_RMS_DEG)
    solve(warm, 0)  # first-call set-up (thread pools, imports) is not measured

    batch = {"workers": args.workers, "cluster": args.cluster}
    sizes = list(range(args.min_edges, args.max_edges + 1))
    pairs_by_size, by_size = run_sizes(args, sizes, batch, console)
    fd_speedup = run_gradients(pairs_by_size[args.max_edges], args, batch, console)
    by_distance = run_distances(args, batch, console)

    medians = [float(np.median([r.ms for r in by_size[n]])) for n in sizes]
    exponent = fit_exponent(sizes, medians)
    success = float(np.mean([r.solved for n in sizes for r in by_size[n]]))
    if args.plot:
        plot(by_size, by_distance, exponent, args.plot)
    print(f"exponent={exponent:.3f} fd_speedup_30={fd_speedup:.1f} success={success:.3f} "
          f"median_ms_30={medians[-1]:.2f}")


if __name__ == "__main__":
    main()
