"""The module emulator: one protocol endpoint per module, backed by a simulator.

``platform emulate --robot ROBOT CONFIG.json`` runs an :class:`Emulator`: the robot's
own first driver simulates the modules of the configuration; each module gets a UDP
socket on a loopback address (distinct ports) and a :class:`~.module.ModuleLink` with
its own module key (derived from the site key), so the ``link`` driver (:mod:`.driver`)
talks to it exactly as to real modules. One more socket stands for the network's
broadcast address (the systems file's ``group``): a datagram the host sends there
reaches every module, each with its own loss and latency, as on a radio. Every control
period [s of module time] the emulator:

1. reads the datagrams that arrived (HELLO, SETUP, COMMAND, BYE), each timed when it
   is read off its socket;
2. applies each module's current command (none -- motors stopped -- without a
   session, after a stop or BYE, or once its watchdog expired);
3. steps the simulator by one period;
4. lets each module report (:meth:`~.module.ModuleLink.report` decides whether one is
   due): the simulator's sensor data of that module, its pose, its latched ports,
   docking events, a battery voltage.

Time: each module's clock is the wall clock since :meth:`Emulator.open` times ``speed``
(as a module's oscillator, it runs on whether or not the simulator keeps up); frames
carry it when they are sealed, the watchdog and the faults' ``at`` use it. The loop is
paced at one period of that clock; the simulator steps one period per tick.

The record table of the modules' reports (which dataclasses their sensor data holds,
which fields are rotations or unit vectors) is read off the simulator's first
observation and written to the systems file.

Faults (``--faults``, the syntax of :func:`msrr.core.faults.parse_faults`):

=============  =====================================  =================================
kind           keys (default)                         effect
=============  =====================================  =================================
``loss``       ``p`` (required)                       each datagram, either way, is lost
                                                      with probability ``p``
``latency``    ``ms`` (required), ``jitter`` (0)      each datagram is delayed ``ms`` +-
                                                      ``jitter`` ms (uniform)
``dropout``    ``module`` (required), ``at`` (0),     the module neither sends nor hears
               ``for`` (inf)                          from ``at`` for ``for`` s
``reboot``     ``module`` (required), ``at`` (0),     the module forgets its session at
               ``for`` (0.5)                          ``at`` and is silent ``for`` s
``wrong-key``  ``module`` (required)                  the module holds a key of another
                                                      site
``disobey``    ``module`` (required), ``at`` (0)      from ``at`` the module accepts
                                                      commands but no longer applies them
                                                      (it keeps reporting)
``stall``      ``module`` (required), ``at`` (0)      from ``at`` the module's motors stop
                                                      turning (it reports a motor fault)
=============  =====================================  =================================
"""

from __future__ import annotations

import contextlib
import heapq
import math
import select
import socket
import time as wall
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..capabilities import Recognizer
from ..configuration import Configuration
from ..driver import Driver, DriverFactory, ModuleCommand, Observation, Pose, check_driver_options
from ..errors import ConfigurationError, ExecutionError
from ..faults import Fault, parse_faults
from .codec import Codec, CodecError, RecordTable, infer_records
from .declarations import declared
from .keys import module_key
from .module import DEFAULT_WATCHDOG_PERIODS, ModuleLink
from .protocol import LinkStats
from .system import GroupAddress, KeyRef, ModuleEntry, RecordEntry, SystemFile, new_key
from .transport import drain, udp_socket

__all__ = ["LINK_FAULT_KINDS", "Emulator", "parse_link_faults"]

LINK_FAULT_KINDS: dict[str, dict[str, float | str | None]] = {
    "loss": {"p": None},
    "latency": {"ms": None, "jitter": 0.0},
    "dropout": {"module": None, "at": 0.0, "for": math.inf},
    "reboot": {"module": None, "at": 0.0, "for": 0.5},
    "wrong-key": {"module": None},
    "disobey": {"module": None, "at": 0.0},
    "stall": {"module": None, "at": 0.0},
}
FULL_BATTERY = 8.4
"""Emulated battery voltage when full [V] (2S Li-ion)."""
DRAIN = 0.002
"""Emulated battery drop per second of motor use [V/s]."""


def parse_link_faults(spec: str) -> tuple[Fault, ...]:
    """The emulator's faults of ``spec`` (kinds: module doc); ``""`` is none."""
    return parse_faults(spec, LINK_FAULT_KINDS) if spec.strip() else ()


@dataclass
class _Emulated:
    link: ModuleLink
    sock: socket.socket
    links: frozenset[tuple[str, str, str]] = frozenset()
    offline_until: float = -math.inf
    motor_time: float = 0.0


