"""The ``link`` driver: the modules of a systems file, over UDP (``docs/hardware.md``).

Registered for every robot (after the robot's own drivers and the generic runtime's):
``platform run --robot ROBOT --driver link --system system.json``. It keeps the
:class:`~msrr.core.driver.Driver` contract over the protocol of :mod:`.protocol`:

* ``connect`` handshakes with every module (HELLO -> WELCOME, fresh nonces);
* ``reset(start)`` expects the modules of ``start`` (it cannot place them) and waits
  for a report of each;
* ``send_action`` sends one COMMAND to every module each tick (a module not named gets
  a stop); an undock is repeated until the module acknowledges it;
* ``step(dt)`` waits ``dt`` of system time (wall time / ``time_scale``) while reading
  reports, so the executor's loop runs at the robot's rate; then it stops the run with
  one line naming the module when a module was silent longer than its timeout, or did
  not acknowledge a dock or undock within it;
* ``disconnect`` says BYE (modules stop at once); without it, their watchdogs stop
  them within ``watchdog`` (default 3 control periods).

The key is read from where the systems file says and kept only in the endpoint.
"""

from __future__ import annotations

import contextlib
import math
import secrets
import select
import socket
import time as wall
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, ClassVar

import networkx as nx
import numpy as np

from ..configuration import Configuration
from ..driver import Companions, Driver, DriverFactory, ModuleCommand, Observation, Pose
from ..errors import ConfigurationError, ExecutionError
from ..robot import RobotSpec
from .module import DEFAULT_WATCHDOG_PERIODS
from .protocol import (
    HEADER,
    HOST,
    VERSION,
    Endpoint,
    FrameType,
    LinkStats,
    Refused,
    command_payload,
)
from .system import ModuleEntry, SystemFile, load_key, load_system

__all__ = ["LinkDriver", "LinkDriverFactory"]

HANDSHAKE = 2.0
"""Shortest wall time [s] given to every module to answer at connect and reset."""
DEFAULT_RATE = 10.0
"""Control rate [Hz] assumed for the watchdog until the first ``step``."""


@dataclass
class _Module:
    entry: ModuleEntry
    timeout: float
    link: int = 0
    heard: float = 0.0
    report: dict[str, Any] | None = None
    links: tuple[Any, ...] = ()
    has_links: bool = False
    reboots: int = 0
    undock: dict[str, int] = field(default_factory=dict)  # port -> first sequence carrying it
    docks: dict[str, tuple[int, float]] = field(default_factory=dict)  # port -> (seq, time)
    sent: dict[int, float] = field(default_factory=dict)  # seq -> wall time sent
    hello_at: float = -math.inf

    @property
    def address(self) -> tuple[str, int]:
        return (self.entry.address, self.entry.port)


