"""``platform emulate``: emulated modules on loopback for ``platform run --driver link``."""

from __future__ import annotations

import math
import os
from pathlib import Path

import click

from ... import plugins
from ...console import SEED, FiniteFloat, console, err_console, plural, table
from ...errors import ConfigurationError
from ...interrupts import Interrupted, handled

__all__ = ["command"]


@click.command("emulate")
@click.option("--robot", required=True, help="Robot name (see `platform robots`).")
@click.argument("config", type=click.Path(path_type=Path))
@click.option("--faults", default="", metavar="SPEC",
              help="Link faults, e.g. 'loss:p=0.05;latency:ms=20,jitter=5;dropout:module=3,"
                   "at=2;reboot:module=4,at=3,for=0.5;wrong-key:module=5' (docs/hardware.md).")
@click.option("--system-out", "system_out", type=click.Path(path_type=Path),
              default=Path("system.json"), show_default=True,
              help="Where to write the systems file (the key goes to FILE's .key sibling).")
@click.option("--key-env", default=None, metavar="NAME",
              help="Take the site key (hex) from environment variable NAME; no key file is "
                   "written.")
@click.option("--rate", type=FiniteFloat(0, 1000, open_low=True), default=10.0, show_default=True,
              help="Control rate of the modules [Hz]; the watchdog is 3 periods.")
@click.option("--speed", type=FiniteFloat(0, 100, open_low=True), default=1.0, show_default=True,
              help="Module time per wall time (1: real time, at most 100).")
@click.option("--timeout", type=FiniteFloat(0, open_low=True), default=1.0, show_default=True,
              help="Silence timeout of each module written to the systems file [s].")
@click.option("--budget", type=FiniteFloat(0, open_low=True), default=None, metavar="KBPS",
              help="Link budget written to the systems file [kbit/s, UDP/IP included]: the "
                   "host spaces reports to stay within it (the FreeSN paper: 60); default: "
                   "none, a report every period.")
@click.option("--duration", type=FiniteFloat(0, open_low=True), default=None,
              help="Stop after this much module time [s]; default: until Ctrl-C.")
@click.option("--seed", type=SEED, default=0, show_default=True, help="Seed of the faults and simulator.")
@click.option("--driver-option", "driver_options", multiple=True, metavar="KEY=VALUE",
              help="Keyword option of the simulator behind the modules, repeatable (FreeSN: "
                   "noise=0.035 [rad], slip=0.05: noisy reports that state their accuracy); "
                   "`platform robots --options`.")
def command(robot: str, config: Path, faults: str, system_out: Path, key_env: str | None,
            rate: float, speed: float, timeout: float, budget: float | None,
            duration: float | None,
            seed: int, driver_options: tuple[str, ...]) -> None:
    """Emulate the modules of CONFIG: one UDP endpoint per module on 127.0.0.1, each
    speaking the link protocol, backed by the robot's simulator (its first driver).

    Writes the systems file, then serves until Ctrl-C (or --duration); drive the
    modules with `platform run --robot ROBOT --system FILE ...` from another shell."""
    from ...files import check_output_place  # pydantic: loads when the command runs
    from ...link.emulator import Emulator, parse_link_faults  # the link loads when it starts
    from ...link.system import KeyRef, new_key, parse_key, write_key, write_system
    from ..run import parse_driver_options

    with handled():
        start = plugins.load_configuration(config)
        if start.robot != robot:
            raise ConfigurationError(f"is a {start.robot!r} configuration, not {robot!r}",
                                     source=str(config))
        spec = parse_link_faults(faults)
        check_output_place(system_out, option="--system-out")
        capabilities = plugins.capabilities(robot)
        factory = capabilities.driver()
        recognizer = capabilities.recognizer(factory.companions.recognizer)
        if key_env is not None:
            if key_env not in os.environ:
                raise ConfigurationError(f"environment variable {key_env} is not set",
                                         field="--key-env")
            key, ref = parse_key(os.environ[key_env], f"${key_env}", "key"), KeyRef(env=key_env)
        else:
            key = new_key()
            key_path = system_out.with_suffix(".key")
            ref = KeyRef(file=key_path.name)
        emulator = Emulator(factory, start, recognizer=recognizer, rate=rate, speed=speed,
                            faults=spec, seed=seed, key=key, timeout=timeout, budget=budget,
                            driver_options=parse_driver_options(driver_options))
        with emulator:
            if key_env is None:
                write_key(key_path, key)
            write_system(system_out, emulator.system_file(ref, robot))
            ports = sorted(e.sock.getsockname()[1] for e in emulator.modules.values())
            console.print(f"{plural(len(ports), f'emulated {robot} module')} ({factory.name}) on 127.0.0.1 "
                          f"ports {ports[0]}-{ports[-1]}, {rate:g} Hz x{speed:g}"
                          + (f", faults {'; '.join(map(str, spec))}" if spec else "")
                          + f"; systems file {system_out}; Ctrl-C to stop", markup=False)
            stopped: Interrupted | None = None
            try:
                emulator.serve(duration if duration is not None else math.inf)
            except Interrupted as exc:
                stopped = exc
            rows = []
            for module, emulated in emulator.modules.items():
                stats, link = emulated.link.stats, emulated.link
                refused = ", ".join(f"{r} {n}" for r, n in sorted(stats.refused.items()))
                rows.append([module, stats.received, stats.sent, refused or "-",
                             len(link.trips), link.boots - 1])
            console.print(table(f"Emulated modules after {emulator.clock:.1f} s",
                                ["module", "frames in", "frames out", "refused",
                                 "watchdog stops", "reboots"], rows))
            for error in emulator.errors[:3]:
                err_console.print(f"note: simulator refused a command: {error}", markup=False)
        if stopped is not None:
            err_console.print(f"stopped ({stopped.name})", markup=False)
            raise SystemExit(stopped.exit_code)
