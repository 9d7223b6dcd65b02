"""Cost of deriving a changed configuration (``Configuration.derive`` and what uses it).

Planners derive one target configuration per action, so this is on the hot path of
large plans. A random tree of ``--modules`` node modules joined by struts with random
``z`` and ``x`` (seeded) is derived in the ways the platform does: a copy, a relabelling,
the skeletal view, a module map with every second strut reversed (``ModuleMap.apply``)
and a yaw rotation. Each row is the best of ``--repeat`` runs of ``--number`` calls.
The last line is machine-readable::

    copy_ms=... relabel_ms=... apply_ms=...

Usage: ``python benchmarks/configuration_derive.py --modules 500 --seed 0``
"""

from __future__ import annotations

import argparse
import timeit

import numpy as np
from rich.console import Console
from rich.table import Table

from msrr.core.alignment import rot_z
from msrr.core.configuration import Configuration
from msrr.core.mapping import ModuleMap


def tree(modules: int, rng: np.random.Generator) -> Configuration:
    """A random tree of ``modules`` nodes joined by struts with unit ``z`` and ``x``."""
    def unit() -> np.ndarray:
        v = rng.normal(size=3)
        return v / np.linalg.norm(v)

    config = Configuration("bench", name=f"tree-{modules}")
    for i in range(modules):
        config.add_module(f"N{i}", "node")
    for i in range(1, modules):
        config.connect(f"N{i}", f"N{int(rng.integers(i))}", id=f"S{i}", kind="strut",
                       z=unit(), x=unit())
    return config


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--modules", type=int, default=500)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--number", type=int, default=50)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    config = tree(args.modules, np.random.default_rng(args.seed))
    renames = {v: f"M{v}" for v in config.vertices()}
    mapping = ModuleMap(renames, {e: (f"T{e}", i % 2 == 1)
                                  for i, e in enumerate(config.edge_ids())})
    yaw = rot_z(0.3)
    cases = {
        "copy": config.copy,
        "relabel": lambda: config.relabel(renames),
        "skeletal": config.skeletal,
        "apply": lambda: mapping.apply(config),
        "apply+yaw": lambda: mapping.apply(config, rotation=yaw),
    }
    times = {name: min(timeit.repeat(call, number=args.number, repeat=args.repeat))
             / args.number * 1e3 for name, call in cases.items()}
    table = Table(title=f"derive a {args.modules}-module configuration (seed {args.seed})")
    table.add_column("derivation")
    table.add_column("time (ms)", justify="right")
    for name, ms in times.items():
        table.add_row(name, f"{ms:.3f}")
    Console().print(table)
    print(f"seed={args.seed} copy_ms={times['copy']:.3f} relabel_ms={times['relabel']:.3f} "
          f"apply_ms={times['apply']:.3f}")


if __name__ == "__main__":
    main()
