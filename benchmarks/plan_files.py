"""Plan files that scale (issue 29, item 5): size, write time and load+validate time.

A plan file (schema version 2) holds the start whole and then every action's target,
and the goal, as its changes to the one before (:mod:`msrr.core.delta`); version 1
held every target whole. Per robot and size, on seeded random pairs:

* MMRP (``mcs-hybrid``): random planar trees (:func:`msrr.plugins.mmrp.random_trees.random_tree`);
* FreeBOT (``miso``): random MISO trees (:func:`msrr.core.freeform.miso.random_miso_tree`,
  branching unbounded unless ``--branching``) with random unit connection vectors;
* FreeSN (``library``): the largest shipped sub-library's plan (S12N6-1.1 -> S12N6-5.2),
  with its kinematic trees.

Columns: actions; file size [MB]; about the size a version 1 file would have had [MB]
(every target's configuration written whole at its nesting, computed from the
targets, not written; 200 bytes for an action's other fields, trees not counted:
within 20 % of the real files of ``tests/core/plans_v1``); write time (``save_plan``) [s]; load+validate time
(``plugins.load_plan``: parse, rebuild, :func:`msrr.core.plan.check_plan` against the
robot) [s], wall and CPU of this process (the machine is shared: CPU time is what the
load costs). ``--out DIR`` keeps the start, goal and plan files (``platform plan
DIR/mmrp-1000-start.json DIR/mmrp-1000-goal.json --json plan.json`` repeats a row).

``--hash-seeds 11,12`` also runs ``platform plan`` on every row's files as a user would,
once per ``PYTHONHASHSEED``, in its own process (wall time, CPU time and peak memory of
that process; the whole command: loading, planning, printing, writing), and compares
the plan files it writes: byte for byte once the timings (stats ending in ``_ms``) are
set aside (issue 29 item 3: the same plan file under any hash seed).

Usage: ``python benchmarks/plan_files.py [--seed 1] [--sizes 100,500,1000] [--out DIR]
[--hash-seeds 11,12]``. The last line is machine-readable: ``max_mb_1000=...
max_load_s_1000=...`` (and ``hash_seeds_identical=K/N`` rows).
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from msrr.core import plugins
from msrr.core.configuration import Configuration
from msrr.core.console import console, table
from msrr.core.freeform.miso import random_miso_tree
from msrr.core.io import configuration_to_model, save_configuration
from msrr.core.plan import Plan, save_plan
from msrr.core.random_configurations import pointer_configuration

ROOT = Path(__file__).resolve().parents[1]
LIBRARY = ROOT / "plugins/freesn/configs/library"


def pairs(sizes: list[int], seed: int, branching: int | None
          ) -> list[tuple[str, str, int, Configuration, Configuration]]:
    """(robot, planner, modules, start, goal) of every row, drawn in order from one
    generator per robot."""
    from msrr.plugins.mmrp.random_trees import random_tree

    rows = []
    rng = np.random.default_rng(seed)
    for n in sizes:
        rows.append(("mmrp", "mcs-hybrid", n, random_tree(n, rng, name=f"mmrp-{n}-start"),
                     random_tree(n, rng, name=f"mmrp-{n}-goal")))
    rng = np.random.default_rng(seed)
    for n in sizes:
        rows.append(("freebot", "miso", n,
                     *(pointer_configuration("freebot", "freebot",
                                             random_miso_tree(n, rng, max_branching=branching),
                                             rng) for _ in range(2))))
    start, goal = (plugins.load_configuration(LIBRARY / f"S12N6-{g}.json") for g in ("1.1", "5.2"))
    rows.append(("freesn", "library", len(start.modules()), start, goal))
    return rows


def v1_bytes(plan: Plan) -> int:
    """The size of the version 1 file of ``plan`` (indent 2, every target whole): the
    targets' text at their nesting (six more spaces a line), each distinct target
    serialised once, plus the version 2 file's actions without their changes."""
    sizes: dict[int, int] = {}

    def size(config: Configuration, indent: int) -> int:
        if id(config) not in sizes:
            text = json.dumps(configuration_to_model(config).model_dump(
                mode="json", exclude_none=True), indent=2)
            sizes[id(config)] = len(text) + indent * text.count("\n")
        return sizes[id(config)]

    return size(plan.start, 2) + size(plan.goal, 2) + sum(
        size(a.target, 6) + 200 for a in plan.actions)


def measure(robot: str, planner: str, start: Configuration, goal: Configuration, seed: int,
            folder: Path, stem: str) -> dict[str, float]:
    """Plan the pair, write the plan, load and validate it; the row's numbers."""
    began = time.perf_counter()
    plan = plugins.planners.get(robot, planner).plan(start, goal, seed=seed)
    planned = time.perf_counter() - began
    path = folder / f"{stem}.plan.json"
    began = time.perf_counter()
    save_plan(plan, path)
    written = time.perf_counter() - began
    save_configuration(start, folder / f"{stem}-start.json")
    save_configuration(goal, folder / f"{stem}-goal.json")
    began, cpu = time.perf_counter(), time.process_time()
    again = plugins.load_plan(path)
    loaded, loaded_cpu = time.perf_counter() - began, time.process_time() - cpu
    assert len(again.actions) == len(plan.actions)
    return {"actions": len(plan.actions), "mb": path.stat().st_size / 1e6,
            "v1_mb": v1_bytes(plan) / 1e6, "plan_s": planned, "write_s": written,
            "load_s": loaded, "load_cpu_s": loaded_cpu}


