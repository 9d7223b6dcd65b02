"""MMRP random reconfigurations in PyBullet at 30 and 100 modules (issue 29, item 2).

Each run is ``platform run --robot mmrp --from START --to GOAL`` in its own process,
as a user runs it: success is the platform's verdict on the simulator's ground truth
(goal topology and goal shape within MMRP's ``shape_tolerance``); a failure shows the
run's own one-line reason. Pairs are seeded random legal planar trees
(:func:`msrr.plugins.mmrp.random_trees.random_tree`), drawn in order from one
generator.

Usage: ``python benchmarks/mmrp_sim.py [--seed N] [--small N] [--large N]
[--sizes 30,100] [--timeout S] [--only 30:3,100:1] [--out DIR]``: ``--small`` pairs of
the first size, ``--large`` of the second; ``--only`` reruns chosen pairs (the same
pairs as in a full run), ``--out`` keeps every pair's files, run folder and the run's
output as it is written (``30-3.log``). Prints the seed, a line as each run ends, one
row per run (docks, undocks, simulated and wall time, real-time factor, reason) and
per size the success rate and totals; the last line is ``runs=... succeeded=...
failed=... sim_s=... wall_s=... rtf=...``. Exits 1 if a run failed.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import click
import numpy as np

from msrr.core.console import console, table
from msrr.core.io import save_configuration
from msrr.plugins.mmrp.random_trees import random_tree

_PLATFORM = "from msrr.core.app.cli import main; main()"
"""``platform`` in this interpreter."""


def _run(n: int, k: int, rng: np.random.Generator, folder: Path, timeout: float) -> dict:
    start, goal = random_tree(n, rng, name=f"start{k}"), random_tree(n, rng, name=f"goal{k}")
    a, b, out = folder / f"{n}-{k}-start.json", folder / f"{n}-{k}-goal.json", folder / f"{n}-{k}"
    save_configuration(start, a)
    save_configuration(goal, b)
    began = time.perf_counter()
    log = folder / f"{n}-{k}.log"
    with log.open("w") as output:  # written as the run goes: a long run shows its progress
        try:
            subprocess.run([sys.executable, "-c", _PLATFORM, "run", "--robot", "mmrp",
                            "--from", str(a), "--to", str(b), "--out", str(out), "--no-log",
                            "--force"], stdout=output, stderr=subprocess.STDOUT, text=True,
                           timeout=timeout)
            last = (log.read_text().strip().splitlines() or [""])[-1]
        except subprocess.TimeoutExpired:
            last = f"benchmark timeout after {timeout:g} s of wall time"
    wall = time.perf_counter() - began
    summary = out / "summary.json"
    data = json.loads(summary.read_text()) if summary.exists() else {}
    return {"n": n, "k": k, "success": bool(data.get("success")), "wall": wall,
            "sim": float(data.get("sim_time_s", float("nan"))),
            "docks": data.get("docks", "-"), "planned": data.get("planned_docks", "-"),
            "undocks": data.get("undocks", "-"), "actions": data.get("actions_total", "-"),
            "reason": "" if data.get("success") else (data.get("reason") or last)}


@click.command()
@click.option("--seed", default=29, show_default=True, help="Seed of the random pairs.")
@click.option("--small", default=20, show_default=True, help="Pairs of the first size.")
@click.option("--large", default=5, show_default=True, help="Pairs of the second size.")
@click.option("--sizes", default="30,100", show_default=True,
              help="The two sizes, comma-separated.")
@click.option("--timeout", default=3600.0, show_default=True,
              help="Wall time one run may take [s].")
@click.option("--only", default="", help="Run only these pairs, e.g. '30:3,30:7,100:1' "
              "(the others are still drawn, so each pair is the same as in a full run).")
@click.option("--out", "out", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Keep every pair's start, goal and run folder here (default: deleted).")
def main(seed: int, small: int, large: int, sizes: str, timeout: float, only: str,
         out: Path | None) -> None:
    console.print(f"seed={seed}")
    rng = np.random.default_rng(seed)
    first, second = (int(n) for n in sizes.split(","))
    chosen = {tuple(int(v) for v in item.split(":")) for item in only.split(",") if item}
    rows, results = [], []
    with tempfile.TemporaryDirectory() as tmp:
        folder = out or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        for n, count in ((first, small), (second, large)):
            for k in range(count):
                if chosen and (n, k) not in chosen:
                    random_tree(n, rng), random_tree(n, rng)  # the same draws as a full run
                    continue
                r = _run(n, k, rng, folder, timeout)
                results.append(r)
                rows.append([n, k, "success" if r["success"] else "FAILED", r["actions"],
                             f"{r['docks']}/{r['planned']}", r["undocks"], f"{r['sim']:.0f}",
                             f"{r['wall']:.0f}", f"{r['sim'] / r['wall']:.2f}", r["reason"]])
                console.print(f"  {n} modules, pair {k}: {rows[-1][2]}, {r['sim']:.0f} s "
                              f"simulated in {r['wall']:.0f} s {r['reason']}", style="dim")
                sys.stdout.flush()  # progress lines reach a log as each run ends
    console.print(table("MMRP random reconfigurations in PyBullet", [
        "modules", "pair", "result", "actions", "docks", "undocks", "sim [s]", "wall [s]",
        "real-time factor", "reason"], rows))
    per_size = []
    for n in (first, second):
        mine = [r for r in results if r["n"] == n]
        if mine:
            sim, wall = sum(r["sim"] for r in mine), sum(r["wall"] for r in mine)
            per_size.append([n, len(mine), sum(r["success"] for r in mine),
                             f"{sum(r['success'] for r in mine) / len(mine):.2f}",
                             f"{sim:.0f}", f"{wall:.0f}", f"{sim / wall:.2f}"])
    console.print(table("Per size", ["modules", "runs", "succeeded", "success rate",
                                     "sim [s]", "wall [s]", "real-time factor"], per_size))
    ok = sum(r["success"] for r in results)
    sim, wall = sum(r["sim"] for r in results), sum(r["wall"] for r in results)
    print(f"runs={len(results)} succeeded={ok} failed={len(results) - ok} sim_s={sim:.0f} "
          f"wall_s={wall:.0f} rtf={sim / max(wall, 1e-9):.2f}")
    if ok < len(results):
        raise SystemExit(1)


if __name__ == "__main__":
    main()
