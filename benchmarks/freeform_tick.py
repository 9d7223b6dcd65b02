"""Where a FreeBOT MuJoCo run spends its CPU per tick, and a fingerprint of its outcome
(issue 28, item 6: the 568-module human example must run to its goal).

Runs ``platform run``'s own functions (``prepare_run``, ``execute_run``) on the human
example (``--human``: ``human-chains-near.json`` -> ``human.json``) or a FreeBOT scenario
(``--scenario``) for ``--seconds`` of simulated time (the run's ``deadline``), timing the
parts of every tick without cProfile: each part's CPU (``time.process_time``) counts
without the parts timed inside it, so the shares add up to the whole run. Parts: the
world's step loop (``MujocoWorld.step`` less what follows), ``mj_step``, the world's servo
(``FreeformWorld._servo``), the modules' reports (``FreeformWorld.reports``), the
recognizer (``ContactRecognizer.recognize``), the controller
(``ContactController.control``), the executor's change detection
(``Executor._detect_changes``), the driver guard's checks (``GuardedDriver._hold``), and
the rest (executor, planner, judge).

The fingerprint proves an optimisation left the run unchanged to the bit: a SHA-256 over
every report the world gave (links, tilt and relative rotations, sucker, events,
odometry, byte for byte), then over every module's ``qpos`` and ``qvel`` at the end, and
the run's summary (ticks, simulated time, success, shape error).

Usage: ``python benchmarks/freeform_tick.py (--human | --scenario NAME) [--seconds 60]
[--seed 0] [--noise 0] [--save FILE.png]``. Prints the seed, the table and the
fingerprint; ``--save`` plots the shares.
"""

from __future__ import annotations

import hashlib
import math
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import click
import mujoco
import numpy as np

from msrr.core.app.run import RunRequest, execute_run, prepare_run
from msrr.core.console import console, table
from msrr.core.executor import Executor
from msrr.core.faults import GuardedDriver
from msrr.core.freeform import mujoco as freeform_mujoco
from msrr.core.freeform.recognition import ContactController, ContactRecognizer
from msrr.core.freeform.world import FreeformWorld, ModuleReport

ROOT = Path(__file__).resolve().parents[1]
HUMAN = ROOT / "plugins" / "freebot" / "configs" / "human"


class Timer:
    """CPU time of named parts, each without the timed parts nested in it."""

    def __init__(self) -> None:
        self.own: dict[str, float] = {}
        self.calls: dict[str, int] = {}
        self._stack: list[float] = []    # CPU of the timed parts nested in each open part

    def wrap(self, name: str, func: Callable[..., Any]) -> Callable[..., Any]:
        """``func`` timed as part ``name``."""
        self.own.setdefault(name, 0.0)
        self.calls.setdefault(name, 0)

        def timed(*args: Any, **kwargs: Any) -> Any:
            self._stack.append(0.0)
            started = time.process_time()
            try:
                return func(*args, **kwargs)
            finally:
                spent = time.process_time() - started
                nested = self._stack.pop()
                self.own[name] += spent - nested
                self.calls[name] += 1
                if self._stack:
                    self._stack[-1] += spent
        return timed


class Fingerprint:
    """A running SHA-256 of every report the world gave, and the world last stepped."""

    def __init__(self) -> None:
        self.digest = hashlib.sha256()
        self.world: FreeformWorld | None = None

    def add_reports(self, reports: dict[str, ModuleReport]) -> None:
        for module, r in reports.items():
            self.digest.update(f"{module}|{r.attached}|{r.sucker}|{r.events!r}|".encode())
            for array in (r.tilt, r.relative, r.odometry):
                if array is not None:
                    self.digest.update(np.ascontiguousarray(array, dtype=np.float64).tobytes())

    def final(self) -> tuple[str, str]:
        """The reports' digest and the digest of the final ``qpos`` and ``qvel``."""
        state = hashlib.sha256()
        if self.world is not None:
            state.update(self.world.data.qpos.tobytes())
            state.update(self.world.data.qvel.tobytes())
        return self.digest.hexdigest()[:16], state.hexdigest()[:16]


PARTS = (("world step loop", freeform_mujoco.MujocoWorld, "step"),
         ("world servo", FreeformWorld, "_servo"),
         ("reports", FreeformWorld, "reports"),
         ("recognition", ContactRecognizer, "recognize"),
         ("controller", ContactController, "control"),
         ("change detection", Executor, "_detect_changes"),
         ("driver guard", GuardedDriver, "_hold"))


