"""The ``link`` driver: the modules of a systems file, over UDP (``docs/hardware.md``).

Registered for every robot (after the robot's own drivers and the generic runtime's):
``platform run --robot ROBOT --driver link --system system.json``. It keeps the
:class:`~msrr.core.driver.Driver` contract over the protocol of :mod:`.protocol`:

* ``connect`` handshakes with every module (HELLO -> WELCOME -> SETUP, a fresh X25519
  exchange each, :mod:`.keys`) and waits for each one's first report;
* ``reset(start)`` expects the modules of ``start`` (it cannot place them) and waits
  for a full report of each with its latched ports (asking for it, key 4);
* ``send_action`` sends one COMMAND frame per tick for all modules (a module not named
  stops); a module's command travels in full until the module acknowledges it, then as
  its version only (a change finer than the wire's quantum is none); an undock is
  repeated until acknowledged; every ``every``-th frame polls all modules (key 5), so
  their reports show one instant, and a module whose answer is two periods late is
  polled again at once;
* ``step(dt)`` waits ``dt`` of system time (wall time / ``time_scale``) while reading
  reports, so the executor's loop runs at the robot's rate; then it stops the run with
  one line naming the module when a module was silent longer than its timeout, did not
  acknowledge a dock or undock within it, received commands for two control periods
  without applying them, reports its motors failed, or heard no command for its timeout;
* ``disconnect`` says BYE (modules stop at once); without it, their watchdogs stop
  them within ``watchdog`` (default 3 control periods).

With a budget in the systems file the host polls the modules every 1 to 6 control
periods (:meth:`LinkDriver._budget`) so that the traffic on its socket, UDP/IP headers
included, stays within it. The site key is read from where the systems file says and kept only in this
object (never printed); modules hold keys derived from it.
"""

from __future__ import annotations

import contextlib
import math
import select
import socket
import time as wall
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, ClassVar

from ..configuration import Configuration
from ..driver import Companions, Driver, DriverFactory, ModuleCommand, Observation, Pose
from ..errors import ConfigurationError, ExecutionError
from ..robot import RobotSpec
from .codec import INCOMPLETE, Codec, CodecError, RecordSpec, RecordTable
from .keys import Aead, Ephemeral, SessionKeys, Signer, module_key, random_key, session_keys
from .module import DEFAULT_WATCHDOG_PERIODS, FAULT, WATCHDOG
from .protocol import (
    HEADER,
    HOST,
    MAX_COUNTER,
    MAX_FRAME,
    SIGNATURE_SIZE,
    TAG_SIZE,
    UDP_IP_BYTES,
    VERSION,
    VERSION_MARKS,
    FrameType,
    Freshness,
    Header,
    LinkStats,
    NameTable,
    Refused,
    clock_ms,
    command_entry,
    decode_map,
    open_handshake,
    open_sealed,
    pose_from_wire,
    read_header,
    seal,
    seal_handshake,
    seal_signed,
    unsigned,
    want,
)
from .system import ModuleEntry, SystemFile, load_key, load_system
from .transport import drain, udp_socket

__all__ = ["LinkDriver", "LinkDriverFactory"]

HANDSHAKE = 2.0
"""Shortest wall time [s] given to every module to answer at connect and reset."""
DEFAULT_RATE = 10.0
"""Control rate [Hz] assumed for the watchdog until the first ``step``."""
RESEND = 0.1
"""HELLO and SETUP are repeated every this many seconds [system time] until answered."""
MAX_EVERY = 6
"""Reports are at least every this many control periods under a budget (a module reports
at once when its status changes or it falls behind, so faults show within 3 periods),
and never so far apart that three lost reports in a row exceed a module's timeout."""
DISOBEY_PERIODS = 2.0
"""A module that received commands this many control periods newer than the one it
applies stops the run."""
_PAYLOAD_LIMIT = MAX_FRAME - HEADER.size - TAG_SIZE - SIGNATURE_SIZE
BUDGET_WINDOW = 2.0
"""The budget is checked on the traffic of the last this many seconds [wall]..."""
BUDGET_STEP = 0.5
"""... every this many seconds [wall]."""
BUDGET_HIGH = 0.9
BUDGET_LOW = 0.8
"""Reports are spaced further when the estimate exceeds this share of the budget, and
come closer when the closer spacing stays within the lower share."""