def without_timings(path: Path) -> bytes:
    """A plan file's bytes as written, the timings (stats ending in ``_ms``) removed."""
    plan = json.loads(path.read_bytes())
    plan["stats"] = {k: v for k, v in plan.get("stats", {}).items() if not k.endswith("_ms")}
    return json.dumps(plan, indent=2).encode()


def cli_plan(robot: str, planner: str, seed: int, folder: Path, stem: str, hash_seed: str
             ) -> dict[str, float | bytes]:
    """``platform plan`` of a row's files in a process with ``PYTHONHASHSEED=hash_seed``:
    its wall and CPU time [s], peak resident memory [MB] (Linux: VmHWM, sampled every
    50 ms), file size [MB] and file without timings."""
    out = folder / f"{stem}-hash{hash_seed}.plan.json"
    command = [str(Path(sys.executable).with_name("platform")), "plan", "--robot", robot,
               "--planner", planner, "--seed", str(seed), str(folder / f"{stem}-start.json"),
               str(folder / f"{stem}-goal.json"), "--json", str(out)]
    began = time.perf_counter()
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                               env={**os.environ, "PYTHONHASHSEED": hash_seed})
    # the peak resident memory of the command's own image (VmHWM: a forked child's
    # ru_maxrss would start at this process's size), read while it runs
    peak_kb, status_file = 0, Path(f"/proc/{process.pid}/status")
    while True:
        pid, status, usage = os.wait4(process.pid, os.WNOHANG)
        if pid:
            break
        with contextlib.suppress(OSError):
            line = next((x for x in status_file.read_text().splitlines()
                         if x.startswith("VmHWM:")), "VmHWM: 0 kB")
            peak_kb = max(peak_kb, int(line.split()[1]))
        time.sleep(0.05)
    wall = time.perf_counter() - began
    error = process.stderr.read().decode() if process.stderr else ""
    if status:
        raise SystemExit(f"{' '.join(command)} failed: {error.strip()}")
    return {"wall_s": wall, "cpu_s": usage.ru_utime + usage.ru_stime,
            "peak_mb": peak_kb / 1024, "mb": out.stat().st_size / 1e6,
            "content": without_timings(out)}


def hash_seed_rows(rows: list[tuple[str, str, int]], seed: int, folder: Path,
                   hash_seeds: list[str]) -> list[list[str]]:
    """Every row planned by ``platform plan`` under each hash seed, and whether the files
    agree (timings aside)."""
    table_rows = []
    for robot, planner, n in rows:
        runs = [cli_plan(robot, planner, seed, folder, f"{robot}-{n}", h) for h in hash_seeds]
        same = all(r["content"] == runs[0]["content"] for r in runs)
        digest = hashlib.sha256(runs[0]["content"]).hexdigest()[:12]
        table_rows.append([str(n), f"{robot}/{planner}", ", ".join(hash_seeds),
                           " / ".join(f"{r['wall_s']:.1f}" for r in runs),
                           " / ".join(f"{r['cpu_s']:.1f}" for r in runs),
                           f"{max(r['peak_mb'] for r in runs):.0f}", f"{runs[0]['mb']:.3f}",
                           "yes" if same else "NO", digest])
    return table_rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--sizes", default="100,500,1000")
    parser.add_argument("--branching", type=int, default=None,
                        help="FreeBOT: most modules that branch (default unbounded)")
    parser.add_argument("--out", type=Path, default=None,
                        help="keep the configurations and plan files here")
    parser.add_argument("--hash-seeds", default="",
                        help="also run platform plan under each PYTHONHASHSEED (e.g. 11,12) "
                             "and compare its plan files")
    args = parser.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    hash_seeds = [h for h in args.hash_seeds.split(",") if h]
    console.print(f"seed {args.seed}, sizes {sizes}, FreeBOT branching "
                  f"{args.branching or 'unbounded'}")
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.out or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        rows, found = [], []
        done = pairs(sizes, args.seed, args.branching)
        for robot, planner, n, start, goal in done:
            r = measure(robot, planner, start, goal, args.seed, folder, f"{robot}-{n}")
            found.append((robot, n, r))
            rows.append([str(n), f"{robot}/{planner}", str(r["actions"]), f"{r['mb']:.3f}",
                         f"{r['v1_mb']:.1f}", f"{r['plan_s']:.1f}", f"{r['write_s']:.2f}",
                         f"{r['load_s']:.2f}", f"{r['load_cpu_s']:.2f}"])
            console.print(f"  {robot} {n} done", style="dim")
        console.print(table("Plan files (schema version 2)",
                            ["modules", "robot/planner", "actions", "file MB", "v1 MB (≈)",
                             "plan s", "write s", "load+validate s", "load CPU s"], rows))
        hashed = hash_seed_rows([(robot, planner, n) for robot, planner, n, *_ in done],
                                args.seed, folder, hash_seeds) if hash_seeds else []
    if hashed:
        console.print(table("platform plan under each PYTHONHASHSEED (own process each)",
                            ["modules", "robot/planner", "hash seeds", "wall s", "CPU s",
                             "peak MB", "file MB", "same file (timings aside)",
                             "sha256 (timings aside)"], hashed))
    top = [r for robot, n, r in found if n == max(sizes) and robot != "freesn"]
    console.print(f"max_mb_{max(sizes)}={max(r['mb'] for r in top):.3f} "
                  f"max_load_s_{max(sizes)}={max(r['load_s'] for r in top):.2f} "
                  f"max_load_cpu_s_{max(sizes)}={max(r['load_cpu_s'] for r in top):.2f}"
                  + (f" hash_seeds_identical={sum(r[7] == 'yes' for r in hashed)}/{len(hashed)}"
                     if hashed else ""))


if __name__ == "__main__":
    main()
