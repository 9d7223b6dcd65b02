"""The module link measured on loopback (issues 15 and 26): bandwidth, latency, loss.

1. **Bandwidth** of the 18 modules of FreeSN S12N6 (12 struts, 6 nodes) emulated in
   MuJoCo at 10 Hz in real time by ``platform emulate --budget 60 --timeout 2`` (the
   FreeSN paper's "approximately 60 kbits s^-1 at maximum", section 7), counted on the
   host's socket: every datagram's bytes plus its 28 bytes of UDP/IPv4 header, per second
   of system time, both ways. Two workloads:

   * *at rest*: S12N6-1.1 for ``--seconds`` s, every strut commanded every tick to hold
     (an empty command keeps its targets), every node stopped;
   * *walking*: the ``fig19-crawl-s12n6`` scenario (a trot of all 18 modules: 16
     connection vectors new every tick) run by ``platform run``'s own functions over the
     link, measured from its first to its last tick.

   The host polls the modules' reports to keep the budget (at most every
   ``timeout / (4 periods)`` control periods, so three lost reports in a row never trip
   the silence timeout); the table says how far apart, and the mean bytes of a datagram
   each way (a COMMAND frame; a REPORT).
2. **Latency** at rest: wall time from sending a command to receiving the first report
   that acknowledges it (includes the wait for the poll and the module's tick).
3. **Success vs packet loss**: ``platform run``'s functions over the link with the
   emulator losing each datagram, either way, with probability 0, 1 %, 5 %, 20 %, under
   the same budget and timeout (``--no-budget-loss``: none, timeout 1 s), with the
   modules' default watchdog (3 control periods) and at 20 % also with a watchdog of 5
   (``watchdog_s: 0.5`` in the systems file): FreeSN ``s6n3-connect`` and
   ``fig19-crawl-s12n6``, ``--runs`` seeds per level; with ``--mmrp`` also MMRP cross ->
   probe once per level (at ``--speed``).

Usage: ``python benchmarks/link.py [--seed N] [--seconds 10] [--runs 3] [--mmrp]``.
The emulator runs as ``platform emulate`` in a second process (as a lab would run it);
all traffic stays on 127.0.0.1. Prints the seed and three tables; exits 1 if a workload
exceeds the budget, the walking run fails, or a run at up to 5 % loss fails.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import click
import numpy as np

from msrr.core import plugins
from msrr.core.app.run import RunRequest, execute_run, prepare_run, resolve_scenario
from msrr.core.console import console, table
from msrr.core.driver import ModuleCommand
from msrr.core.link import LinkDriver
from msrr.core.link.protocol import UDP_IP_BYTES

ROOT = Path(__file__).resolve().parents[1]
PAPER_KBITS = 60.0
"""The FreeSN paper's bandwidth of the computer at maximum [kbit/s] (section 7)."""
TIMEOUT = 2.0
"""The modules' timeout under the budget [s]: reports up to 5 periods apart."""
LEVELS = ((0.0, None), (0.01, None), (0.05, None), (0.20, None), (0.20, 0.5))
"""Loss levels of the success table, each with the modules' watchdog [s] (``None``: the
default, 3 control periods)."""


@contextmanager
def emulated(robot: str, start_path: Path, folder: Path, *, faults: str = "", seed: int = 0,
             speed: float = 1.0, timeout: float = 1.0, budget: float | None = None,
             watchdog: float | None = None) -> Iterator[Path]:
    """``platform emulate`` of ``start_path`` in its own process; yields the systems file
    once written (with ``watchdog_s`` set to ``watchdog``, as a lab would edit it), and
    ends the emulator with SIGINT (as Ctrl-C) afterwards."""
    system = folder / "system.json"
    system.unlink(missing_ok=True)
    command = [sys.executable, "-c", "from msrr.core.app.cli import main; main()", "emulate",
               "--robot", robot, str(start_path), "--system-out", str(system), "--seed",
               str(seed), "--speed", str(speed), "--timeout", str(timeout), "--duration",
               "3600"] + (["--faults", faults] if faults else []) + (
               ["--budget", str(budget)] if budget is not None else [])
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        end = time.monotonic() + 60.0
        while not system.exists():
            if process.poll() is not None or time.monotonic() > end:
                raise RuntimeError(f"emulator did not start: {process.stderr.read().decode()}")
            time.sleep(0.05)
        if watchdog is not None:
            text = json.loads(system.read_text())
            system.write_text(json.dumps({**text, "watchdog_s": watchdog}))
        yield system
    finally:
        process.send_signal(signal.SIGINT)
        try:
            process.wait(10.0)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(5.0)


@dataclass
class Traffic:
    """What crossed the host's socket between two instants, per second of system time."""

    down: float  # host -> modules [B/s], UDP/IP included
    up: float
    datagrams_down: float
    datagrams_up: float
    every: int

    @property
    def kbits(self) -> float:
        return (self.down + self.up) * 8 / 1000