def _instrument(timer: Timer, print_: Fingerprint) -> Callable[[], None]:
    """Time :data:`PARTS` and ``mj_step``, feed the fingerprint; returns the undo."""
    saved = [(owner, attr, getattr(owner, attr)) for _, owner, attr in PARTS]
    saved.append((mujoco, "mj_step", mujoco.mj_step))
    for name, owner, attr in PARTS:
        setattr(owner, attr, timer.wrap(name, getattr(owner, attr)))
    mujoco.mj_step = timer.wrap("mj_step", mujoco.mj_step)
    step, reports = FreeformWorld.step, FreeformWorld.reports

    def stepping(world: FreeformWorld, duration: float) -> None:
        print_.world = world
        step(world, duration)

    def reporting(world: FreeformWorld) -> dict[str, ModuleReport]:
        out = reports(world)
        print_.add_reports(out)
        return out

    FreeformWorld.step, FreeformWorld.reports = stepping, reporting   # type: ignore[method-assign]

    def undo() -> None:
        del FreeformWorld.step             # inherited again
        for owner, attr, value in saved:
            setattr(owner, attr, value)
    return undo


def measure(scenario: str | None, seconds: float, seed: int, noise: float
            ) -> tuple[dict[str, Any], Timer, Fingerprint]:
    """One run for ``seconds`` simulated: its summary, parts and fingerprint."""
    timer, print_ = Timer(), Fingerprint()
    files = (None, None) if scenario else (HUMAN / "human-chains-near.json",
                                           HUMAN / "human.json")
    options = (("noise", str(noise)),) if noise else ()
    with tempfile.TemporaryDirectory() as out:
        prepared = prepare_run(RunRequest("freebot", scenario=scenario, start=files[0],
                                          goal=files[1], driver="mujoco",
                                          out=Path(out) / "run", log=False, seed=seed,
                                          deadline=seconds, driver_options=options))
        undo = _instrument(timer, print_)
        try:
            started = time.process_time()
            result = execute_run(prepared)
            cpu = time.process_time() - started
        finally:
            undo()
    goal = result.goal
    shape = None if goal is None or goal.shape is None else math.degrees(goal.shape.error)
    summary = {"ticks": result.ticks, "simulated": result.sim_time, "success": result.success,
               "shape": shape, "actions": f"{result.actions_done}/{result.actions_total}",
               "cpu": cpu}
    return summary, timer, print_


def _rows(summary: dict[str, Any], timer: Timer) -> list[list[object]]:
    cpu, ticks = summary["cpu"], max(1, summary["ticks"])
    rest = cpu - sum(timer.own.values())
    parts = [*((name, timer.own[name], timer.calls[name]) for name in timer.own),
             ("executor and the rest", rest, ticks)]
    return [[name, f"{spent:.1f}", f"{100 * spent / cpu:.1f}", f"{1000 * spent / ticks:.2f}",
             calls] for name, spent, calls in parts]


@click.command()
@click.option("--human", "human", is_flag=True, help="The 568-module human example.")
@click.option("--scenario", default="", help="A FreeBOT scenario instead (chains-to-tree).")
@click.option("--seconds", default=60.0, show_default=True, help="Simulated time [s].")
@click.option("--seed", default=0, show_default=True, help="Seed of the run.")
@click.option("--noise", default=0.0, show_default=True,
              help="Standard deviation of every reported angle [rad].")
@click.option("--save", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Save a bar plot of the shares here.")
def main(human: bool, scenario: str, seconds: float, seed: int, noise: float,
         save: Path | None) -> None:
    if human == bool(scenario):
        raise click.UsageError("give one of --human and --scenario NAME")
    name = scenario or "human (human-chains-near -> human)"
    console.print(f"seed {seed}, noise {noise} rad, {name}, {seconds:g} s simulated")
    summary, timer, print_ = measure(scenario or None, seconds, seed, noise)
    sim = max(summary["simulated"], 1e-9)
    console.print(f"CPU {summary['cpu']:.1f} s for {summary['simulated']:.1f} s simulated: "
                  f"{summary['cpu'] / sim:.3f} CPU s per simulated s, "
                  f"{1000 * summary['cpu'] / max(1, summary['ticks']):.1f} ms per tick")
    rows = _rows(summary, timer)
    console.print(table("CPU by part (each without the parts timed inside it)",
                        ["part", "CPU [s]", "share [%]", "ms per tick", "calls"], rows))
    reports, state = print_.final()
    shape = "-" if summary["shape"] is None else f"{summary['shape']:.2f}"
    console.print(f"fingerprint: ticks {summary['ticks']}, simulated "
                  f"{summary['simulated']:.1f} s, actions {summary['actions']}, success "
                  f"{summary['success']}, shape {shape} deg, reports {reports}, "
                  f"state {state}")
    if save is not None:
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(7, 3.5))
        ax.barh([r[0] for r in rows], [float(r[2]) for r in rows])
        ax.set_xlabel("share of CPU [%]")
        ax.set_title(f"{name}: {summary['cpu'] / sim:.2f} CPU s per simulated s")
        fig.tight_layout()
        fig.savefig(save)
        console.print(f"saved {save}")


if __name__ == "__main__":
    main()
