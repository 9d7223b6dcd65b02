"""A replay attacker on 127.0.0.1: a relay between the host and the emulated modules
records every datagram (HELLO, SETUP, COMMAND, BYE; the attacker has no key), then plays
them back at the modules in every order -- mid-session, after the host was killed with
SIGKILL, after a module rebooted. Nothing replayed is ever obeyed, and no motor runs past
the watchdog once the host is gone. Every wait is bounded; all traffic stays on loopback."""

from __future__ import annotations

import itertools
import random
import select
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
from tiny_robot import LinkRecognizer, PointDriver, chain

from msrr.core.driver import ModuleCommand
from msrr.core.link import (
    Emulator,
    FrameType,
    KeyRef,
    LinkDriver,
    load_system,
    parse_link_faults,
    write_key,
    write_system,
)

SPEED = 2.0  # module seconds per wall second
KINDS = (FrameType.HELLO, FrameType.COMMAND, FrameType.BYE)


class Relay:
    """Forwards the host's datagrams to the modules' real addresses (and their answers
    back), recording what the host sent: the attacker's tap on the network."""

    def __init__(self, targets: dict[tuple[str, int], tuple[str, int]]):
        self.pairs = []  # (front: the host sends here, back: talks to the module, target)
        for target in targets.values():
            front = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            back = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            front.bind(("127.0.0.1", 0))
            back.bind(("127.0.0.1", 0))
            self.pairs.append((front, back, target))
        self.fronts = {target: front.getsockname() for front, _, target in self.pairs}
        self.recorded: list[tuple[FrameType, tuple[str, int], bytes]] = []
        self.host: tuple[str, int] | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        socks = {s: (front, back, target) for front, back, target in self.pairs
                 for s in (front, back)}
        while not self._stop.is_set():
            ready, _, _ = select.select(list(socks), [], [], 0.02)
            for sock in ready:
                front, back, target = socks[sock]
                try:
                    data, address = sock.recvfrom(65536)
                except OSError:
                    continue
                if sock is front:
                    self.host = address
                    self.recorded.append((FrameType(data[0] & 0x0F), target, data))
                    back.sendto(data, target)
                elif self.host is not None:
                    front.sendto(data, self.host)

    def __enter__(self) -> Relay:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(2.0)
        for front, back, _ in self.pairs:
            front.close()
            back.close()


class Tap:
    """What the modules made of each datagram (wraps ``ModuleLink.handle``)."""

    def __init__(self, emulator: Emulator):
        self.results: list[tuple[str, FrameType, tuple[str, int], str | None]] = []
        for emulated in emulator.modules.values():
            link, handle = emulated.link, emulated.link.handle

            def tapped(datagram, address, clock, _link=link, _handle=handle):
                result = _handle(datagram, address, clock)
                self.results.append((_link.module, FrameType(datagram[0] & 0x0F),
                                     tuple(address), result))
                return result

            link.handle = tapped  # type: ignore[method-assign]

    def sent_by(self, address: tuple[str, int]) -> list[tuple[str, FrameType, str | None]]:
        """What the modules made of the datagrams from ``address``."""
        return [(m, kind, result) for m, kind, a, result in self.results if a == address]


@contextmanager
def attacked(folder: Path, *, speed: float = SPEED, faults: str = ""
             ) -> Iterator[tuple[Emulator, Path, Relay, Tap]]:
    """Emulated modules a-b (docked) and c serving in a thread; a systems file whose
    addresses are the relay's, so every host datagram passes the attacker's tap."""
    emulator = Emulator(PointDriver, chain(("a", "b"), name="ab"), recognizer=LinkRecognizer(),
                        rate=10.0, speed=speed, timeout=2.0, faults=parse_link_faults(faults))
    stop = threading.Event()
    with emulator:
        write_key(folder / "system.key", emulator.key)
        real = emulator.system_file(KeyRef(file="system.key"), "tiny")
        targets = {(m.address, m.port): (m.address, m.port) for m in real.modules}
        group = (real.group.address, real.group.port)
        targets[group] = group
        with Relay(targets) as relay:
            fronts = relay.fronts
            tapped = real.model_copy(update={
                "modules": [m.model_copy(update={"port": fronts[(m.address, m.port)][1]})
                            for m in real.modules],
                "group": real.group.model_copy(update={"port": fronts[group][1]})})
            path = write_system(folder / "system.json", tapped)
            tap = Tap(emulator)
            thread = threading.Thread(target=emulator.serve,
                                      kwargs={"duration": 60.0, "stop": stop.is_set})
            thread.start()
            try:
                yield emulator, path, relay, tap
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


def _orders(recorded: list[tuple[FrameType, tuple[str, int], bytes]], seed: int
            ) -> dict[str, list[tuple[FrameType, tuple[str, int], bytes]]]:
    """The recording played back as recorded, reversed, shuffled, and with its HELLO,
    COMMAND and BYE frames grouped in each of the six orders of the three kinds."""
    shuffled = list(recorded)
    random.Random(seed).shuffle(shuffled)
    orders = {"recorded": list(recorded), "reversed": recorded[::-1], "shuffled": shuffled}
    for kinds in itertools.permutations(KINDS):
        name = "-".join(k.name.lower() for k in kinds)
        orders[name] = [r for k in kinds for r in recorded if r[0] is k]
    return orders


def _attacker() -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    return sock


