"""CPU per simulated second of a FreeBOT world at rest, with and without MuJoCo's island
sleeping (issue 28: the 568-module human example's start, six chains on the floor).

Builds the world of a start configuration through the robot's driver (seeded), lets it
settle for ``--settle`` simulated seconds, then steps it ``--steps`` times 0.5 s and
prints, per ``sleep_tolerance`` (0: never sleeps; the driver's default), the CPU time
per simulated second (``time.process_time``), the awake trees and the constraint rows at
the end, and how far the shells moved over the measured steps (the largest centre
displacement, ground truth): sleeping must not move what rests.

Usage: ``python benchmarks/freeform_sleep.py [--seed 0] [--config PATH]
[--settle 1.0] [--steps 4]``.
"""

from __future__ import annotations

import time
from pathlib import Path

import click
import numpy as np

from msrr.core.console import console, table
from msrr.core.io import load_configuration

ROOT = Path(__file__).resolve().parents[1]
HUMAN = ROOT / "plugins" / "freebot" / "configs" / "human" / "human-chains.json"


def measure(config_path: Path, tolerance: float | None, seed: int, settle: float,
            steps: int) -> dict[str, float]:
    """One world at rest: CPU per simulated second [s/s], awake trees, constraint rows
    and the largest shell displacement [m] over ``steps`` x 0.5 s after ``settle`` s."""
    from msrr.plugins.freebot.plugin import plugin

    options = {} if tolerance is None else {"sleep_tolerance": tolerance}
    driver = plugin.driver_factory()(seed=seed, **options)
    driver.connect()
    driver.reset(load_configuration(config_path))
    world = driver.world
    world.step(settle)
    before = np.array([world.centre(m) for m in world.modules])
    start = time.process_time()
    for _ in range(steps):
        world.step(0.5)
    cpu = (time.process_time() - start) / (0.5 * steps)
    after = np.array([world.centre(m) for m in world.modules])
    return {"cpu": cpu, "awake": float(world.data.ntree_awake), "rows": float(world.data.nefc),
            "moved": float(np.max(np.linalg.norm(after - before, axis=1))),
            "tolerance": world.options.sleep_tolerance}


@click.command()
@click.option("--seed", default=0, show_default=True)
@click.option("--config", "config_path", type=click.Path(exists=True, path_type=Path),
              default=HUMAN, show_default=True)
@click.option("--settle", default=1.0, show_default=True, help="simulated seconds first")
@click.option("--steps", default=4, show_default=True, help="measured steps of 0.5 s")
def main(seed: int, config_path: Path, settle: float, steps: int) -> None:
    console.print(f"seed {seed}; {config_path.name}; settle {settle} s, then {steps} x 0.5 s")
    rows = []
    for tolerance in (0.0, None):
        r = measure(config_path, tolerance, seed, settle, steps)
        rows.append([f"{r['tolerance']:g}", f"{r['cpu']:.2f}", f"{r['awake']:.0f}",
                     f"{r['rows']:.0f}", f"{1000 * r['moved']:.3f}"])
    console.print(table("a FreeBOT world at rest", ["sleep_tolerance [m/s]", "CPU s per simulated s", "awake trees",
                         "constraint rows", "largest shell travel [mm]"], rows))


if __name__ == "__main__":
    main()
