"""The link end to end on 127.0.0.1: emulated tiny-robot modules (backed by the tiny
robot's own PointDriver) driven by ``platform run``'s machinery with ``--driver link``;
a module that drops out, a wrong key, and a host killed mid-run. Every wait is bounded
(a few seconds at most) and all traffic stays on loopback."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
import textwrap
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from click.testing import CliRunner
from tiny_robot import LinkRecognizer, PointDriver, chain, installed

from msrr.core import save_configuration
from msrr.core.app.cli import get_cli
from msrr.core.app.run import RUN_FILES, RunRequest, execute_run, prepare_run, write_outputs
from msrr.core.driver import ModuleCommand
from msrr.core.errors import ExecutionError
from msrr.core.link import Emulator, KeyRef, LinkDriver, parse_link_faults, write_key, write_system

SPEED = 5.0  # module seconds per wall second


@contextmanager
def emulating(folder: Path, faults: str = "", *, speed: float = SPEED, timeout: float = 1.0,
              start=None, budget: float | None = None) -> Iterator[tuple[Emulator, Path]]:
    """Emulated modules of ``start`` (a-b docked, c apart) serving in a thread."""
    emulator = Emulator(PointDriver, start or chain(("a", "b"), name="ab"),
                        recognizer=LinkRecognizer(), rate=10.0, speed=speed,
                        faults=parse_link_faults(faults), timeout=timeout, budget=budget)
    stop = threading.Event()
    with emulator:
        write_key(folder / "system.key", emulator.key)
        path = write_system(folder / "system.json",
                            emulator.system_file(KeyRef(file="system.key"), "tiny"))
        thread = threading.Thread(target=emulator.serve, kwargs={"duration": 60.0,
                                                                 "stop": stop.is_set})
        thread.start()
        try:
            yield emulator, path
        finally:
            stop.set()
            thread.join(5.0)
            assert not thread.is_alive()


def _until(condition, seconds: float = 4.0) -> bool:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if condition():
            return True
        time.sleep(0.005)
    return condition()


def _request(tmp_path: Path, system: Path, **options) -> RunRequest:
    start, goal = tmp_path / "start.json", tmp_path / "goal.json"
    save_configuration(chain(("a", "b"), name="ab"), start)
    save_configuration(options.pop("goal", chain(("b", "c"), name="bc")), goal)
    return RunRequest(robot="tiny", start=start, goal=goal, out=tmp_path / "run",
                      driver="link", driver_options=(("system", str(system)),), **options)


def test_a_run_over_the_link_reaches_the_topology_of_the_direct_simulation(tmp_path) -> None:
    with installed(), emulating(tmp_path) as (emulator, system):
        prepared = prepare_run(_request(tmp_path, system, log=False))
        assert prepared.driver.name == "link" and prepared.run.driver == "link"
        result = execute_run(prepared)
        assert result.success, result.reason
        assert (result.docks, result.undocks) == (1, 1)
        link_world = emulator.driver.links  # the emulated modules' own simulator
        direct = execute_run(prepare_run(RunRequest(
            robot="tiny", start=tmp_path / "start.json", goal=tmp_path / "goal.json",
            out=tmp_path / "direct", log=False)))
        assert direct.success and (direct.docks, direct.undocks) == (1, 1)
        assert link_world == {frozenset({("b", "T"), ("c", "B")})}
        stats = emulator.stats()
        assert all(s.received > 0 and s.sent > 0 and not s.refused for s in stats.values())
        assert not any(e.link.trips for e in emulator.modules.values())  # BYE, not watchdog


def test_a_module_that_drops_out_stops_the_run_within_its_timeout(tmp_path) -> None:
    # a travels 0 -> 3 m at 1 m/s (3 s of module time); b stops answering at 1 s
    with installed(), emulating(tmp_path, "dropout:module=b,at=1", speed=2.5,
                                timeout=0.5) as (emulator, system):
        prepared = prepare_run(_request(tmp_path, system, goal=chain(("c", "a"), name="ca")))
        result = execute_run(prepared)
        write_outputs(prepared.run, result)  # as platform run does
    assert not result.success
    assert "module b silent for" in result.reason and "timeout 0.5 s" in result.reason
    assert "\n" not in result.reason and result.failed_action is not None
    silent = float(result.reason.split("silent for ")[1].split(" s")[0])
    assert 0.5 < silent <= 0.5 + 0.1 + 1e-9  # stopped at the first step past the timeout
    assert sorted(p.name for p in (tmp_path / "run").iterdir()) == sorted(RUN_FILES)
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["success"] is False and summary["driver"] == "link"


@pytest.mark.parametrize(("fault", "words"), [
    ("disobey:module=a,at=2", "module a received commands"),
    ("stall:module=a,at=2", "module a reports its motors stopped while commanded")])
def test_a_module_that_stops_obeying_or_stops_its_motors_stops_the_run_within_three_periods(
        tmp_path, fault, words) -> None:
    # a travels 0 -> 3 m at 1 m/s; from 2 s (module time: the run is under way) it stops
    # applying commands, or its motors stop, while it keeps reporting: the host stops the
    # run within three control periods
    with installed(), emulating(tmp_path, fault, speed=2.5, timeout=2.0) as (emulator, system):
        link = emulator.modules["a"].link
        ended: list[float] = []
        handle = link.handle

        def tapped(datagram, address, clock):
            result = handle(datagram, address, clock)
            if result is None and datagram[0] & 0x0F == 6 and not ended:  # its BYE
                ended.append(clock)
            return result

        link.handle = tapped
        prepared = prepare_run(_request(tmp_path, system, goal=chain(("c", "a"), name="ca")))
        result = execute_run(prepared)
        write_outputs(prepared.run, result)
    assert not result.success and words in result.reason, result.reason
    assert "\n" not in result.reason and result.reason.endswith("run stopped")
    assert ended and 2.0 < ended[0] <= 2.0 + 0.1 + 3 * 0.1 + 0.05  # first tick + 3 periods
    assert sorted(p.name for p in (tmp_path / "run").iterdir()) == sorted(RUN_FILES)


def test_datagrams_are_timed_when_they_arrived_not_when_they_are_read() -> None:
    from msrr.core.link.transport import drain, udp_socket

    first, second = udp_socket("127.0.0.1"), udp_socket("127.0.0.1")
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    with first, second, sender:
        sender.sendto(b"1", first.getsockname())
        time.sleep(0.05)
        sender.sendto(b"2", second.getsockname())
        time.sleep(0.1)
        read = time.monotonic()
        (_, _, later), = drain(second)  # read first, arrived second
        (_, _, earlier), = drain(first)
    assert earlier < later - 0.03 and later < read - 0.05


def test_a_wrong_key_is_refused_and_counted_on_both_sides(tmp_path) -> None:
    with installed(), emulating(tmp_path, "wrong-key:module=c") as (emulator, system):
        driver = LinkDriver(system=system, robot="tiny", handshake=0.5)
        with pytest.raises(ExecutionError, match=r"^module c \(127\.0\.0\.1:\d+\) did not "
                                                 r"answer the handshake within 0\.5 s"):
            driver.connect()
        assert not driver.is_connected
        assert emulator.modules["c"].link.stats.refused["bad_tag"] >= 1
        assert not emulator.modules["c"].link.seen  # it never answered this host
        assert emulator.modules["a"].link.seen  # the others did (then BYE)


HOST = textwrap.dedent("""
    import sys
    from msrr.core.driver import ModuleCommand
    from msrr.core.link import LinkDriver
    driver = LinkDriver(system=sys.argv[1])
    driver.connect()
    while True:
        driver.send_action({"a": ModuleCommand(wheels={"v": 0.2})})
        driver.step(0.1)
