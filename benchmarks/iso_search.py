"""Isomorphism tree search versus brute-force sorting (FreeSN paper, section 7.1, Fig. 16).

Ten topologies of five node modules and sixteen struts (``benchmarks/fig16.py``,
48 to 57 600 isomorphisms). For each, random configuration pairs of three kinds:

* isomorphic -- the reference is the system under a random yaw and a random relabelling
  of nodes and struts (some struts reversed);
* near-random -- the same, with every vector tilted at random (RMS angle about 24 deg);
* full-random -- independent uniformly random vectors, then relabelled.

Times the tree search to its first (minimum-distance) mapping and the brute force
(enumerate every isomorphism, compute each distance with the same ``vectorMatch``, sort).
``--pairs N`` pairs of each kind are spread round-robin over the ten topologies. The
brute force of full-random pairs is skipped above ``--bf-max`` isomorphisms (it only
feeds the table and plot). The last line is machine-readable::

    exact=... exact_near=... speedup_57600=... median_ms_57600=...

The pairs are drawn first, in order, from one generator; then each is timed as one batch
task (:mod:`msrr.core.app.batch`): ``--workers N`` / ``--cluster ADDRESS`` time several pairs
at once and print the same table columns (timings vary run to run anyway; ``exact`` and
``rms deg`` are the same for the same seed). Default: one worker, so timings are
comparable to the published ones.

Usage: ``python benchmarks/iso_search.py --pairs 50 --seed 0 --plot fig16.png``
"""

from __future__ import annotations

import argparse
import statistics
import time
from dataclasses import dataclass

import numpy as np
from fig16 import FIG16_TOPOLOGIES, TopologySpec

from msrr.core.alignment import rot_z
from msrr.core.app.batch import exit_on_interrupt, run_batch
from msrr.core.configuration import Configuration
from msrr.core.console import exit_unless_installed
from msrr.core.matching import brute_force_isomorphisms, iso_search

KINDS = ("isomorphic", "near-random", "full-random")
NEAR_RMS = np.deg2rad(24.0)
TOLERANCE = 1e-9


@dataclass
class Result:
    topology: str
    isomorphisms: int
    kind: str
    tree_ms: float
    bf_ms: float | None
    exact: bool | None
    rms_deg: float


def tilted(z: np.ndarray, rng: np.random.Generator, rms: float) -> np.ndarray:
    """``z`` tilted in a random tangent direction; angles have RMS ``rms`` [rad] on average."""
    tangent = rng.normal(size=3) * rms / np.sqrt(2.0)
    tangent -= tangent.dot(z) * z
    angle = np.linalg.norm(tangent)
    if angle < 1e-12:
        return z
    return np.cos(angle) * z + np.sin(angle) * tangent / angle


def make_pair(spec: TopologySpec, kind: str, rng: np.random.Generator
              ) -> tuple[Configuration, Configuration]:
    """A (system, reference) pair of ``kind`` on ``spec``."""
    system = spec.configuration(rng)
    if kind == "full-random":
        vectors = {e.id: v.z for e, v in zip(system.edges(), spec.configuration(rng).edges(),
                                             strict=True)}
    elif kind == "near-random":
        vectors = {e.id: tilted(e.z, rng, NEAR_RMS) for e in system.edges()}
    else:
        vectors = {e.id: e.z for e in system.edges()}
    rotation = rot_z(rng.uniform(-np.pi, np.pi))
    node_names = {v: f"M{i}" for v, i in zip(system.vertices(),
                                           rng.permutation(len(system)), strict=True)}
    edge_names = {e.id: f"E{i}" for e, i in zip(system.edges(),
                                              rng.permutation(len(system.edges())), strict=True)}
    reference = Configuration(system.robot, name=f"{spec.name}-{kind}")
    for v in system.vertices():
        reference.add_module(node_names[v], system.kind_of(v))
    for e in system.edges():
        z = rotation @ vectors[e.id]
        source, target = node_names[e.source], node_names[e.target]
        if rng.integers(2) and not system.is_virtual(e.target):
            source, target, z = target, source, -z
        reference.connect(source, target, id=edge_names[e.id], kind=e.kind, z=z)
    return system, reference


@dataclass(frozen=True)
class Pair:
    """One timed search: a (system, reference) pair and what the brute force may do."""

    topology: str
    isomorphisms: int
    kind: str
    system: Configuration
    reference: Configuration
    brute_force: bool
    timeout: float


def make_task(spec: TopologySpec, kind: str, rng: np.random.Generator, *, bf_max: int,
              timeout: float) -> Pair:
    """Draw the pair here (one generator, task order), so any backend times the same pairs."""
    system, reference = make_pair(spec, kind, rng)
    brute_force = not (kind == "full-random" and spec.isomorphisms > bf_max)
    return Pair(spec.name, spec.isomorphisms, kind, system, reference, brute_force, timeout)