def _traffic(before: dict[str, int], after: dict[str, int], seconds: float, every: int
             ) -> Traffic:
    d = {k: after[k] - before[k] for k in after}
    return Traffic((d["sent"] + UDP_IP_BYTES * d["datagrams_sent"]) / seconds,
                   (d["received"] + UDP_IP_BYTES * d["datagrams_received"]) / seconds,
                   d["datagrams_sent"] / seconds, d["datagrams_received"] / seconds, every)


def at_rest(folder: Path, seconds: float, seed: int, budget: float
            ) -> tuple[Traffic, np.ndarray]:
    """S12N6-1.1 held for ``seconds`` s: the traffic and the latencies [ms]."""
    start = next((ROOT / "plugins/freesn/configs").rglob("S12N6-1.1.json"))
    config = plugins.load_configuration(start)
    struts = [m for m, kind in config.modules().items() if kind == "strut"]
    with emulated("freesn", start, folder, seed=seed, timeout=TIMEOUT,
                  budget=budget) as system, LinkDriver(system=system, robot="freesn") as driver:
        driver.reset(config)
        for _ in range(30):  # the budget settles
            driver.send_action({m: ModuleCommand() for m in struts})
            driver.step(0.1)
        before, t0 = dict(driver.traffic), driver.time
        driver.latencies.clear()
        for _ in range(round(seconds * 10)):
            driver.send_action({m: ModuleCommand() for m in struts})
            driver.step(0.1)
        traffic = _traffic(before, driver.traffic, driver.time - t0, driver.every)
        return traffic, np.array(driver.latencies) * 1000


@contextmanager
def _watched() -> Iterator[list[tuple[dict[str, int], float, int]]]:
    """The link driver's socket counters when each run's first tick is sent and when it
    disconnects (``platform run`` builds its driver itself)."""
    marks: list[tuple[dict[str, int], float, int]] = []
    reset, disconnect = LinkDriver.reset, LinkDriver.disconnect

    def watched_reset(self: LinkDriver, start) -> None:
        reset(self, start)
        marks.append((dict(self.traffic), self.time, self.every))

    def watched_disconnect(self: LinkDriver) -> None:
        if self.is_connected:
            marks.append((dict(self.traffic), self.time, self.every))
        disconnect(self)

    LinkDriver.reset, LinkDriver.disconnect = watched_reset, watched_disconnect
    try:
        yield marks
    finally:
        LinkDriver.reset, LinkDriver.disconnect = reset, disconnect


def one_run(robot: str, scenario: str | None, start: Path | None, goal: Path | None,
            folder: Path, *, loss: float = 0.0, seed: int = 0, speed: float = 1.0,
            budget: float | None = None, timeout: float = 1.0, watchdog: float | None = None
            ) -> tuple[bool, str, float, Traffic | None]:
    """One ``platform run`` over the link: success, reason, wall time, traffic."""
    where = resolve_scenario(robot, scenario) if scenario else None
    start_path = where.start if where else start
    assert start_path is not None
    faults = f"loss:p={loss:g}" if loss else ""
    with emulated(robot, start_path, folder, faults=faults, seed=seed, speed=speed,
                  budget=budget, timeout=timeout, watchdog=watchdog) as system, \
            _watched() as marks:
        request = RunRequest(robot, scenario=scenario, start=None if where else start,
                             goal=None if where else goal, seed=seed, log=False,
                             out=folder / "run", force=True, driver="link",
                             driver_options=(("system", str(system)),))
        t0 = time.monotonic()
        result = execute_run(prepare_run(request))
        wall = time.monotonic() - t0
    traffic = None
    if len(marks) >= 2 and marks[-1][1] > marks[0][1]:
        (before, t_start, _), (after, t_end, every) = marks[0], marks[-1]
        traffic = _traffic(before, after, t_end - t_start, every)
    return result.success, result.reason, wall, traffic