def _replay(frames, attacker: socket.socket, rng: random.Random, *, gap=(0.0, 0.0)) -> None:
    for _, target, data in frames:
        attacker.sendto(data, target)
        if gap[1]:
            time.sleep(rng.uniform(*gap))


def test_recorded_frames_replayed_mid_session_in_every_order_are_never_obeyed(tmp_path) -> None:
    with attacked(tmp_path) as (emulator, path, relay, tap):
        # an earlier run of the host, recorded from HELLO to BYE
        first = LinkDriver(system=path, robot="tiny")
        with first:
            for _ in range(5):
                first.send_action({"a": ModuleCommand(wheels={"v": 0.5})})
                first.step(0.1)
        assert _until(lambda: sum(k is FrameType.BYE for k, _, _ in relay.recorded) == 3)
        earlier = list(relay.recorded)
        assert {k for k, _, _ in earlier} >= set(KINDS)
        # the live run: a stands still, b is commanded, c is stopped
        driver = LinkDriver(system=path, robot="tiny")
        attacker = _attacker()
        rng = random.Random(26)
        with driver, attacker:
            live = [r for r in relay.recorded if r not in earlier]
            orders = _orders(earlier + live, seed=26)
            sessions = {m: e.link.live for m, e in emulator.modules.items()}
            for name, frames in orders.items():
                driver.send_action({"a": ModuleCommand(wheels={"v": 0.0}),
                                    "b": ModuleCommand(wheels={"v": 0.1})})
                _replay(frames, attacker, rng)
                driver.step(0.1)
                assert emulator.driver.speed.get("a", 0.0) == 0.0, name
                assert {m: e.link.live for m, e in emulator.modules.items()} == sessions, name
            assert _until(lambda: len(tap.sent_by(attacker.getsockname())) >= 8 * len(earlier))
            results = tap.sent_by(attacker.getsockname())
            driver.send_action({})
            driver.step(0.1)
    obeyed = [(m, kind) for m, kind, r in results if r is None and kind is not FrameType.HELLO]
    assert not obeyed  # every replay refused (a HELLO may only be answered, changing nothing)
    assert {r for _, kind, r in results if kind is FrameType.HELLO} <= {"replayed", None}
    assert {r for _, _, r in results} >= {"replayed", "bad_tag"}


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


def test_replays_after_the_host_is_killed_keep_no_motor_running_past_the_watchdog(
        tmp_path) -> None:
    with attacked(tmp_path) as (emulator, path, relay, tap):
        earlier = LinkDriver(system=path, robot="tiny")  # a BYE to replay, from a run before
        with earlier:
            earlier.send_action({"a": ModuleCommand(wheels={"v": 0.3})})
            earlier.step(0.1)
        host = subprocess.Popen([sys.executable, "-c", HOST, str(path)],
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        link = emulator.modules["a"].link
        try:
            assert _until(lambda: emulator.driver.speed.get("a") == pytest.approx(0.2), 8.0), \
                host.stderr.read1().decode() if host.poll() is not None else "no command"
            time.sleep(0.3)
            host.kill()
            host.wait(5.0)
        finally:
            if host.poll() is None:
                host.kill()
                host.wait(5.0)
        orders = _orders(list(relay.recorded), seed=7)
        rng = random.Random(15)
        attacker = _attacker()
        moving_after = []
        with attacker:
            for order in ("recorded", "shuffled", "bye-command-hello", "reversed"):
                frames, began = orders[order], time.monotonic()
                while time.monotonic() - began < 0.5:  # replayed every 15-100 ms
                    _replay(frames[:10], attacker, rng, gap=(0.015, 0.1))
                    frames = frames[10:] + frames[:10]
                    if link.trips:
                        moving_after.append(emulator.driver.speed.get("a"))
            results = tap.sent_by(attacker.getsockname())
        trip, = link.trips  # stopped once, by the watchdog, and never restarted
        assert trip.previous - trip.last <= link.watchdog + 1e-9 < trip.at - trip.last
        assert not any(moving_after) and "a" not in emulator.driver.speed
        assert results and not [(m, k) for m, k, r in results
                                if r is None and k is not FrameType.HELLO]
        assert link.current(emulator.clock) is None


def test_replays_after_a_module_reboot_open_no_session(tmp_path) -> None:
    with attacked(tmp_path, faults="reboot:module=a,at=3,for=0.2") as (emulator, path, relay,
                                                                       tap):
        driver = LinkDriver(system=path, robot="tiny")
        with driver:
            for _ in range(8):
                driver.send_action({"a": ModuleCommand(wheels={"v": 0.2})})
                driver.step(0.1)
        link = emulator.modules["a"].link
        assert _until(lambda: link.boots == 2 and emulator.clock >= 3.3, 4.0)  # back online
        attacker = _attacker()
        with attacker:
            for _, target, data in relay.recorded:
                attacker.sendto(data, target)
            assert _until(lambda: len(tap.sent_by(attacker.getsockname()))
                          >= len(relay.recorded), 3.0)
            after = [(k, r) for m, k, r in tap.sent_by(attacker.getsockname()) if m == "a"]
        assert after and all(r is not None or k is FrameType.HELLO for k, r in after)
        assert any(k is FrameType.HELLO and r is None for k, r in after)  # answered, no more
        time.sleep(0.2)
        assert not link.session and link.command is None and "a" not in emulator.driver.speed
        assert load_system(path).modules[0].id == "a"
