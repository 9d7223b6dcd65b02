"""MISO connection planning against the exact solver and against Luo and Lam's IM.

Instances of the three kinds Luo and Lam draw (generators written from their
description, :mod:`msrr.core.freeform.miso.model`), six connections at most on a module:

* ``tree`` -- one tree (modules join random placed modules);
* ``forest`` -- 2 to 6 separate trees;
* ``cyclic`` -- every module picks a random module to sit on (not itself, not one on
  it) or stays free while fewer than six are: pieces and cycles as they fall.

Start and goal of an instance are two draws of the same kind and size. Four tables:

1. **Optimality**, ``n = 5..10``: the heuristic ``miso`` against ``miso-exact`` (an
   integer program that proves the fewest connection changes) and against IM
   (:func:`msrr.core.freeform.miso.im_pairing`, our reimplementation of Luo and Lam's IM
   from their description, not their code), on connection changes (broken + made, their
   metric); steps for both planners.
2. **The exact solver's reach**, ``n = 15, 20, 25``: proved, time, heuristic optimal.
3. **Scale**, ``n`` up to 1,000: changes of the heuristic and IM, steps, and the time
   of each in the same process, alternating (median of the repeats): the pairing alone
   against IM's pairing, and the whole plan (pairing and step order). The heuristic's
   pairing computes IM's as one of its candidates (its guarantee never to be worse), so
   its time includes IM's.
4. **The human example** (Luo and Lam 2023, section VI.B: six chains -> a human figure,
   568 modules; ``plugins/freebot/configs/human/``): changes beside the published IM
   result, 91.

With ``--peer DIR`` (a checkout of ``FreeformRobotics/MISO_connection``) the scale table
also runs the *published* IM, unmodified, on the same instances in the same run: a
subprocess of ``--peer-python`` (an interpreter with the peer's own dependencies: numpy,
networkx, anytree, graphviz; none of them msrr's) imports its ``IM/Matrix2tree.py`` and
``IM/POINTER_Pairing.py`` and times the calls its ``IM/run_POINTER.py`` times. Its
changes are recomputed from its pairing (its own ``error`` truncates a float square,
docs/freebot.md), and the heuristic's time is compared with its time.

The last line is machine-readable::

    optimal_rate=... worse_than_im=... time_ratio_1000=... human_changes=...

Usage: ``python benchmarks/miso_planner.py --seed 0 [--peer DIR --peer-python PY]``
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

from msrr.core.app.batch import exit_on_interrupt, run_batch
from msrr.core.freeform.miso import (
    FREE,
    MisoLimits,
    MisoProblem,
    changes,
    heuristic_pairing,
    im_pairing,
    random_cyclic,
    random_forest,
    random_miso_tree,
    solve_exact,
    solve_heuristic,
    targets,
)
from msrr.core.io import load_configuration

KINDS = ("tree", "forest", "cyclic")
SMALL = tuple(range(5, 11))
REACH = (15, 20, 25)
LARGE = (50, 100, 200, 500, 1000)
RULES = MisoLimits(max_in=6, no_docking_onto="child")   # FreeBOT's, Luo and Lam's model
HUMAN = Path(__file__).resolve().parent.parent / "plugins" / "freebot" / "configs" / "human"
PUBLISHED_IM_HUMAN = 91
PEER_RUN = """
import json, sys, time
import numpy as np
sys.setrecursionlimit(100000)
sys.path.insert(0, sys.argv[1])
import Matrix2tree, POINTER_Pairing
data = np.load(sys.argv[2])
start = time.time()   # from here on, the calls IM/run_POINTER.py times
trees = []
for matrix, name in ((data["I"], "Initial"), (data["F"], "Final")):
    tree = Matrix2tree.Matrix2tree(matrix, name)
    tree.matrix2tree(printer=False)
    tree.CNL_cal()
    tree.tree_render(printer=False, draw=False)
    tree.Pointer()
    tree.Pointer_int(printer=False)
    trees.append(tree)