class LinkDriver(Driver):
    """The modules of a systems file over UDP (module doc).

    Args:
        system: path of the systems file.
        robot: the run's robot (the systems file must name it).
        packages: packages whose dataclasses reports may carry (the robot's plugin).
        handshake: wall time [s] to wait for every module at connect and reset;
            default the largest module timeout / ``time_scale``, at least 2 s.
        gui, seed: accepted for the factory interface; unused.
    """

    name: ClassVar[str] = "link"
    description: ClassVar[str] = ("modules over UDP (docs/protocol.md): hardware, or "
                                  "`platform emulate`; --system FILE")

    def __init__(self, *, system: str | Path | None = None, robot: str | None = None,
                 packages: tuple[str, ...] = ("msrr",), handshake: float | None = None,
                 gui: bool = False, seed: int = 0, **unknown: Any):
        if unknown:
            raise ConfigurationError(f"unknown link driver option(s) {sorted(unknown)} "
                                     "(known: system, handshake)", field="--driver-option")
        if system is None or not str(system).strip():
            raise ConfigurationError("the link driver needs a systems file", field="--system")
        self.path = Path(system)
        self.system: SystemFile = load_system(self.path)
        if robot is not None and self.system.robot != robot:
            raise ConfigurationError(f"describes {self.system.robot!r} modules, not {robot!r}",
                                     source=str(self.path), field="robot")
        self.packages = packages
        self.handshake = handshake
        self.modules = {m.id: _Module(m, self.system.timeout(m)) for m in self.system.modules}
        self._by_number = {m.entry.number: m for m in self.modules.values()}
        self._endpoint: Endpoint | None = None
        self._sock: socket.socket | None = None
        self.session = 0
        self._time = 0.0
        self._t0 = 0.0
        self._mark = 0.0
        self._dt = 1.0 / DEFAULT_RATE
        self.latencies: list[float] = []
        self.held = 0
        """Observations held because two modules' reports disagreed about a latch."""
        self._agreed: Observation | None = None
        self.bytes_by_module: dict[str, list[int]] = {m: [0, 0] for m in self.modules}

    # -- connection ------------------------------------------------------------------

    @property
    def is_connected(self) -> bool:
        return self._sock is not None

    @property
    def stats(self) -> LinkStats:
        """Frames, bytes and refusals of the host's end (an empty count before connect)."""
        return self._endpoint.stats if self._endpoint is not None else LinkStats()

    def _clock(self) -> float:
        """The host's link clock [s of system time]."""
        return (wall.monotonic() - self._t0) * self.system.time_scale

    def _wall(self, seconds: float) -> float:
        return seconds / self.system.time_scale

    def connect(self) -> None:
        if self._sock is not None:
            return
        key = load_key(self.system, self.path)
        window = max(m.timeout for m in self.modules.values())
        self._endpoint = Endpoint(key, self.system.system, HOST, window=window,
                                  packages=self.packages)
        loopback = all(m.entry.address.startswith("127.") for m in self.modules.values())
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.bind(("127.0.0.1" if loopback else "0.0.0.0", 0))
        sock.setblocking(False)
        self._sock = sock
        self.session = secrets.randbits(32) | 1
        self._t0 = wall.monotonic()
        self._mark = self._t0
        try:
            self._wait(lambda m: m.link != 0, "answer the handshake")
        except BaseException:
            self.disconnect()
            raise

    def disconnect(self) -> None:
        if self._sock is None:
            return
        for module in self.modules.values():
            if module.link:
                self._send(module, FrameType.BYE, {})
                module.link = 0
        self._sock.close()
        self._sock = None

    def _limit(self) -> float:
        if self.handshake is not None:
            return self.handshake
        return max(HANDSHAKE, self._wall(max(m.timeout for m in self.modules.values())))

    def _wait(self, ready: Any, what: str) -> None:
        """Pump frames (re-sending HELLOs) until ``ready(module)`` for every module."""
        end = wall.monotonic() + self._limit()
        while True:
            waiting = [m for m in self.modules.values() if not ready(m)]
            if not waiting:
                return
            now = wall.monotonic()
            if now >= end:
                names = ", ".join(f"{m.entry.id} ({m.entry.address}:{m.entry.port})"
                                  for m in waiting[:4])
                refused = self.stats.refused
                raise ExecutionError(
                    f"module{'s' if len(waiting) > 1 else ''} {names} did not {what} within "
                    f"{self._limit():.1f} s"
                    + (f"; frames refused: {_counts(refused)}" if refused else ""))
            for module in waiting:
                if module.link == 0 and now - module.hello_at >= self._wall(0.1):
                    self._hello(module)
            self._pump(min(end, now + self._wall(0.05)))

    def _hello(self, module: _Module) -> None:
        module.hello_at = wall.monotonic()
        self._send(module, FrameType.HELLO, {"version": VERSION, "watchdog": self._watchdog()},
                   link=0)

    def _watchdog(self) -> float:
        if self.system.watchdog_s is not None:
            return self.system.watchdog_s
        return DEFAULT_WATCHDOG_PERIODS * self._dt

    # -- frames ----------------------------------------------------------------------

    def _send(self, module: _Module, frame_type: FrameType, payload: Any,
              link: int | None = None) -> int:
        assert self._sock is not None and self._endpoint is not None
        data = self._endpoint.encode(frame_type, module.entry.number, session=self.session,
                                     link=module.link if link is None else link,
                                     clock=self._clock(), payload=payload)
        self.bytes_by_module[module.entry.id][0] += len(data)
        with contextlib.suppress(OSError):  # a full buffer, a module gone: silence tells
            self._sock.sendto(data, module.address)
        return self._endpoint.seq

    def _pump(self, until: float) -> None:
        """Read every datagram until wall time ``until`` (at least the ones waiting)."""
        assert self._sock is not None
        while True:
            timeout = max(0.0, until - wall.monotonic())
            ready, _, _ = select.select([self._sock], [], [], timeout)
            if not ready:
                return
            while True:
                try:
                    data, _address = self._sock.recvfrom(65536)
                except (BlockingIOError, InterruptedError):
                    break
                except OSError:
                    break  # ICMP port unreachable of a module that is gone
                self._receive(data)
            if wall.monotonic() >= until:
                return

    def _receive(self, data: bytes) -> None:
        assert self._endpoint is not None
        stats = self._endpoint.stats
        if len(data) < HEADER.size:
            stats.refuse("malformed")
            return
        module = self._by_number.get(int.from_bytes(data[8:10], "little"))
        if module is None:
            stats.refuse("foreign")
            return
        welcome = data[3] == FrameType.WELCOME
        try:
            frame = self._endpoint.accept(data, self._clock(), session=self.session,
                                          link=None if welcome else module.link or -1)
        except Refused:
            return
        self.bytes_by_module[module.entry.id][1] += len(data)
        payload = frame.payload
        if frame.type is FrameType.WELCOME:
            if not isinstance(payload, dict) or payload.get("id") != module.entry.id:
                stats.refuse("foreign")
                return
            if module.link and frame.link != module.link:
                module.reboots += 1
            module.link = frame.link
            module.heard = self._time
            return
        if frame.type is not FrameType.REPORT or not isinstance(payload, dict):
            stats.refuse("malformed")
            return
        module.report = payload
        module.heard = self._time
        links = payload.get("links")
        if isinstance(links, tuple):
            module.links, module.has_links = links, True
        ack = payload.get("ack", 0)
        if isinstance(ack, int):
            self._acknowledged(module, ack)

    def _acknowledged(self, module: _Module, ack: int) -> None:
        for port in [p for p, seq in module.undock.items() if ack >= seq]:
            del module.undock[port]
        for port in [p for p, (seq, _) in module.docks.items() if ack >= seq]:
            del module.docks[port]
        for seq in [s for s in module.sent if s <= ack]:
            sent = module.sent.pop(seq)
            if seq == ack:
                self.latencies.append(wall.monotonic() - sent)

    # -- the Driver contract ---------------------------------------------------------

    def reset(self, start: Configuration) -> None:
        """Expect the modules of ``start``: they must be the systems file's, and each
        must report; time becomes 0. The link cannot place modules."""
        self.require_connected()
        want, have = set(start.modules()), set(self.modules)
        if want != have:
            missing, extra = sorted(want - have), sorted(have - want)
            raise ConfigurationError(
                "the modules differ from the configuration's"
                + (f"; not in the systems file: {', '.join(missing[:6])}" if missing else "")
                + (f"; not in the configuration: {', '.join(extra[:6])}" if extra else ""),
                source=str(self.path), field="modules")
        self._time = 0.0
        self._agreed = None
        for module in self.modules.values():
            module.heard, module.report = 0.0, None  # links stay: they change by events
            module.undock.clear()
            module.docks.clear()
        self.send_action({})
        self._wait(lambda m: m.report is not None and m.has_links, "report")
        self._mark = wall.monotonic()

    def get_observation(self) -> Observation:
        """The newest report of every module. While two modules' reports disagree about a
        latch between them (one was sent before a dock or undock, the other after: a lost
        or late report), the last observation on which they agreed is returned (with the
        current time), for at most the smallest module timeout; then the disagreeing one,
        and the recognizer says what is wrong."""
        self.require_connected()
        poses: dict[str, Pose] = {}
        sensors: dict[str, Any] = {}
        graph = nx.Graph()
        graph.add_nodes_from(self.modules)
        claims: set[tuple[str, str, str, str]] = set()
        for name, module in self.modules.items():
            report = module.report or {}
            pose = report.get("pose")
            if isinstance(pose, np.ndarray) and pose.shape == (7,):
                poses[name] = Pose(pose[:3].copy(), pose[3:].copy())
            sensors[name] = report.get("sensors")
            for link in module.links:
                if (isinstance(link, tuple) and len(link) == 3 and link[1] in self.modules
                        and all(isinstance(x, str) for x in link)):
                    graph.add_edge(name, link[1])
                    claims.add((name, link[0], link[1], link[2]))
        components = [frozenset(c) for c in nx.connected_components(graph)]
        groups = tuple(sorted(components, key=min)) if len(components) > 1 else ()
        observation = Observation(time=self._time, poses=poses, sensors=sensors, groups=groups)
        agree = all((b, pb, a, pa) in claims for a, pa, b, pb in claims)
        limit = min(m.timeout for m in self.modules.values())
        if agree or self._agreed is None or self._time - self._agreed.time > limit + 1e-9:
            if agree:
                self._agreed = observation
            return observation
        self.held += 1
        return replace(self._agreed, time=self._time)

    def send_action(self, commands: Mapping[str, ModuleCommand]) -> None:
        self.require_connected()
        unknown = set(commands) - set(self.modules)
        if unknown:
            raise ExecutionError(f"commands for module(s) not in the systems file "
                                 f"{sorted(unknown)}")
        wd = self._watchdog()
        for name, module in self.modules.items():
            if not module.link:
                continue
            command = commands.get(name)
            if command is None:
                payload: dict[str, Any] = {"s": True, "wd": wd}
                if module.undock:
                    payload["u"] = list(module.undock)
            else:
                for port in command.dock:
                    module.undock.pop(port, None)
                payload = {**command_payload(command, tuple(module.undock)), "wd": wd}
            seq = self._endpoint.seq + 1 if self._endpoint is not None else 1
            for port in command.undock if command is not None else ():
                module.undock.setdefault(port, seq)
            for port in command.dock if command is not None else ():
                module.docks.setdefault(port, (seq, self._time))
            for port in list(module.docks):
                if command is None or port not in command.dock:
                    del module.docks[port]  # no longer armed: nothing to acknowledge
            module.sent[self._send(module, FrameType.COMMAND, payload)] = wall.monotonic()
            while len(module.sent) > 64:
                del module.sent[next(iter(module.sent))]

    def step(self, dt: float) -> None:
        self.require_connected()
        if not (math.isfinite(dt) and dt > 0):
            raise ExecutionError(f"step of {dt!r} s; expected a finite time > 0")
        self._dt = dt
        deadline = self._mark + self._wall(dt)
        self._pump(deadline)
        now = wall.monotonic()
        self._mark = deadline if now - deadline < self._wall(dt) else now  # resync if late
        self._time += dt
        self._check()

    def _check(self) -> None:
        for name, module in self.modules.items():
            silent = self._time - module.heard
            if silent > 2 * self._dt and wall.monotonic() - module.hello_at > self._wall(self._dt):
                self._hello(module)  # a rebooted module needs a new handshake
            if silent > module.timeout + 1e-9:
                refused = self.stats.refused
                raise ExecutionError(
                    f"module {name} silent for {silent:.2f} s (timeout {module.timeout:g} s)"
                    + (f"; frames refused: {_counts(refused)}" if refused else "")
                    + "; run stopped")
            for kind, pending in (("dock", {p: t for p, (_, t) in module.docks.items()}),
                                  ("undock", dict.fromkeys(module.undock, None))):
                for port, since in pending.items():
                    if since is None:
                        continue
                    if self._time - since > module.timeout + 1e-9:
                        raise ExecutionError(f"module {name} did not acknowledge the {kind} "
                                             f"of port {port} within {module.timeout:g} s; "
                                             "run stopped")

    @property
    def time(self) -> float:
        return self._time

    def reboots(self) -> dict[str, int]:
        """Re-handshakes of each module with a new link nonce since connect (reboots)."""
        return {name: m.reboots for name, m in self.modules.items() if m.reboots}


def _counts(refused: Mapping[str, int]) -> str:
    return ", ".join(f"{reason} {n}" for reason, n in sorted(refused.items()))


class LinkDriverFactory:
    """Builds :class:`LinkDriver` s for one robot: ``factory(system=PATH, gui=..., seed=...)``.

    The modules behind the link report what the robot's simulator reports, so the link
    takes its companions (the recognizer and controller) from ``simulator``, the robot's
    default driver, which also lays out a goal for judging the final shape.

    Args:
        spec: the robot.
        simulator: the robot's default driver (``None``: it has none).
    """

    name = LinkDriver.name
    description = LinkDriver.description
    generic = True

    def __init__(self, spec: RobotSpec, simulator: DriverFactory | None):
        self.spec = spec
        self.layout = simulator
        self.companions = simulator.companions if simulator is not None else Companions()
        module = "msrr" if simulator is None else (
            simulator.__module__ if isinstance(simulator, type) else type(simulator).__module__)
        self.packages = tuple(dict.fromkeys(("msrr", module.split(".")[0])))

    def __call__(self, **options: Any) -> LinkDriver:
        return LinkDriver(robot=self.spec.name, packages=self.packages, **options)