class Emulator:
    """Emulated modules of ``start`` (module doc).

    Args:
        factory: the robot's own driver (simulator) factory.
        start: the configuration the modules are in.
        recognizer: to tell each module's latched ports when the driver has no
            ground truth (recognized per group, as the executor does).
        rate: control rate [Hz]; the watchdog defaults to 3 periods.
        speed: module time / wall time (1: real time).
        faults: from :func:`parse_link_faults`.
        seed: seed of the faults and of the driver.
        key: the site key (a fresh one by default); each module gets its own key
            derived from it. system: the system id.
        timeout: the silence timeout written to the systems file [s].
        budget: the link budget written to the systems file [kbit/s] (``None``: none).
        address: loopback address the modules listen on (one port each).
        driver_options: keyword options of the driver, checked
            (:func:`~msrr.core.driver.check_driver_options`; FreeSN: ``noise``, ``slip``:
            modules whose reports are as noisy, and state so in their ``accuracy``).
    """

    def __init__(self, factory: DriverFactory, start: Configuration, *,
                 recognizer: Recognizer | None = None, rate: float = 10.0, speed: float = 1.0,
                 faults: tuple[Fault, ...] = (), seed: int = 0, key: bytes | None = None,
                 system: int = 1, timeout: float = 1.0, budget: float | None = None,
                 address: str = "127.0.0.1",
                 driver_options: tuple[tuple[str, object], ...] = ()):
        if not (math.isfinite(rate) and rate > 0):
            raise ConfigurationError(f"must be a finite number > 0, got {rate!r}", field="--rate")
        if not (math.isfinite(speed) and 0 < speed <= 100):
            raise ConfigurationError(f"must be in (0, 100], got {speed!r}", field="--speed")
        ids = list(start.modules())
        for fault in faults:
            module = fault.params.get("module")
            if module is not None and module not in ids:
                raise ConfigurationError(f"fault {fault}: no module {module!r} in the "
                                         "configuration", field="--faults")
        self.factory, self.start, self.recognizer = factory, start, recognizer
        self.driver_options = dict(check_driver_options(factory, driver_options))
        self.period = 1.0 / rate
        self.speed = speed
        self.faults = faults
        self.seed = seed
        self.key = key if key is not None else new_key()
        self.system_id = system
        self.timeout = timeout
        self.budget = budget
        self.address = address
        self.rng = np.random.default_rng(seed)
        self.ids = ids
        self.clock = 0.0
        self._t0 = wall.monotonic()
        self.driver: Driver | None = None
        self.modules: dict[str, _Emulated] = {}
        self.group: socket.socket | None = None
        self.records: RecordTable = RecordTable()
        self.errors: list[str] = []
        self.dropped = 0
        """Datagrams the ``loss`` fault dropped."""
        self._queue: list[tuple[float, int, str, bytes, Any]] = []  # delayed datagrams
        self._count = 0
        self._fired: set[int] = set()

    # -- life cycle ------------------------------------------------------------------

    def open(self) -> None:
        """Bind the sockets, build the simulator, place ``start`` and read the record
        table off its first observation."""
        wrong = {str(f.params["module"]) for f in self.faults if f.kind == "wrong-key"}
        try:
            self.driver = self.factory(gui=False, seed=self.seed, **self.driver_options)
            self.driver.connect()
            self.driver.reset(self.start)
            first = self.driver.get_observation()
            sensors = first.sensors.values() if isinstance(first.sensors, Mapping) else ()
            self.records = RecordTable(infer_records(sensors))
            codec = Codec(self.records)
            self.group = self._socket()
            for number, module in enumerate(self.ids, start=1):
                site = new_key() if module in wrong else self.key
                self.modules[module] = _Emulated(ModuleLink(
                    module, number, module_key(site, self.system_id, number), self.system_id,
                    watchdog=DEFAULT_WATCHDOG_PERIODS * self.period, codec=codec),
                    self._socket())
            self._observe()
            self._t0 = wall.monotonic()
        except BaseException:
            self.close()
            raise

    def _socket(self) -> socket.socket:
        return udp_socket(self.address)

    def close(self) -> None:
        """Stop every motor and release the sockets; safe to call twice."""
        if self.driver is not None:
            try:
                if self.driver.is_connected:
                    self.driver.send_action({})
            finally:
                self.driver.disconnect()
                self.driver = None
        for emulated in self.modules.values():
            emulated.sock.close()
        if self.group is not None:
            self.group.close()

    def __enter__(self) -> Emulator:
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def system_file(self, key: KeyRef, robot: str) -> SystemFile:
        """The systems file of these modules (the key by reference only), with what
        ``robot`` declared of its link data (:mod:`.declarations`)."""
        assert self.group is not None, "call open() first"
        return SystemFile(
            system=self.system_id, robot=robot, key=key, timeout_s=self.timeout,
            time_scale=self.speed, budget_kbps=self.budget,
            group=GroupAddress(address=self.address, port=self.group.getsockname()[1]),
            records=[RecordEntry(type=r.type, rotations=list(r.rotations),
                                 directions=list(r.directions)) for r in self.records.specs],
            vectors=list(declared(robot).vectors), pose_every=declared(robot).pose_every,
            modules=[ModuleEntry(id=m, number=e.link.number, address=self.address,
                                 port=e.sock.getsockname()[1])
                     for m, e in self.modules.items()])

    # -- the loop --------------------------------------------------------------------

    def serve(self, duration: float = math.inf, *, stop: Callable[[], bool] = lambda: False
              ) -> None:
        """Run ticks paced at ``speed`` x real time for ``duration`` s of module time, or
        until ``stop()`` is true (checked every tick)."""
        ticks = math.floor(self._now() / self.period)
        while self.clock < duration - 1e-9 and not stop():
            self.tick()
            ticks = max(ticks + 1, math.floor(self._now() / self.period))  # skip if late
            self._wait_until(self._t0 + ticks * self.period / self.speed)

    def _now(self) -> float:
        """The modules' clock [s] (module doc)."""
        return (wall.monotonic() - self._t0) * self.speed

    def _sockets(self) -> list[socket.socket]:
        return [e.sock for e in self.modules.values()] + ([self.group] if self.group else [])

    def _wait_until(self, deadline: float) -> None:
        socks = self._sockets()
        while True:
            now = wall.monotonic()
            timeout = deadline - now
            if self._queue:
                timeout = min(timeout, self._queue[0][0] - now)
            if timeout <= 0 and now >= deadline:
                self._release(now)
                return
            ready, _, _ = select.select(socks, [], [], max(0.0, timeout))
            self._release(wall.monotonic())
            self._read(ready)

    def tick(self) -> None:
        """One control period (module doc, steps 1-4)."""
        assert self.driver is not None, "call open() first"
        self.clock = self._now()
        self._release(wall.monotonic())
        self._read(self._sockets())
        self._faults()
        commands: dict[str, ModuleCommand] = {}
        for module, emulated in self.modules.items():
            command = emulated.link.current(self.clock)
            if command is not None and self._online(emulated) and not emulated.link.motor_fault:
                commands[module] = command
                if command.joints or command.wheels:
                    emulated.motor_time += self.period
        try:
            self.driver.send_action(commands)
        except ExecutionError as exc:  # a command the simulator refuses: stop everything
            self.errors.append(str(exc))
            self.driver.send_action({})
        self.driver.step(self.period)
        observation, events = self._observe()
        poses = self._tracking(observation)
        for module, emulated in self.modules.items():
            if not self._online(emulated):
                continue
            try:
                emulated.link.report(
                    self._now(), sensors=_sensors_of(observation.sensors, module),
                    pose=poses.get(module), links=tuple(emulated.links),
                    events=events.get(module, []),
                    battery=round(FULL_BATTERY - DRAIN * emulated.motor_time, 2))
            except CodecError as exc:  # data the record table cannot carry: no report
                self.errors.append(f"module {module}: {exc}")
        self._flush()

    def _online(self, emulated: _Emulated) -> bool:
        return self.clock >= emulated.offline_until

    def _faults(self) -> None:
        for index, fault in enumerate(self.faults):
            if fault.kind in ("loss", "latency", "wrong-key"):
                continue
            emulated = self.modules[str(fault.params["module"])]
            at = float(fault.params["at"])
            if fault.kind == "dropout" and at <= self.clock + 1e-9 < at + float(fault.params["for"]):
                emulated.offline_until = max(emulated.offline_until,
                                             at + float(fault.params["for"]))
            if index in self._fired or self.clock < at - 1e-9:
                continue
            if fault.kind == "reboot":
                self._fired.add(index)
                emulated.link.reboot()
                emulated.offline_until = max(emulated.offline_until,
                                             at + float(fault.params["for"]))
            elif fault.kind == "disobey":
                self._fired.add(index)
                emulated.link.obey = False
            elif fault.kind == "stall":
                self._fired.add(index)
                emulated.link.motor_fault = True

    # -- datagrams -------------------------------------------------------------------

    def _read(self, ready: list[socket.socket]) -> None:
        """Deliver what arrived on ``ready`` in the order it arrived (kernel time)."""
        by_sock = {e.sock: e for e in self.modules.values()}
        arrived = [(arrival, n, sock, data, address) for sock in ready
                   for n, (data, address, arrival) in enumerate(drain(sock))]
        for arrival, _, sock, data, address in sorted(arrived, key=lambda a: a[:2]):
            if sock is self.group:  # the broadcast address: every module hears it
                for emulated in self.modules.values():
                    self._deliver_later(emulated.link.module, data, address, incoming=True,
                                        arrival=arrival)
            else:
                self._deliver_later(by_sock[sock].link.module, data, address, incoming=True,
                                    arrival=arrival)

    def _deliver_later(self, module: str, data: bytes, address: Any, *, incoming: bool,
                       arrival: float | None = None) -> None:
        """Apply loss and latency to one datagram, then deliver or send it (now or later);
        ``arrival``: when it reached the emulator [wall clock]."""
        for fault in self.faults:
            if fault.kind == "loss" and self.rng.random() < float(fault.params["p"]):
                self.dropped += 1
                return
        delay = 0.0
        for fault in self.faults:
            if fault.kind == "latency":
                jitter = float(fault.params["jitter"])
                delay += max(0.0, float(fault.params["ms"]) + self.rng.uniform(-jitter, jitter))
        if delay <= 0.0:
            self._do(module, data, address, incoming, arrival)
            return
        self._count += 1
        heapq.heappush(self._queue, (wall.monotonic() + delay / 1000.0 / self.speed, self._count,
                                     module, data, (address, incoming)))

    def _release(self, now: float) -> None:
        while self._queue and self._queue[0][0] <= now:
            due, _, module, data, (address, incoming) = heapq.heappop(self._queue)
            self._do(module, data, address, incoming, due)

    def _do(self, module: str, data: bytes, address: Any, incoming: bool,
            arrival: float | None = None) -> None:
        emulated = self.modules[module]
        if not self._online(emulated):
            return
        if incoming:
            at = self._now() if arrival is None else (arrival - self._t0) * self.speed
            emulated.link.handle(data, address, at)
            self._flush()
            return
        with contextlib.suppress(OSError):  # the host is gone: the watchdog stops us
            emulated.sock.sendto(data, address)

    def _flush(self) -> None:
        for module, emulated in self.modules.items():
            out, emulated.link.outbox = emulated.link.outbox, []
            for data, address in out:
                self._deliver_later(module, data, address, incoming=False)

    # -- observation -----------------------------------------------------------------

    def _tracking(self, observation: Observation) -> Mapping[str, Pose]:
        """The poses the modules report (the ``pose`` field): the robot's own pose sensor
        where it has one (MMRP's overhead tracking), else the lab's motion capture that
        the emulator stands in for, from the simulator's witness; the host gives these
        to the judge and the control path alike (a FreeSN controller reads none)."""
        if observation.tracked:
            return observation.tracked
        seen = self.driver.witness() if self.driver is not None else None
        return seen.poses if seen is not None else {}

    def _observe(self) -> tuple[Observation, dict[str, list[tuple[Any, ...]]]]:
        """The simulator's observation, each module's latched ports updated, and the
        docking events since the previous call."""
        assert self.driver is not None
        observation = self.driver.get_observation()
        config = self.driver.ground_truth()
        if config is None and self.recognizer is not None:
            config = self.recognizer.recognize(observation.sensors, seed=self.seed)
        found: dict[str, set[tuple[str, str, str]]] = {m: set() for m in self.modules}
        for edge in config.edges() if config is not None else ():
            ports = edge.ports or ("", "")
            pairs = [(edge.source, ports[0], edge.target, ports[1])]
            if edge.kind is not None and edge.id in found:  # a module on the edge (strut)
                pairs = [(edge.id, "a", edge.source, ports[0]), (edge.id, "b", edge.target,
                                                                  ports[1])]
            for a, pa, b, pb in pairs:
                for here, port, there, other in ((a, pa, b, pb), (b, pb, a, pa)):
                    if here in found:
                        found[here].add((port or "", there, other or ""))
        events: dict[str, list[tuple[Any, ...]]] = {}
        for module, emulated in self.modules.items():
            now = frozenset(found[module])
            for kind, items in (("dock", now - emulated.links), ("undock", emulated.links - now)):
                for port, other, other_port in sorted(items):
                    events.setdefault(module, []).append(
                        (kind, port, other, other_port, round(self.clock, 3)))
            emulated.links = now
        return observation, events

    # -- what happened ---------------------------------------------------------------

    def stats(self) -> dict[str, LinkStats]:
        """Each module's counters (frames, bytes, refusals by reason)."""
        return {m: e.link.stats for m, e in self.modules.items()}

    def refused(self) -> dict[str, int]:
        """Refusals of all modules, by reason."""
        total: dict[str, int] = {}
        for stats in self.stats().values():
            for reason, n in stats.refused.items():
                total[reason] = total.get(reason, 0) + n
        return total


def _sensors_of(sensors: Any, module: str) -> Any:
    if isinstance(sensors, Mapping):
        return sensors.get(module)
    return None