pairing = POINTER_Pairing.POINTER_Pairing(*trees)
pairing.Virtual_roots(printer=False)
pairing.Difference(printer=False)
seconds = time.time() - start
print(json.dumps({"pairs": [list(map(int, c.Match)) for c in pairing.csg], "seconds": seconds}))
"""
"""The published IM run on one instance, in the peer's own interpreter: its pipeline as
``IM/run_POINTER.py`` runs it (argv: the peer's ``IM`` folder, an ``.npz`` of ``I`` and
``F``, row ``i`` holding a 1 in column ``j`` when module ``i`` sits on ``j``)."""


def draw(kind: str, n: int, rng: np.random.Generator) -> tuple[int, ...]:
    if kind == "tree":
        return random_miso_tree(n, rng)
    if kind == "forest":
        return random_forest(n, int(rng.integers(2, min(6, n) + 1)), rng)
    return random_cyclic(n, rng)


def instance(kind: str, n: int, rng: np.random.Generator) -> MisoProblem:
    return MisoProblem.from_parents(draw(kind, n, rng), draw(kind, n, rng), RULES)


def im_changes(problem: MisoProblem) -> int:
    return changes(problem.start, targets(problem, im_pairing(problem)))


@dataclass
class Compared:
    kind: str
    n: int
    heuristic: int
    exact: int
    im: int
    heuristic_steps: int
    exact_steps: int
    proved: bool
    exact_ms: float


def compare(task: tuple[str, int, MisoProblem]) -> Compared:
    """Heuristic, exact and IM on one instance (a batch task)."""
    kind, n, problem = task
    heuristic = solve_heuristic(problem)
    t0 = time.perf_counter()
    exact = solve_exact(problem)
    ms = 1e3 * (time.perf_counter() - t0)
    return Compared(kind, n, heuristic.changes, exact.changes, im_changes(problem),
                    heuristic.cost, exact.cost, bool(exact.stats["changes_proved"]), ms)


def _last_line(stderr: str) -> str:
    """A failed subprocess's last line of error output (its exception)."""
    return (stderr.strip().splitlines() or ["no message"])[-1]


@dataclass(frozen=True)
class Peer:
    """The published planner's checkout and the interpreter that runs it."""

    folder: Path
    python: str

    def missing(self) -> str | None:
        """Why the published IM cannot be imported under ``python``, or ``None``."""
        out = subprocess.run([self.python, "-c", "import sys; sys.path.insert(0, sys.argv[1]); "
                              "import Matrix2tree, POINTER_Pairing", str(self.folder / "IM")],
                             capture_output=True, text=True, check=False)
        return None if out.returncode == 0 else _last_line(out.stderr)

    def im(self, problem: MisoProblem) -> tuple[int, float]:
        """The published IM on ``problem``: changes of its pairing and its time [ms]."""
        n = problem.n
        matrices = {name: np.zeros((n, n)) for name in ("I", "F")}
        for name, parent in (("I", problem.start), ("F", problem.goal)):
            for i, p in enumerate(parent):
                if p != FREE:
                    matrices[name][i, p] = 1.0
        with tempfile.TemporaryDirectory() as scratch:
            path = Path(scratch) / "instance.npz"
            np.savez(path, **matrices)
            out = subprocess.run([self.python, "-c", PEER_RUN, str(self.folder / "IM"),
                                  str(path)], capture_output=True, text=True, check=False)
        if out.returncode != 0:
            raise SystemExit(f"{self.folder}: the published IM failed under "
                             f"{self.python}: {_last_line(out.stderr)}")
        result = json.loads(out.stdout.strip().splitlines()[-1])
        pair = [FREE] * n
        for a, b in result["pairs"]:
            pair[a] = b
        return changes(problem.start, targets(problem, pair)), 1e3 * result["seconds"]


@dataclass
class Timed:
    kind: str
    n: int
    heuristic: int
    im: int
    steps: int
    pairing_ms: float
    im_ms: float
    plan_ms: float
    peer: int | None = None
    peer_ms: float | None = None


