"""Start-up time of every command's ``--help``: the command line's first impression.

Runs ``platform <command> --help`` as a user does (the installed console script, a new
process each time) for the top level, every built-in command, every subcommand of a
group (``library build``...) and every command a plugin registers, ``--runs`` times
each, round-robin so a busy moment hits every command alike. Prints a table of the
median and the largest wall time per command, the median against the goal (0.5 s,
issue 16; the largest shows how much a busy machine adds), and the bare interpreter's
start for scale. Nothing is random: the seed line says so.

The last line is machine-readable::

    commands=... worst_median_s=... worst_max_s=... over_goal=...

``tests/core/test_cli_startup.py`` checks the cause rather than the time: the
``--help`` path imports none of numpy, scipy, networkx, rerun, MuJoCo, PyBullet.

Usage: ``python benchmarks/cli_startup.py --runs 5 --plot docs/images/cli-startup.png``
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

from rich.console import Console
from rich.table import Table

from msrr.core.app.cli import command_paths, get_cli
from msrr.core.console import exit_unless_installed

GOAL_S = 0.5
"""Issue 16: every ``--help`` starts within this [s]."""


def script(given: str | None = None) -> str:
    """``given``, else the ``platform`` console script of this interpreter's environment."""
    if given is not None:
        return given
    beside = Path(sys.executable).with_name("platform")
    found = str(beside) if beside.exists() else shutil.which("platform")
    if found is None:
        raise SystemExit("no `platform` script: pip install -e . in this environment")
    return found


def time_once(argv: list[str]) -> float:
    """Wall time [s] of one process running ``argv`` to its end (must exit 0)."""
    start = time.perf_counter()
    done = subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, check=False)
    elapsed = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(argv)} exited {done.returncode}: "
                         f"{done.stderr.decode(errors='replace').strip()[-300:]}")
    return elapsed


def measure(paths: list[tuple[str, ...]], runs: int, platform: str) -> dict[str, list[float]]:
    """``{label: [seconds per run]}``: the interpreter alone, then every ``--help`` of the
    script ``platform``."""
    argvs = {"python -c pass (interpreter)": [sys.executable, "-c", "pass"]}
    argvs |= {" ".join(("platform", *path, "--help")): [platform, *path, "--help"]
              for path in paths}
    times: dict[str, list[float]] = {label: [] for label in argvs}
    for _ in range(runs):  # round-robin: a busy moment slows every command alike
        for label, argv in argvs.items():
            times[label].append(time_once(argv))
    return times


def plot(times: dict[str, list[float]], path: str) -> None:
    """A bar per command: median, the largest run as a tick, the goal as a line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = list(times)
    medians = [statistics.median(v) for v in times.values()]
    tops = [max(v) for v in times.values()]
    fig, ax = plt.subplots(figsize=(8, 0.3 * len(labels) + 1.2))
    ax.barh(labels, medians, color="tab:blue", label="median")
    ax.plot(tops, labels, "k|", markersize=10, label="largest")
    ax.axvline(GOAL_S, color="tab:red", linestyle="--", label=f"goal {GOAL_S} s")
    ax.invert_yaxis()
    ax.set_xlabel("start-up time of --help [s]")
    ax.set_title(f"platform --help start-up, {len(next(iter(times.values())))} runs each, "
                 f"{os.cpu_count()} cores")
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5, help="runs per command (default 5)")
    parser.add_argument("--plot", metavar="PNG", help="also draw the times to this PNG")
    parser.add_argument("--script", metavar="PATH", default=None,
                        help="the `platform` to time (default: this environment's; another "
                             "checkout's wrapper script compares versions)")
    args = parser.parse_args()
    if args.runs < 1:
        parser.error("--runs must be at least 1")
    if args.plot:
        exit_unless_installed("matplotlib", "plot", "--plot")
    console = Console(highlight=False)
    paths = command_paths(get_cli())
    console.print("seed: none (nothing random; wall times of new processes)", markup=False)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    console.print(f"{os.cpu_count()} cores, load average {load:.2f}; {args.runs} runs each",
                  markup=False)
    platform = script(args.script)
    console.print(f"script: {platform}", markup=False)
    times = measure(paths, args.runs, platform)
    table = Table(title="Start-up of --help [s]", title_justify="left")
    for column in ("command", "median", "max", f"median <= {GOAL_S} s"):
        table.add_column(column, justify="left" if column == "command" else "right")
    for label, values in times.items():
        ok = "" if label.startswith("python") else (
            "yes" if statistics.median(values) <= GOAL_S else "NO")
        table.add_row(label, f"{statistics.median(values):.3f}", f"{max(values):.3f}", ok)
    console.print(table)
    helps = {k: v for k, v in times.items() if not k.startswith("python")}
    over = [k for k, v in helps.items() if statistics.median(v) > GOAL_S]
    console.print(f"commands={len(helps)} "
                  f"worst_median_s={max(statistics.median(v) for v in helps.values()):.3f} "
                  f"worst_max_s={max(max(v) for v in helps.values()):.3f} "
                  f"over_goal={len(over)}", markup=False)
    if args.plot:
        plot(times, args.plot)
        console.print(f"wrote {args.plot}", markup=False)


if __name__ == "__main__":
    main()