def bandwidth(folder: Path, seconds: float, seed: int, budget: float) -> bool:
    rest, latencies = at_rest(folder, seconds, seed, budget)
    success, reason, _, moving = one_run("freesn", "fig19-crawl-s12n6", None, None, folder,
                                         seed=seed, budget=budget, timeout=TIMEOUT)
    rows = []
    for label, traffic in (("at rest (S12N6-1.1, struts held)", rest),
                           (f"walking (fig19-crawl-s12n6{'' if success else ', failed'})",
                            moving)):
        if traffic is None:
            rows.append([label, "-", "-", "-", "-", "-", "-", reason[:60]])
            continue
        rows.append([label, f"{traffic.down:.0f}", f"{traffic.up:.0f}",
                     f"{traffic.datagrams_down:.0f} / {traffic.datagrams_up:.0f}",
                     f"{traffic.down / traffic.datagrams_down:.0f} / "
                     f"{traffic.up / traffic.datagrams_up:.0f}",
                     f"{traffic.every}", f"{traffic.kbits:.1f}",
                     "yes" if traffic.kbits <= PAPER_KBITS else "no"])
    if not success:
        console.print(f"the walking run failed: {reason}", markup=False)
    console.print(table(
        f"Bandwidth of 18 FreeSN modules at 10 Hz on the host's socket (UDP/IP included; "
        f"budget {budget:g} kbit/s, timeout {TIMEOUT:g} s)",
        ["workload", "host -> modules [B/s]", "modules -> host [B/s]", "datagrams/s",
         "bytes/datagram", "reports every [periods]", "kbit/s", f"<= {PAPER_KBITS:g}"], rows))
    console.print(table("Latency at rest: command sent -> report acknowledging it",
                        ["commands", "mean [ms]", "median [ms]", "95 % [ms]", "max [ms]"],
                        [[len(latencies), f"{latencies.mean():.1f}",
                          f"{np.median(latencies):.1f}", f"{np.percentile(latencies, 95):.1f}",
                          f"{latencies.max():.1f}"]] if len(latencies) else [[0] + ["-"] * 4]))
    return success and moving is not None and all(
        t.kbits <= PAPER_KBITS for t in (rest, moving))


def loss_table(folder: Path, runs: int, seed: int, mmrp: bool, speed: float,
               budget: float | None) -> bool:
    cases = [("freesn s6n3-connect", "freesn", "s6n3-connect", None, None, runs, 1.0),
             ("freesn fig19-crawl-s12n6", "freesn", "fig19-crawl-s12n6", None, None, runs, 1.0)]
    if mmrp:
        configs = ROOT / "plugins/mmrp/configs"
        cases.append(("mmrp cross -> probe", "mmrp", None, configs / "cross.json",
                      configs / "probe.json", 1, speed))
    timeout = TIMEOUT if budget is not None else 1.0
    rows, ok, failures = [], True, []
    for label, robot, scenario, start, goal, count, pace in cases:
        for loss, watchdog in LEVELS:
            outcomes, reasons, walls, rates = [], [], [], []
            for k in range(count):
                success, reason, wall, traffic = one_run(
                    robot, scenario, start, goal, folder, loss=loss, seed=seed + k, speed=pace,
                    budget=budget, timeout=timeout, watchdog=watchdog)
                outcomes.append(success)
                walls.append(wall)
                if traffic is not None:
                    rates.append(traffic.kbits)
                if not success:
                    reasons.append(reason)
                    failures.append(f"{label} at {loss:.0%}, seed {seed + k}: {reason}")
            if loss <= 0.05 and not all(outcomes):
                ok = False
            rows.append([label, f"{loss:.0%}",
                         "3 periods" if watchdog is None else f"{watchdog:g} s",
                         f"{sum(outcomes)}/{count}", f"{np.mean(walls):.1f}",
                         f"{max(rates):.1f}" if rates else "-",
                         (reasons[0][:80] if reasons else "-")])
    console.print(table(
        "Run success vs packet loss (each datagram, both ways; "
        + (f"budget {budget:g} kbit/s, timeout {timeout:g} s)" if budget is not None
           else f"no budget, timeout {timeout:g} s)"),
        ["run", "loss", "watchdog", "succeeded", "wall [s]", "kbit/s (largest)",
         "first failure"], rows))
    for failure in failures:
        console.print(failure, markup=False)
    return ok


@click.command()
@click.option("--seed", default=0, show_default=True, help="Seed of the faults and runs.")
@click.option("--seconds", default=10.0, show_default=True, help="Length of the run at rest.")
@click.option("--runs", default=3, show_default=True, help="Seeds per loss level (FreeSN).")
@click.option("--mmrp", is_flag=True, help="Also MMRP cross -> probe once per loss level.")
@click.option("--speed", default=5.0, show_default=True, help="Emulator speed of MMRP runs.")
@click.option("--budget", default=PAPER_KBITS, show_default=True,
              help="The systems file's budget [kbit/s] of every run.")
@click.option("--no-budget-loss", is_flag=True,
              help="Run the loss table without a budget (timeout 1 s), as before issue 26.")
@click.option("--no-loss", is_flag=True, help="Only the bandwidth and latency tables.")
def main(seed: int, seconds: float, runs: int, mmrp: bool, speed: float, budget: float,
         no_budget_loss: bool, no_loss: bool) -> None:
    console.print(f"seed={seed}")
    with tempfile.TemporaryDirectory() as folder:
        ok = bandwidth(Path(folder), seconds, seed, budget)
        if not no_loss:
            ok = loss_table(Path(folder), runs, seed, mmrp, speed,
                            None if no_budget_loss else budget) and ok
    if not ok:
        raise SystemExit(1)


if __name__ == "__main__":
    main()
