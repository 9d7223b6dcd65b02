"""The module link measured on loopback (issue 15): bandwidth, latency, loss.

1. **Bandwidth and latency**: the 18 modules of FreeSN S12N6-1.1 (12 struts, 6 nodes)
   emulated in MuJoCo at 10 Hz in real time, driven by the ``link`` driver for
   ``--seconds`` s: every strut is commanded every tick (a hold: the connection vector
   of each docked end, from its own report). Bytes/s per module and in total, both
   directions, frames included (header 32 B, tag 16 B, CBOR payload, not counting
   UDP/IP's 28 B), compared with the FreeSN paper's "approximately 60 kbits s^-1 at
   maximum" for this system (section 7). Latency: wall time from sending a command to
   receiving the first report that acknowledges it (the module applies it at its next
   tick, steps, reports), so it includes waiting for that tick (0..100 ms at 10 Hz).
2. **Success vs packet loss**: ``platform run``'s own functions over the link with the
   emulator losing each datagram (either way) with probability 0, 1 %, 5 %, 20 %: the
   FreeSN ``s6n3-connect`` scenario, ``--runs`` seeds per level; with ``--mmrp`` also
   MMRP cross -> probe once per level (at ``--speed``, about a minute each).

Usage: ``python benchmarks/link.py [--seed N] [--seconds 5] [--runs 5] [--mmrp]``.
The emulator runs as ``platform emulate`` in a second process (as a lab would run
it); all traffic stays on 127.0.0.1. Prints the seed and three tables.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import click
import numpy as np

from msrr.core import plugins
from msrr.core.app.run import RunRequest, execute_run, prepare_run, resolve_scenario
from msrr.core.console import console, table
from msrr.core.driver import ModuleCommand
from msrr.core.link import LinkDriver

ROOT = Path(__file__).resolve().parents[1]
PAPER_BITS = 60_000
"""The FreeSN paper's bandwidth of the computer at maximum [bit/s] (section 7)."""


@contextmanager
def emulated(robot: str, start_path: Path, folder: Path, *, faults: str = "", seed: int = 0,
             speed: float = 1.0, timeout: float = 1.0) -> Iterator[Path]:
    """``platform emulate`` of ``start_path`` in its own process; yields the systems file
    once written, and ends the emulator with SIGINT (as Ctrl-C) afterwards."""
    system = folder / "system.json"
    system.unlink(missing_ok=True)
    command = [sys.executable, "-c", "from msrr.core.app.cli import main; main()", "emulate",
               "--robot", robot, str(start_path), "--system-out", str(system), "--seed",
               str(seed), "--speed", str(speed), "--timeout", str(timeout), "--duration",
               "3600"] + (["--faults", faults] if faults else [])
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        end = time.monotonic() + 60.0
        while not system.exists():
            if process.poll() is not None or time.monotonic() > end:
                raise RuntimeError(f"emulator did not start: {process.stderr.read().decode()}")
            time.sleep(0.05)
        yield system
    finally:
        process.send_signal(signal.SIGINT)
        try:
            process.wait(10.0)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(5.0)


def _hold(report: dict | None) -> ModuleCommand | None:
    """A strut's hold command from its report: each docked end toward where it is."""
    sensors = (report or {}).get("sensors")
    attitude = getattr(sensors, "attitude", None)
    if not attitude:
        return None
    joints = {}
    for end, rotation in attitude.items():
        for axis, value in zip("xyz", np.asarray(rotation)[:, 2], strict=True):
            joints[f"{end}.dir_{axis}"] = float(value)
        for axis, value in zip("xyz", np.asarray(rotation)[:, 0], strict=True):
            joints[f"{end}.fwd_{axis}"] = float(value)
    return ModuleCommand(joints=joints)