def timed(kind: str, n: int, problem: MisoProblem, peer: Peer | None = None) -> Timed:
    """IM's pairing, the heuristic's pairing and its whole plan, one after the other;
    then the published IM when ``peer`` is given."""
    t0 = time.perf_counter()
    im = im_changes(problem)
    t1 = time.perf_counter()
    pair = heuristic_pairing(problem)
    t2 = time.perf_counter()
    plan = solve_heuristic(problem)
    t3 = time.perf_counter()
    assert plan.changes == changes(problem.start, targets(problem, pair))
    published = peer.im(problem) if peer is not None else (None, None)
    return Timed(kind, n, plan.changes, im, plan.cost, 1e3 * (t2 - t1), 1e3 * (t1 - t0),
                 1e3 * (t3 - t2), *published)


def optimality_table(rows: list[Compared], sizes: tuple[int, ...], title: str) -> Table:
    table = Table(title=title)
    for column in ("kind", "n", "inst.", "optimal", "changes heur. / exact / IM",
                   "steps heur. / exact", "worse than IM", "proved", "exact median ms",
                   "exact max ms"):
        table.add_column(column, justify="right")
    for kind in KINDS:
        for n in sizes:
            r = [c for c in rows if c.kind == kind and c.n == n]
            if not r:
                continue
            table.add_row(kind, str(n), str(len(r)),
                          f"{np.mean([c.heuristic == c.exact for c in r]):.2f}",
                          f"{np.mean([c.heuristic for c in r]):.2f} / "
                          f"{np.mean([c.exact for c in r]):.2f} / {np.mean([c.im for c in r]):.2f}",
                          f"{np.mean([c.heuristic_steps for c in r]):.2f} / "
                          f"{np.mean([c.exact_steps for c in r]):.2f}",
                          str(sum(c.heuristic > c.im for c in r)),
                          f"{np.mean([c.proved for c in r]):.2f}",
                          f"{np.median([c.exact_ms for c in r]):.0f}",
                          f"{max(c.exact_ms for c in r):.0f}")
    return table


def scale_table(runs: list[Timed]) -> Table:
    peer = all(t.peer is not None for t in runs)
    title = "Scale: heuristic, IM" + (" and the published IM" if peer else "")
    table = Table(title=f"{title} in the same run (median ms)")
    columns = ["kind", "n", "changes heur.", "changes IM", "steps heur.", "worse than IM",
               "pairing ms", "IM ms", "pairing / IM", "whole plan ms"]
    if peer:
        columns += ["changes published IM", "published IM ms", "pairing / published"]
    for column in columns:
        table.add_column(column, justify="right")
    for kind in KINDS:
        for n in LARGE:
            r = [t for t in runs if t.kind == kind and t.n == n]
            pairing, im = statistics.median(t.pairing_ms for t in r), statistics.median(
                t.im_ms for t in r)
            row = [kind, str(n), f"{np.mean([t.heuristic for t in r]):.1f}",
                   f"{np.mean([t.im for t in r]):.1f}", f"{np.mean([t.steps for t in r]):.1f}",
                   str(sum(t.heuristic > t.im for t in r)), f"{pairing:.0f}", f"{im:.0f}",
                   f"{pairing / im:.2f}", f"{statistics.median(t.plan_ms for t in r):.0f}"]
            if peer:
                published = statistics.median(t.peer_ms for t in r)
                row += [f"{np.mean([t.peer for t in r]):.1f}", f"{published:.0f}",
                        f"{pairing / published:.2f}"]
            table.add_row(*row)
    return table