""")


def test_killing_the_host_stops_the_motors_within_the_watchdog(tmp_path) -> None:
    with emulating(tmp_path, speed=2.0, timeout=2.0) as (emulator, system):
        host = subprocess.Popen([sys.executable, "-c", HOST, str(system)],
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        try:
            link = emulator.modules["a"].link
            assert _until(lambda: emulator.driver.speed.get("a") == pytest.approx(0.2), 8.0), \
                host.stderr.read1().decode() if host.poll() is not None else "no command"
            host.kill()
            host.wait(5.0)
            assert _until(lambda: bool(link.trips), 3.0)
            trip, = link.trips
            watchdog = link.watchdog
            assert watchdog == pytest.approx(0.3)  # 3 control periods of the host
            assert trip.previous - trip.last <= watchdog + 1e-9 < trip.at - trip.last
            assert _until(lambda: "a" not in emulator.driver.speed, 1.0)  # motors stopped
        finally:
            if host.poll() is None:
                host.kill()
                host.wait(5.0)


@pytest.mark.parametrize("faults", ["loss:p=0.05", "latency:ms=30,jitter=20",
                                    "reboot:module=b,at=1,for=0.2"])
def test_runs_survive_loss_latency_and_a_reboot(tmp_path, faults) -> None:
    # loss and latency: the swap (nothing travels, so a command held one period late by
    # the fault moves nothing: the outcome cannot depend on when packets arrive);
    # reboot: b (standing) reboots while a travels 3 m
    reboot = faults.startswith("reboot")
    goal = chain(("c", "a"), name="ca") if reboot else chain(("b", "c"), name="bc")
    # a silence timeout of 2 s, ten times the reboot's: at 1 s a loaded machine's stalled
    # emulator thread tripped it (module a silent 1.10 s, stop 51's CI beside a simulation)
    with installed(), emulating(tmp_path, faults, timeout=2.0) as (emulator, system):
        result = execute_run(prepare_run(_request(tmp_path, system, log=False, goal=goal)))
        assert result.success, result.reason
        want = [("c", "T"), ("a", "B")] if reboot else [("b", "T"), ("c", "B")]
        assert emulator.driver.links == {frozenset(want)}
        if reboot:
            assert emulator.modules["b"].link.boots == 2  # and the host linked it again
        elif faults.startswith("loss"):
            assert emulator.dropped > 0


def test_platform_emulate_writes_the_systems_file_and_platform_run_drives_it(tmp_path) -> None:
    save_configuration(chain(("a", "b"), name="ab"), tmp_path / "ab.json")
    system = tmp_path / "out" / "system.json"
    with installed():
        result = CliRunner().invoke(get_cli(), [
            "emulate", "--robot", "tiny", str(tmp_path / "ab.json"), "--system-out", str(system),
            "--duration", "0.3", "--speed", "3", "--faults", "loss:p=0.1"])
        assert result.exit_code == 0, result.output
        assert "3 emulated tiny modules (points) on 127.0.0.1" in result.output
        assert "loss:p=0.1" in result.output and "watchdog stops" in result.output
        key = system.with_suffix(".key")
        assert key.stat().st_mode & 0o077 == 0 and key.read_text().strip() not in system.read_text()
        assert json.loads(system.read_text())["key"] == {"file": "system.key"}
        bad = CliRunner().invoke(get_cli(), ["emulate", "--robot", "tiny", str(tmp_path / "ab.json"),
                                             "--faults", "dropout:module=z"])
        assert bad.exit_code == 1 and "no module 'z'" in bad.output
        with emulating(tmp_path) as (_emulator, path):
            save_configuration(chain(("b", "c"), name="bc"), tmp_path / "bc.json")
            run = CliRunner().invoke(get_cli(), [
                "run", "--robot", "tiny", "--from", str(tmp_path / "ab.json"), "--to",
                str(tmp_path / "bc.json"), "--system", str(path), "--no-log", "--out",
                str(tmp_path / "run")], terminal_width=200)
        assert run.exit_code == 0, run.output
        assert "driver link" in run.output


def test_under_a_budget_the_host_polls_all_modules_at_once_and_keeps_within_it(tmp_path) -> None:
    # 3 modules at 10 Hz carry about 30 kbit/s with a report every period; 18 kbit/s makes
    # the host poll every few periods (at most 5 with a 2 s timeout), all three at once
    with installed(), emulating(tmp_path, timeout=2.0, budget=18.0) as (emulator, system):
        reports: list[tuple[float, str]] = []
        with LinkDriver(system=system, robot="tiny") as driver:
            handle = driver._report

            def tapped(module, header, data, arrival):
                handle(module, header, data, arrival)
                reports.append((round(driver.time, 1), module.entry.id))

            driver._report = tapped
            driver.reset(chain(("a", "b"), name="ab"))
            before, start = dict(driver.traffic), driver.time
            reports.clear()
            for _ in range(120):  # 12 s of module time: enough whole polls that one
                # datagram late under a loaded CPU (a poll split in two) leaves 80 % whole
                driver.send_action({"a": ModuleCommand(wheels={"v": 0.1})})
                driver.step(0.1)
            seconds = driver.time - start
            sent = {k: driver.traffic[k] - before[k] for k in before}
            every = driver.every
    kbits = 8 * (sent["sent"] + sent["received"] + 28 * (sent["datagrams_sent"]
                                                        + sent["datagrams_received"]))
    assert 2 <= every <= 5 and kbits / seconds / 1000 <= 18.0
    ticks: dict[float, set[str]] = {}  # instants, keyed by their first arrival
    settled = reports[len(reports) // 2][0]  # once the spacing settled: whole ticks after it
    for at, module in sorted(r for r in reports if r[0] > settled):
        # one poll's answers are timed by arrival: a datagram may land one control
        # period (0.1 s) after the others, still the same instant of the robot
        first = max((t for t in ticks if at - t <= 0.1 + 1e-9), default=at)
        ticks.setdefault(first, set()).add(module)
    # the window's first and last instants may be cut by its edges (a poll answered
    # partly before the cut, or after the last step): whole polls only
    whole = [ticks[t] for t in sorted(ticks)][1:-1]
    together = sum(len(m) == 3 for m in whole)
    assert len(whole) >= 3 and together >= 0.8 * len(whole), ticks  # one instant