def bandwidth(folder: Path, seconds: float, seed: int) -> None:
    start = next((ROOT / "plugins/freesn/configs").rglob("S12N6-1.1.json"))
    kinds = plugins.load_configuration(start).modules()
    with emulated("freesn", start, folder, seed=seed) as system:
        driver = LinkDriver(system=system, robot="freesn")
        with driver:
            driver.reset(plugins.load_configuration(start))
            before = {m: list(v) for m, v in driver.bytes_by_module.items()}
            driver.latencies.clear()
            ticks = round(seconds * 10)
            t0 = time.monotonic()
            for _ in range(ticks):
                commands = {m: c for m, module in driver.modules.items()
                            if (c := _hold(module.report)) is not None}
                driver.send_action(commands)
                driver.step(0.1)
            elapsed = time.monotonic() - t0
            latencies = np.array(driver.latencies) * 1000
            rows, total = [], 0.0
            for module, (out, into) in driver.bytes_by_module.items():
                down = (out - before[module][0]) / elapsed
                up = (into - before[module][1]) / elapsed
                total += down + up
                rows.append((module, down, up))
    struts = [r for r in rows if kinds[r[0]] == "strut"]
    nodes = [r for r in rows if kinds[r[0]] != "strut"]
    out = []
    for label, group in (("strut (mean of 12)", struts), ("node (mean of 6)", nodes)):
        down = float(np.mean([r[1] for r in group]))
        up = float(np.mean([r[2] for r in group]))
        out.append([label, f"{down:.0f}", f"{up:.0f}", f"{(down + up) * 8 / 1000:.1f}"])
    out.append(["all 18 modules", f"{sum(r[1] for r in rows):.0f}",
                f"{sum(r[2] for r in rows):.0f}", f"{total * 8 / 1000:.1f}"])
    out.append(["FreeSN paper (section 7), at most", "", "", f"{PAPER_BITS / 1000:.0f}"])
    console.print(table(f"Bandwidth at 10 Hz, 18 FreeSN modules, {elapsed:.1f} s",
                        ["", "host -> module [B/s]", "module -> host [B/s]", "kbit/s"], out))
    console.print(table("Latency: command sent -> report acknowledging it",
                        ["commands", "mean [ms]", "median [ms]", "95 % [ms]", "max [ms]"],
                        [[len(latencies), f"{latencies.mean():.1f}",
                          f"{np.median(latencies):.1f}",
                          f"{np.percentile(latencies, 95):.1f}", f"{latencies.max():.1f}"]]))


def one_run(robot: str, scenario: str | None, start: Path | None, goal: Path | None,
            loss: float, seed: int, speed: float, folder: Path) -> tuple[bool, str, float]:
    where = resolve_scenario(robot, scenario) if scenario else None
    start_path = where.start if where else start
    assert start_path is not None
    faults = f"loss:p={loss:g}" if loss else ""
    with emulated(robot, start_path, folder, faults=faults, seed=seed, speed=speed) as system:
        request = RunRequest(robot, scenario=scenario, start=None if where else start,
                             goal=None if where else goal, seed=seed, log=False,
                             out=folder / "run", force=True, driver="link",
                             driver_options=(("system", str(system)),))
        t0 = time.monotonic()
        result = execute_run(prepare_run(request))
        return result.success, result.reason, time.monotonic() - t0


def loss_table(folder: Path, runs: int, seed: int, mmrp: bool, speed: float) -> bool:
    cases = [("freesn s6n3-connect", "freesn", "s6n3-connect", None, None, runs, 1.0)]
    if mmrp:
        configs = ROOT / "plugins/mmrp/configs"
        cases.append(("mmrp cross -> probe", "mmrp", None, configs / "cross.json",
                      configs / "probe.json", 1, speed))
    rows, ok = [], True
    for label, robot, scenario, start, goal, count, pace in cases:
        for loss in (0.0, 0.01, 0.05, 0.20):
            outcomes, reasons, walls = [], [], []
            for k in range(count):
                success, reason, wall = one_run(robot, scenario, start, goal, loss, seed + k,
                                                pace, folder)
                outcomes.append(success)
                walls.append(wall)
                if not success:
                    reasons.append(reason)
            if loss <= 0.05 and not all(outcomes):
                ok = False
            rows.append([label, f"{loss:.0%}", f"{sum(outcomes)}/{count}",
                         f"{np.mean(walls):.1f}", (reasons[0][:90] if reasons else "-")])
    console.print(table("Run success vs packet loss (each datagram, both ways)",
                        ["run", "loss", "succeeded", "wall [s]", "first failure"], rows))
    return ok


@click.command()
@click.option("--seed", default=0, show_default=True, help="Seed of the faults and runs.")
@click.option("--seconds", default=5.0, show_default=True, help="Length of the bandwidth test.")
@click.option("--runs", default=5, show_default=True, help="Seeds per loss level (FreeSN).")
@click.option("--mmrp", is_flag=True, help="Also MMRP cross -> probe once per loss level.")
@click.option("--speed", default=5.0, show_default=True, help="Emulator speed of MMRP runs.")
def main(seed: int, seconds: float, runs: int, mmrp: bool, speed: float) -> None:
    console.print(f"seed={seed}")
    with tempfile.TemporaryDirectory() as folder:
        bandwidth(Path(folder), seconds, seed)
        ok = loss_table(Path(folder), runs, seed, mmrp, speed)
    if not ok:
        raise SystemExit(1)


if __name__ == "__main__":
    main()