def run_pair(pair: Pair) -> Result:
    """Time the tree search to its first mapping, and the brute force (a batch task)."""
    system, reference = pair.system, pair.reference
    start = time.perf_counter()
    first = next(iso_search(system, reference, deadline=time.monotonic() + pair.timeout), None)
    tree_ms = 1e3 * (time.perf_counter() - start)
    rms = np.nan if first is None else np.rad2deg(first.rms_angle)
    if not pair.brute_force:
        return Result(pair.topology, pair.isomorphisms, pair.kind, tree_ms, None, None, rms)
    start = time.perf_counter()
    ranked = brute_force_isomorphisms(system, reference)
    bf_ms = 1e3 * (time.perf_counter() - start)
    exact = first is not None and first.distance <= ranked[0].distance + TOLERANCE
    return Result(pair.topology, pair.isomorphisms, pair.kind, tree_ms, bf_ms, exact,
                  float(np.rad2deg(ranked[0].rms_angle)))


def _median(values: list[float]) -> float:
    return statistics.median(values) if values else float("nan")


def table(results: list[Result]) -> None:
    header = (f"{'topology':>8} {'isos':>6} {'kind':>11} {'pairs':>5} {'tree med':>9} "
              f"{'tree max':>9} {'bf med':>9} {'speedup':>8} {'exact':>6} {'rms deg':>7}")
    print(header)
    print("-" * len(header))
    for spec in FIG16_TOPOLOGIES:
        for kind in KINDS:
            rows = [r for r in results if r.topology == spec.name and r.kind == kind]
            if not rows:
                continue
            tree = [r.tree_ms for r in rows]
            bf = [r.bf_ms for r in rows if r.bf_ms is not None]
            speed = [r.bf_ms / r.tree_ms for r in rows if r.bf_ms is not None]
            exact = [r.exact for r in rows if r.exact is not None]
            print(f"{spec.name:>8} {spec.isomorphisms:>6} {kind:>11} {len(rows):>5} "
                  f"{_median(tree):>8.2f}m {max(tree):>8.2f}m "
                  + (f"{_median(bf):>8.0f}m {_median(speed):>8.1f} " if bf else
                     f"{'-':>9} {'-':>8} ")
                  + (f"{np.mean(exact):>6.2f} " if exact else f"{'-':>6} ")
                  + f"{np.nanmedian([r.rms_deg for r in rows]):>7.1f}", flush=True)


def plot(results: list[Result], path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(13, 4), sharey=True)
    for ax, kind in zip(axes, KINDS, strict=True):
        rows = [r for r in results if r.kind == kind]
        ax.scatter([r.isomorphisms for r in rows], [r.tree_ms for r in rows], s=10,
                   label="isomorphism tree search")
        bf = [r for r in rows if r.bf_ms is not None]
        ax.scatter([r.isomorphisms for r in bf], [r.bf_ms for r in bf], s=10, marker="x",
                   label="brute-force sorting")
        ax.set(xscale="log", yscale="log", title=kind, xlabel="isomorphisms")
    axes[0].set_ylabel("time to the minimum-distance mapping [ms]")
    axes[0].legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    print(f"plot written to {path}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=10,
                        help="pairs per kind, spread round-robin over the ten topologies")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--plot", default=None, help="save a Fig. 16-style plot to FILE")
    parser.add_argument("--bf-max", type=int, default=5000,
                        help="largest isomorphism count brute-forced for full-random pairs")
    parser.add_argument("--timeout", type=float, default=30.0,
                        help="time limit of one tree search [s]")
    parser.add_argument("--workers", type=int, default=1,
                        help="worker processes (1: here; 0: one per core); each pair is timed "
                             "in one worker")
    parser.add_argument("--cluster", default=None, metavar="ADDRESS",
                        help="run on Ray: auto, ray://HOST:PORT or local")
    args = parser.parse_args()
    if args.plot:  # before the work: a missing matplotlib is one line
        exit_unless_installed("matplotlib", "plot", "--plot")
    print(f"seed={args.seed} pairs={args.pairs} per kind over {len(FIG16_TOPOLOGIES)} topologies")
    rng = np.random.default_rng(args.seed)
    pairs = [make_task(FIG16_TOPOLOGIES[-1 - i % len(FIG16_TOPOLOGIES)],  # largest first
                       kind, rng, bf_max=args.bf_max, timeout=args.timeout)
             for kind in KINDS for i in range(args.pairs)]
    with exit_on_interrupt():
        results = run_batch(run_pair, pairs, keys=[f"{p.kind}-{p.topology}-{i}"
                                                   for i, p in enumerate(pairs)],
                            workers=args.workers, cluster=args.cluster, label="pairs").values()
    table(results)
    if args.plot:
        plot(results, args.plot)
    iso = [r for r in results if r.kind == "isomorphic"]
    near = [r for r in results if r.kind == "near-random"]
    big = [r for r in iso if r.isomorphisms == 57600]
    print(f"exact={np.mean([r.exact for r in iso]):.3f} "
          f"exact_near={np.mean([r.exact for r in near]):.3f} "
          f"speedup_57600={_median([r.bf_ms / r.tree_ms for r in big]):.1f} "
          f"median_ms_57600={_median([r.tree_ms for r in big]):.2f}")


if __name__ == "__main__":
    main()