@dataclass
class _Module:
    entry: ModuleEntry
    timeout: float
    aead: Aead
    key: bytes = field(repr=False)
    state: str = "none"  # none -> hello -> setup -> live
    hello: Ephemeral | None = None
    hello_at: float = -math.inf
    setup_at: float = -math.inf
    keys: SessionKeys | None = None
    session_public: bytes = b""  # the host key of the handshake that made ``keys``
    module_public: bytes = b""
    counter: int = 0
    freshness: Freshness | None = None
    boot: int | None = None
    reboots: int = 0
    heard: float = 0.0
    reports: int = 0
    sensors: Any = None
    pose: Pose | None = None
    battery: float | None = None
    status: int = 0
    watchdog_since: float | None = None
    known: int = 0
    links: tuple[Any, ...] = ()
    has_links: bool = False
    complete: bool = False  # the host holds the session's full sensor data
    awaiting: float | None = None  # host time of the oldest poll it has not answered
    command: ModuleCommand | None = None
    wire: list[Any] | None = None  # the command's entry as sent, without its version
    version: int = 0
    acked_version: int | None = None
    batches: dict[int, int | None] = field(default_factory=dict)  # counter -> version sent
    undock: dict[str, int] = field(default_factory=dict)  # port -> first counter carrying it
    docks: dict[str, tuple[int, float]] = field(default_factory=dict)  # port -> (counter, t)
    sent: dict[int, float] = field(default_factory=dict)  # counter -> wall time sent
    problem: str | None = None

    @property
    def address(self) -> tuple[str, int]:
        return (self.entry.address, self.entry.port)

    @property
    def number(self) -> int:
        return self.entry.number


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
        try:
            table = RecordTable([RecordSpec(r.type, tuple(r.rotations), tuple(r.directions))
                                 for r in self.system.records], packages)
        except ConfigurationError as exc:
            raise ConfigurationError(exc.message if hasattr(exc, "message") else str(exc),
                                     source=str(self.path), field="records") from None
        self.codec = Codec(table)
        self.vectors = tuple(self.system.vectors)
        """Joint names whose ``_x/_y/_z`` joints travel as one packed unit vector."""
        self.handshake = handshake
        self.modules: dict[str, _Module] = {}
        self._by_number: dict[int, _Module] = {}
        self._sock: socket.socket | None = None
        self._stats = LinkStats()
        self._counter = 0
        self._group: Aead | None = None
        self._group_key = b""
        self._signer: Signer | None = None
        self.names = NameTable()
        self._time = 0.0
        self._t0 = 0.0
        self._mark = 0.0
        self._dt = 1.0 / DEFAULT_RATE
        self.every = 1
        """Reports come every this many control periods (set by the budget): the host
        polls every module in every ``every``-th COMMAND frame."""
        self._ticks = 0
        self._polled: set[int] = set()
        """The modules polled this tick."""
        self.latencies: list[float] = []
        self.held = 0
        """Observations held because two modules' reports disagreed about a latch."""
        self._agreed: Observation | None = None
        self.bytes_by_module: dict[str, list[int]] = {}
        """Per module: bytes of the frames sent to it alone (handshake, SETUP, BYE) and
        of the frames it sent (the COMMAND frames, one for all, are in :attr:`traffic`)."""
        self.traffic: dict[str, int] = {"sent": 0, "received": 0, "datagrams_sent": 0,
                                        "datagrams_received": 0}
        """Everything on the host's socket: payload bytes and datagrams each way."""
        self._recent: deque[tuple[float, int, str]] = deque()
        """Datagrams of the last :data:`BUDGET_WINDOW` s: wall time, bytes with UDP/IP,
        ``command``, ``report`` or ``other``."""
        self._budget_at = 0.0
        self._window_start = 0.0
        self._sent_at: dict[int, float] = {}
        """Wall time each COMMAND frame was sent, by counter (the last 256)."""

    # -- connection ------------------------------------------------------------------

    @property
    def is_connected(self) -> bool:
        return self._sock is not None

    @property
    def stats(self) -> LinkStats:
        """Frames, bytes and refusals of the host's end."""
        return self._stats

    def _clock(self) -> float:
        """The host's link clock [s of system time]."""
        return (wall.monotonic() - self._t0) * self.system.time_scale

    def _wall(self, seconds: float) -> float:
        return seconds / self.system.time_scale

    def connect(self) -> None:
        if self._sock is not None:
            return
        site = load_key(self.system, self.path)
        self.modules = {}
        for entry in self.system.modules:
            key = module_key(site, self.system.system, entry.number)
            self.modules[entry.id] = _Module(entry, self.system.timeout(entry), Aead(key), key)
        self._by_number = {m.number: m for m in self.modules.values()}
        self.bytes_by_module = {m: [0, 0] for m in self.modules}
        self._group_key = random_key()
        self._group = Aead(self._group_key)
        self._signer = Signer()
        self._counter = 0
        self.names = NameTable()
        self.every = self._initial_every()
        addresses = [m.entry.address for m in self.modules.values()]
        if self.system.group is not None:
            addresses.append(self.system.group.address)
        loopback = all(a.startswith("127.") for a in addresses)
        sock = udp_socket("127.0.0.1" if loopback else "0.0.0.0")
        if not loopback:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST, 1)
        self._sock = sock
        self._t0 = wall.monotonic()
        self._window_start = self._t0
        self._mark = self._t0
        try:
            self._wait(lambda m: m.state == "live", "answer the handshake")
        except BaseException:
            self.disconnect()
            raise

    def disconnect(self) -> None:
        if self._sock is None:
            return
        for module in self.modules.values():
            if module.keys is not None:
                self._unicast(module, FrameType.BYE, {})
                module.keys, module.state = None, "none"
        self._sock.close()
        self._sock = None

    def _limit(self) -> float:
        if self.handshake is not None:
            return self.handshake
        return max(HANDSHAKE, self._wall(max(m.timeout for m in self.modules.values())))

    def _wait(self, ready: Callable[[_Module], bool], what: str,
              repeat: Callable[[], None] | None = None) -> None:
        """Pump frames (repeating HELLO and SETUP, and calling ``repeat`` every
        :data:`RESEND`) until ``ready(module)`` for every module."""
        end = wall.monotonic() + self._limit()
        repeated = wall.monotonic()
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
            self._handshakes()
            if repeat is not None and now - repeated >= self._wall(RESEND):
                repeat()
                repeated = now
            self._pump(min(end, now + self._wall(0.05)))

    def _handshakes(self) -> None:
        now = wall.monotonic()
        for module in self.modules.values():
            if module.state in ("none", "hello") and now - module.hello_at >= self._wall(RESEND):
                self._hello(module)
            elif module.state == "setup" and now - module.setup_at >= self._wall(RESEND):
                self._setup(module)

    def _hello(self, module: _Module) -> None:
        if module.state != "hello" or module.hello is None:
            module.hello, module.state = Ephemeral(), "hello"
        module.hello_at = wall.monotonic()
        data = seal_handshake(module.aead, self._header(FrameType.HELLO),
                              self.codec.encode({0: VERSION, 1: module.hello.public}))
        self._send(data, module.address, module)

    def _setup(self, module: _Module) -> None:
        assert self._signer is not None
        module.setup_at = wall.monotonic()
        self._unicast(module, FrameType.SETUP, {
            0: self._group_key, 1: self._signer.public, 2: round(self._watchdog() * 1000),
            3: self.every, 4: round(module.timeout * 1000)}
            | ({5: self.system.pose_every} if self.system.pose_every != 1 else {}))

    def _watchdog(self) -> float:
        if self.system.watchdog_s is not None:
            return self.system.watchdog_s
        return DEFAULT_WATCHDOG_PERIODS * self._dt

    # -- frames ----------------------------------------------------------------------

    def _header(self, frame_type: FrameType) -> Header:
        self._counter += 1
        if self._counter > MAX_COUNTER:
            raise ExecutionError("the host's frame counter is exhausted; connect again")
        return Header(frame_type, HOST, self._counter, clock_ms(self._clock()))

    def _unicast(self, module: _Module, frame_type: FrameType, payload: Any) -> int:
        assert module.keys is not None
        header = self._header(frame_type)
        self._send(seal(module.keys.to_module, header, self.codec.encode(payload)),
                   module.address, module)
        return header.counter

    def _send(self, data: bytes, address: tuple[str, int], module: _Module | None) -> None:
        assert self._sock is not None
        with contextlib.suppress(OSError):  # a full buffer, a module gone: silence tells
            self._sock.sendto(data, address)
        self._stats.sent += 1
        self._stats.bytes_sent += len(data)
        self.traffic["sent"] += len(data)
        self.traffic["datagrams_sent"] += 1
        kind = "command" if data[0] & 0x0F == FrameType.COMMAND else "other"
        self._recent.append((wall.monotonic(), len(data) + UDP_IP_BYTES, kind))
        if module is not None:
            self.bytes_by_module[module.entry.id][0] += len(data)

    def _pump(self, until: float) -> None:
        """Read every datagram until wall time ``until`` (at least the ones waiting);
        each is timed by its arrival (:mod:`.transport`)."""
        assert self._sock is not None
        while True:
            timeout = max(0.0, until - wall.monotonic())
            ready, _, _ = select.select([self._sock], [], [], timeout)
            if not ready:
                return
            for data, _address, arrival in drain(self._sock):
                self._receive(data, (arrival - self._t0) * self.system.time_scale)
            if wall.monotonic() >= until:
                return

    def _receive(self, data: bytes, arrival: float) -> None:
        stats = self._stats
        stats.bytes_received += len(data)
        self.traffic["received"] += len(data)
        self.traffic["datagrams_received"] += 1
        kind = "report" if data and data[0] & 0x0F == FrameType.REPORT else "other"
        self._recent.append((wall.monotonic(), len(data) + UDP_IP_BYTES, kind))
        try:
            header = read_header(data)
            module = self._by_number.get(header.sender)
            if module is None or header.sender == HOST:
                raise Refused("foreign", f"sender {header.sender}")
            if header.type is FrameType.WELCOME:
                self._welcome(module, header, data, arrival)
            elif header.type is FrameType.REPORT:
                self._report(module, header, data, arrival)
            else:
                raise Refused("unexpected", f"a {header.type.name} from a module")
        except Refused as exc:
            stats.refuse(exc.reason)
            return
        stats.received += 1
        self.bytes_by_module[module.entry.id][1] += len(data)

    def _welcome(self, module: _Module, header: Header, data: bytes, arrival: float) -> None:
        plain = open_handshake(module.aead, data)
        if plain is None:
            raise Refused("bad_tag")
        payload = decode_map(plain)
        if want(payload, 0, str, "module id") != module.entry.id:
            raise Refused("foreign", f"WELCOME of {payload[0]!r} as {module.entry.id!r}")
        if unsigned(payload, 1, "version") != VERSION:
            raise Refused("version", f"WELCOME of version {payload[1]}")
        boot = unsigned(payload, 2, "boot count")
        public = want(payload, 3, bytes, "module key", size=32)
        host_public = want(payload, 4, bytes, "host key", size=32)
        if module.hello is None or host_public != module.hello.public:
            raise Refused("stale_session", "a WELCOME to another HELLO")
        if module.keys is not None and public == module.module_public:
            raise Refused("replayed", "a WELCOME already answered")
        if module.keys is not None and want(payload, 5, bytes, "live session", b"") == \
                module.session_public:
            module.state, module.heard = "live", self._time  # alive in our session: keep it
            return
        shared = module.hello.shared(public)
        if shared is None:
            raise Refused("malformed", "module key")
        module.keys = session_keys(shared, module.key, host_public, public,
                                   self.system.system, module.number)
        module.module_public, module.counter = public, header.counter
        module.session_public = host_public
        module.freshness = Freshness(DEFAULT_WATCHDOG_PERIODS * self._dt, module.timeout)
        module.freshness.commit(header.clock, arrival)
        if module.boot is not None and boot != module.boot:
            module.reboots += 1
        module.boot, module.state = boot, "setup"
        module.command, module.wire, module.acked_version = None, None, None
        module.batches = {}
        module.known, module.watchdog_since, module.problem = 0, None, None
        module.heard, module.complete, module.awaiting = self._time, False, None
        self._setup(module)

    def _report(self, module: _Module, header: Header, data: bytes, arrival: float) -> None:
        if module.keys is None or module.freshness is None:
            raise Refused("stale_session", "a REPORT outside a session")
        plain = open_sealed(module.keys.to_host, data)
        if plain is None:
            raise Refused("bad_tag")
        if header.counter <= module.counter:
            raise Refused("replayed", f"counter {header.counter} <= {module.counter}")
        module.freshness.check(header.clock, arrival)
        payload, sensors, carried = self._report_payload(plain, module)
        ack = unsigned(payload, 0, "ack")
        lag = unsigned(payload, 1, "lag", 0)
        status = unsigned(payload, 2, "status", limit=255)
        known = unsigned(payload, 8, "names known", module.known, limit=len(self.names))
        links = want(payload, 4, tuple, "links", ())
        if not all(isinstance(link, tuple) and len(link) == 3
                   and all(isinstance(x, str) for x in link) for link in links):
            raise Refused("malformed", "links")
        want(payload, 5, tuple, "events", ())  # docking shows in ``links``; events are for logs
        battery = want(payload, 6, (int, float), "battery", -1.0)
        pose = pose_from_wire(payload[7]) if 7 in payload else None
        if ack > self._counter or ack + lag > self._counter:
            raise Refused("malformed", "ack of a frame never sent")
        # fully accepted
        module.counter = header.counter
        module.freshness.commit(header.clock, arrival)
        module.state = "live"
        module.heard, module.awaiting = self._time, None
        module.reports += 1
        module.status, module.known = status, known
        if sensors is not INCOMPLETE:
            module.sensors, module.complete = sensors, True
        elif carried:  # a partial record whose full value was lost: ask for it
            module.complete = False
        if 4 in payload:
            module.links, module.has_links = links, True
        if pose is not None:
            module.pose = pose
        if battery >= 0:
            module.battery = float(battery)
        self._acknowledged(module, ack, lag)

    def _report_payload(self, plain: bytes, module: _Module
                        ) -> tuple[dict[int, Any], Any, bool]:
        """A REPORT's payload map, its sensor data (merged field by field with the
        module's last; ``INCOMPLETE`` when the report has none or it cannot be completed)
        and whether it carried sensor data.

        Raises:
            Refused: ``malformed``.
        """
        try:
            raw = self.codec.loads(plain)
            if not isinstance(raw, dict) or not all(
                    isinstance(k, int) and not isinstance(k, bool) and k >= 0 for k in raw):
                raise CodecError("a report is a map of unsigned integer keys")
            payload = {k: self.codec.from_wire(v, 1) for k, v in raw.items() if k != 3}
            sensors = self.codec.update(raw[3], module.sensors) if 3 in raw else INCOMPLETE
        except CodecError as exc:
            raise Refused("malformed", str(exc)) from None
        return payload, sensors, 3 in raw

    def _acknowledged(self, module: _Module, ack: int, lag: int) -> None:
        for port in [p for p, counter in module.undock.items() if ack >= counter]:
            del module.undock[port]
        for port in [p for p, (counter, _) in module.docks.items() if ack >= counter]:
            del module.docks[port]
        if ack in module.batches:
            module.acked_version = module.batches[ack]
        for counter in [c for c in module.sent if c <= ack]:
            sent = module.sent.pop(counter)
            if counter == ack:
                self.latencies.append(wall.monotonic() - sent)
        name = module.entry.id
        if module.status & FAULT:
            module.problem = f"module {name} reports its motors stopped while commanded"
        if module.status & WATCHDOG:
            if module.watchdog_since is None:
                module.watchdog_since = self._time
        else:
            module.watchdog_since = None
        if lag and ack:
            applied, received = self._sent_at.get(ack), self._sent_at.get(ack + lag)
            if applied is not None and received is not None and \
                    received - applied >= self._wall(DISOBEY_PERIODS * self._dt) - 1e-9:
                module.problem = (f"module {name} received commands "
                                  f"{(received - applied) * self.system.time_scale:.2f} s newer "
                                  "than the one it applies (not obeying)")

    # -- the Driver contract ---------------------------------------------------------

    def reset(self, start: Configuration) -> None:
        """Expect the modules of ``start``: they must be the systems file's, and each
        must report its latched ports; time becomes 0. The link cannot place modules."""
        self.require_connected()
        want_ids, have = set(start.modules()), set(self.modules)
        if want_ids != have:
            missing, extra = sorted(want_ids - have), sorted(have - want_ids)
            raise ConfigurationError(
                "the modules differ from the configuration's"
                + (f"; not in the systems file: {', '.join(missing[:6])}" if missing else "")
                + (f"; not in the configuration: {', '.join(extra[:6])}" if extra else ""),
                source=str(self.path), field="modules")
        self._time = 0.0
        self._agreed = None
        for module in self.modules.values():
            module.heard, module.reports = 0.0, 0  # links stay: they change by events
            module.undock.clear()
            module.docks.clear()
            module.problem, module.watchdog_since, module.awaiting = None, None, None
        self.send_action({})
        self._wait(lambda m: m.state == "live" and m.reports > 0 and m.has_links, "report",
                   repeat=lambda: self.send_action({}))
        self._mark = wall.monotonic()
        self._recent.clear()  # the handshakes' full reports say nothing of the run's
        self._window_start = self._mark

    def get_observation(self) -> Observation:
        """The newest report of every module. While two modules' reports disagree about a
        latch between them (one was sent before a dock or undock, the other after: a lost
        or late report), the last observation on which they agreed is returned (with the
        current time), for at most the smallest module timeout; then the disagreeing one,
        and the recognizer says what is wrong."""
        self.require_connected()
        poses: dict[str, Pose] = {}
        sensors: dict[str, Any] = {}
        claims: set[tuple[str, str, str, str]] = set()
        for name, module in self.modules.items():
            if module.pose is not None:
                poses[name] = module.pose
            sensors[name] = module.sensors
            for port, other, other_port in module.links:
                if other in self.modules:
                    claims.add((name, port, other, other_port))
        # a module's reported pose is a pose sensor it has (MMRP's tracking), not truth
        observation = Observation(time=self._time, sensors=sensors, tracked=poses)
        agree = all((b, pb, a, pa) in claims for a, pa, b, pb in claims)
        limit = min(m.timeout for m in self.modules.values())
        if agree or self._agreed is None or self._time - self._agreed.time > limit + 1e-9:
            if agree:
                self._agreed = observation
            return observation
        self.held += 1
        return replace(self._agreed, time=self._time)

    def send_action(self, commands: Mapping[str, ModuleCommand]) -> None:
        """One tick's COMMAND frame (several if it would exceed :data:`MAX_FRAME`): every
        linked module's entry, ``null`` for a module not in ``commands`` (it stops); every
        :attr:`every`-th tick it polls them all."""
        self.require_connected()
        unknown = set(commands) - set(self.modules)
        if unknown:
            raise ExecutionError(f"commands for module(s) not in the systems file "
                                 f"{sorted(unknown)}")
        first = self._counter + 1  # the counter of this tick's first frame
        entries = {module.number: self._entry(module, commands.get(name), first)
                   for name, module in self.modules.items() if module.keys is not None}
        self._polled = set(entries) if self._ticks % self.every == 0 else set()
        self._ticks += 1
        for part in self._parts(entries):
            self._send_command({number: entries[number] for number in part})

    def _entry(self, module: _Module, command: ModuleCommand | None, first: int) -> Any:
        """``module``'s entry this tick: ``None`` (stop), its full command, or the
        command's version once the module acknowledged that version."""
        if command is not None:
            for port in command.dock:
                module.undock.pop(port, None)
            for port in command.undock:
                module.undock.setdefault(port, first)
            for port in command.dock:
                module.docks.setdefault(port, (first, self._time))
        for port in list(module.docks):
            if command is None or port not in command.dock:
                del module.docks[port]  # no longer armed: nothing to acknowledge
        if module.undock:  # repeated until acknowledged, even to a module told to stop
            base = command if command is not None else ModuleCommand()
            command = replace(base, undock=tuple(dict.fromkeys((*base.undock, *module.undock))))
        if command is None:
            module.command = module.wire = None
            return None
        entry = command_entry(command, 0, self.names, self.vectors)
        if entry[1:] != module.wire:  # a change finer than the quantum is no change
            module.command, module.wire = command, entry[1:]
            module.version += 1
        if module.acked_version == module.version:
            return module.version % VERSION_MARKS
        entry[0] = module.version % VERSION_MARKS
        return entry

    def _parts(self, entries: Mapping[int, Any]) -> list[list[int]]:
        """The modules of ``entries`` in parts whose COMMAND frames fit one datagram each."""
        parts: list[list[int]] = []
        pending = [list(entries)]
        while pending:
            part = pending.pop()
            if len(part) <= 1 or len(self._command_payload(part, entries)) <= _PAYLOAD_LIMIT:
                parts.append(part)
            else:
                pending += [part[len(part) // 2:], part[:len(part) // 2]]
        return parts

    def _command_payload(self, numbers: list[int], entries: Mapping[int, Any]) -> bytes:
        known = min((self._by_number[n].known for n in numbers), default=len(self.names))
        payload: dict[int, Any] = {0: round(self._watchdog() * 1000), 1: self.every,
                                   2: {n: entries.get(n) for n in numbers}}
        if known < len(self.names):
            payload[3] = [known, *self.names.names[known:]]
        asked = sorted(n for n in numbers if self._asks(self._by_number[n]))
        if asked:
            payload[4] = asked
        polled = [n for n in numbers if n in self._polled or self._late(self._by_number[n])]
        if polled:  # all of them in one tick: one instant of the robot
            payload[5] = True if len(polled) == len(numbers) else sorted(polled)
        return self.codec.encode(payload)

    def _late(self, module: _Module) -> bool:
        """Whether ``module`` has not answered a poll two control periods old (its report,
        or the poll, was lost): it is polled again at once."""
        return module.awaiting is not None and \
            self._time - module.awaiting >= 2 * self._dt - 1e-9

    @staticmethod
    def _asks(module: _Module) -> bool:
        """Whether the host asks ``module`` for a full report at once: it has not reported
        since the run's reset, or the host lacks its links or its full sensor data (the
        reports that carried them were lost)."""
        return module.state == "live" and (
            module.reports == 0 or not module.has_links or not module.complete)

    def _send_command(self, entries: dict[int, Any]) -> None:
        assert self._group is not None and self._signer is not None
        header = self._header(FrameType.COMMAND)
        payload = self._command_payload(list(entries), entries)
        data = seal_signed(self._group, self._signer, header, payload)
        now = wall.monotonic()
        for number, entry in entries.items():
            module = self._by_number[number]
            if number in self._polled and module.awaiting is None:
                module.awaiting = self._time
            module.batches[header.counter] = None if entry is None else module.version
            module.sent[header.counter] = now
            for book in (module.batches, module.sent):
                while len(book) > 128:
                    del book[next(iter(book))]
        if self.system.group is not None:
            self._send(data, (self.system.group.address, self.system.group.port), None)
        else:
            for number in entries:
                self._send(data, self._by_number[number].address, None)
        self._sent_at[header.counter] = now
        while len(self._sent_at) > 256:
            del self._sent_at[next(iter(self._sent_at))]

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
        self._budget()
        self._check()

    def _check(self) -> None:
        gap = (2 * self.every + 1) * self._dt
        for name, module in self.modules.items():
            silent = self._time - module.heard
            if silent > gap and wall.monotonic() - module.hello_at > self._wall(2 * self._dt) \
                    and module.state != "hello":
                module.hello = None
                self._hello(module)  # a rebooted module needs a new handshake
            elif module.state == "hello" and \
                    wall.monotonic() - module.hello_at >= self._wall(RESEND):
                self._hello(module)
            elif module.state == "setup" and \
                    wall.monotonic() - module.setup_at >= self._wall(RESEND):
                self._setup(module)
            if silent > module.timeout + 1e-9:
                refused = self.stats.refused
                raise ExecutionError(
                    f"module {name} silent for {silent:.2f} s (timeout {module.timeout:g} s)"
                    + (f"; frames refused: {_counts(refused)}" if refused else "")
                    + "; run stopped")
            if module.problem is not None:
                raise ExecutionError(f"{module.problem}; run stopped")
            if module.watchdog_since is not None and \
                    self._time - module.watchdog_since > module.timeout + 1e-9:
                raise ExecutionError(f"module {name} heard no valid command for "
                                     f"{self._time - module.watchdog_since:.2f} s (its watchdog "
                                     f"stopped it; timeout {module.timeout:g} s); run stopped")
            for kind, pending in (("dock", {p: t for p, (_, t) in module.docks.items()}),
                                  ("undock", dict.fromkeys(module.undock, None))):
                for port, since in pending.items():
                    if since is None:
                        continue
                    if self._time - since > module.timeout + 1e-9:
                        raise ExecutionError(f"module {name} did not acknowledge the {kind} "
                                             f"of port {port} within {module.timeout:g} s; "
                                             "run stopped")

    # -- the budget --------------------------------------------------------------------

    def _estimate(self, every: int, commands: float, other: float, report: float) -> float:
        """Bytes per second [system time] with reports every ``every`` control periods:
        COMMAND frames ``commands`` and other frames ``other`` [B/s], and one report of
        ``report`` bytes per module per ``every`` periods (UDP/IP included throughout)."""
        return commands + other + len(self.modules) * report / (every * self._dt)

    def _initial_every(self) -> int:
        """The report spacing to start with: under a budget the widest (reports come
        closer once the traffic measured leaves room, :meth:`_budget`)."""
        return 1 if self.system.budget_kbps is None else self._max_every()

    def _spacing(self, budget: float, share: float, commands: float, other: float,
                 report: float) -> int:
        """The smallest report spacing whose estimate is within ``share`` of ``budget``
        (at most :meth:`_max_every`)."""
        for every in range(1, self._max_every()):
            if self._estimate(every, commands, other, report) <= share * budget * 125:
                return every
        return self._max_every()

    def _max_every(self) -> int:
        """The widest report spacing [control periods] (:data:`MAX_EVERY`)."""
        timeout = min(m.timeout for m in self.modules.values())
        return max(1, min(MAX_EVERY, math.floor(timeout / (4 * self._dt) + 1e-9)))

    def _budget(self) -> None:
        """Set the report spacing from the traffic of the last :data:`BUDGET_WINDOW`
        seconds [wall], checked every :data:`BUDGET_STEP`: the COMMAND frames' and other
        frames' bytes per second as measured, the reports' as their mean size times one
        per module per ``every`` periods (per second of system time, as the budget: an
        emulator faster than real time stands for a network at real time). Spaced
        further at once when the estimate exceeds :data:`BUDGET_HIGH` of the budget;
        one period closer when the closer spacing stays within :data:`BUDGET_LOW`."""
        budget = self.system.budget_kbps
        now = wall.monotonic()
        while self._recent and self._recent[0][0] < now - BUDGET_WINDOW:
            self._recent.popleft()
        if budget is None or now - self._budget_at < BUDGET_STEP or \
                now - self._window_start < BUDGET_STEP:
            return
        self._budget_at = now
        span = min(BUDGET_WINDOW, now - self._window_start) * self.system.time_scale
        sums = {"command": 0, "report": 0, "other": 0}
        reports = 0
        for _, size, kind in self._recent:
            sums[kind] += size
            reports += kind == "report"
        if not reports:
            return
        commands, other = sums["command"] / span, sums["other"] / span
        report = sums["report"] / reports
        wanted = self._spacing(budget, BUDGET_HIGH, commands, other, report)
        if wanted > self.every:
            self.every = wanted
        elif self.every > 1 and self._estimate(self.every - 1, commands, other, report) \
                <= BUDGET_LOW * budget * 125:
            self.every -= 1

    @property
    def time(self) -> float:
        return self._time

    def reboots(self) -> dict[str, int]:
        """Re-handshakes of each module after a reboot (a new boot count) since connect."""
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