def human(console: Console, peer: Peer | None) -> int:
    start = load_configuration(HUMAN / "human-chains.json")
    goal = load_configuration(HUMAN / "human.json")
    problem = MisoProblem.from_configurations(start, goal, RULES)
    t0 = time.perf_counter()
    plan = solve_heuristic(problem)
    ms = 1e3 * (time.perf_counter() - t0)
    table = Table(title="Human example (Luo and Lam 2023, VI.B): six chains -> human, 568 modules")
    for column in ("planner", "connection changes", "steps", "ms"):
        table.add_column(column, justify="right")
    table.add_row("miso (heuristic)", str(plan.changes), str(plan.cost), f"{ms:.0f}")
    table.add_row("IM, published", str(PUBLISHED_IM_HUMAN), "", "")
    if peer is not None:
        published, published_ms = peer.im(problem)
        table.add_row("IM, published code run here", str(published), "", f"{published_ms:.0f}")
    table.add_row("IM, our reimplementation", str(im_changes(problem)), "", "")
    console.print(table)
    return plan.changes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--instances", type=int, default=50,
                        help="instances per size and kind, n = 5..10 (default 50)")
    parser.add_argument("--reach", type=int, default=5,
                        help="instances per size and kind, n = 15, 20, 25 (default 5)")
    parser.add_argument("--repeats", type=int, default=3,
                        help="instances per size and kind for the scale table (default 3)")
    parser.add_argument("--workers", type=int, default=1,
                        help="worker processes for the exact comparisons (1: here; 0: per core)")
    parser.add_argument("--peer", type=Path, default=None,
                        help="a checkout of FreeformRobotics/MISO_connection: the scale "
                        "table runs its published IM too")
    parser.add_argument("--peer-python", default=sys.executable,
                        help="the interpreter with the peer's dependencies (numpy, networkx, "
                        "anytree, graphviz); default this one")
    args = parser.parse_args()
    if args.peer is not None and not (args.peer / "IM" / "POINTER_Pairing.py").is_file():
        parser.error(f"--peer {args.peer}: no IM/POINTER_Pairing.py there")
    peer = Peer(args.peer.resolve(), args.peer_python) if args.peer is not None else None
    if peer is not None and (why := peer.missing()) is not None:
        parser.error(f"--peer-python {peer.python}: cannot import the published IM: {why}")
    console = Console(highlight=False, width=160)
    console.print(f"seed={args.seed} instances={args.instances} reach={args.reach} "
                  f"repeats={args.repeats} rules: at most 6 on a module, no docking onto "
                  "one's child")
    rng = np.random.default_rng(args.seed)
    small = [(k, n, instance(k, n, rng)) for n in SMALL for k in KINDS
             for _ in range(args.instances)]
    reach = [(k, n, instance(k, n, rng)) for n in REACH for k in KINDS for _ in range(args.reach)]
    large = [(k, n, instance(k, n, rng)) for n in LARGE for k in KINDS
             for _ in range(args.repeats)]
    with exit_on_interrupt():
        compared = run_batch(compare, small + reach, label="exact comparisons",
                             workers=args.workers).values()
    console.print(optimality_table(compared, SMALL, "Heuristic vs exact and IM, n = 5..10"))
    console.print(optimality_table(compared, REACH, "The exact solver's reach"))
    runs = [timed(*task, peer) for task in large]   # here, in order: the times compare
    console.print(scale_table(runs))
    human_changes = human(console, peer)
    small_rows = [c.heuristic == c.exact for c in compared if c.n in SMALL]
    rate = float(np.mean(small_rows)) if small_rows else float("nan")
    worse = sum(c.heuristic > c.im for c in compared) + sum(t.heuristic > t.im for t in runs)
    big = [t for t in runs if t.n == LARGE[-1]]
    ratio = statistics.median(t.pairing_ms for t in big) / statistics.median(
        t.im_ms for t in big)
    published = (f" time_ratio_published_1000="
                 f"{statistics.median(t.pairing_ms for t in big) / statistics.median(t.peer_ms for t in big):.3f}"
                 if peer is not None else "")
    print(f"optimal_rate={rate:.3f} worse_than_im={worse} time_ratio_1000={ratio:.2f} "
          f"human_changes={human_changes}{published}")


if __name__ == "__main__":
    main()
