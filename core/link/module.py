"""The module side of the link protocol: what a module's firmware does, in Python.

:class:`ModuleLink` is one module's protocol state (``docs/protocol.md``):

* **Handshake.** A HELLO sealed with the module's key (a fresh host X25519 key the
  module has not seen since it booted) is answered with a WELCOME carrying the
  module's own fresh X25519 key; both sides derive the session keys. That is all a
  HELLO does: the live session, its counters and its command are untouched. Only a
  SETUP sealed with the *new* session key -- which only the host that sent the HELLO
  can make -- replaces the live session (motors stop, the command is forgotten).
* **Counters.** The host has one counter across all its frames of a session (SETUP,
  COMMAND, BYE); the module accepts a host frame only with a counter above the last
  accepted one, and records anything about a frame only once it is fully accepted
  (authentic, counter, age, payload).
* **Commands.** The COMMAND frame of each tick (sealed with the run's group key, signed
  by the host) holds one entry per module: ``null`` (stop), a full command, or only its
  version (unchanged). The newest accepted command is applied at the module's next
  control tick; no valid command for ``watchdog`` seconds stops the motors and disarms
  the connectors.
* **Reports** are sent every ``every``-th control tick (the host sets it to keep the
  link within its budget) and at the control tick after a COMMAND frame that polls the
  module (the host polls all modules at once every ``every`` periods: the polls align
  the modules' phases, so their reports show one instant, and ask again for a lost
  one), and at once on a docking event, a change of the latched ports or of
  the status, a command accepted but not applied, or the host's asking for a full
  report. Unchanged sensor fields (field by field for a record), pose, links and the
  names known are left out except for a refresh every :data:`REFRESH` reports (or when
  asked) and the :data:`REPEAT` reports after each change; the pose goes at most every
  ``pose_every``-th report (SETUP).

The emulator (:mod:`.emulator`) runs one per emulated module.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Any

import cbor2

from ..driver import ModuleCommand, Pose
from .codec import TAG_RECORD, Codec
from .keys import Aead, Ephemeral, SessionKeys, Verifier, session_keys
from .protocol import (
    HOST,
    MAX_COUNTER,
    VERSION,
    FrameType,
    Freshness,
    Header,
    LinkStats,
    Refused,
    clock_ms,
    decode_map,
    open_handshake,
    open_sealed,
    open_signed,
    parse_entry,
    pose_wire,
    read_header,
    seal,
    seal_handshake,
    unsigned,
    want,
)

__all__ = ["DEFAULT_WATCHDOG_PERIODS", "FAULT", "MOVING", "REFRESH", "REPEAT", "WATCHDOG",
           "ModuleLink", "WatchdogTrip"]

DEFAULT_WATCHDOG_PERIODS = 3
"""Default watchdog: this many control periods without a valid command stop the motors."""
MOVING, WATCHDOG, FAULT = 1, 2, 4
"""Status bits of a report: executing a motion command; stopped by the watchdog; the
motors failed (a motor driver's fault: commanded but not turning)."""
REFRESH = 10
"""Every this many reports carry everything (sensors, pose, links, battery)."""
REPEAT = 3
"""A changed sensor value, pose or set of links is in this many reports after the change."""
SEEN = 256
"""Host keys remembered since boot (a HELLO with one of them is a replay)."""


@dataclass(frozen=True)
class WatchdogTrip:
    """The motors of ``module`` were stopped at module clock ``at`` [s]; the last valid
    command had arrived at ``last`` [s]; the check before was at ``previous`` [s] (so
    ``previous - last <= watchdog < at - last``: stopped at the first check after)."""

    module: str
    last: float
    at: float
    previous: float


@dataclass
class _Pending:
    host_public: bytes
    keys: SessionKeys
    welcome: bytes


@dataclass
class _Slot:
    """One part of a report sent on change: its bytes when last seen, and how many
    more reports must carry it."""

    data: bytes | None = None
    repeat: int = 0

    def update(self, data: bytes) -> bool:
        """Note this tick's value; ``True`` if it changed."""
        if data == self.data:
            return False
        self.data, self.repeat = data, REPEAT
        return True

    def take(self, refresh: bool) -> bool:
        """Whether this report carries it (and count one)."""
        if self.repeat > 0 or refresh:
            self.repeat -= 1
            return True
        return False


@dataclass
class _Session:
    host_public: bytes
    keys: SessionKeys
    group: Aead
    verifier: Verifier
    host_counter: int
    freshness: Freshness
    address: tuple[str, int]
    counter: int = 1
    every: int = 1
    names: list[str] = field(default_factory=list)
    ticks: int = 0
    reported: int = 0
    record: int | None = None
    fields: list[_Slot] = field(default_factory=list)
    sensors: _Slot = field(default_factory=_Slot)
    pose: _Slot = field(default_factory=_Slot)
    pose_every: int = 1
    pose_age: int = 0  # reports since the pose was last sent
    links: _Slot = field(default_factory=_Slot)
    known: _Slot = field(default_factory=_Slot)
    status: int = -1
    events: list[Any] = field(default_factory=list)
    asked: bool = False  # the host asked for a full report at once
    polled: bool = False  # the host polled since the last report
    since: int = 0  # control ticks since the last report


class ModuleLink:
    """One module's end of the link (module doc).

    Args:
        module: module id (configurations). number: link number (1-65535).
        key: this module's key (:func:`~.keys.module_key`); never printed.
        system: the system id. watchdog: [s] until the host sets one.
        codec: encodes the module's sensor data (its record table).

    Attributes:
        command: the last accepted command (``None``: stopped). command_clock: when [s].
        applied: counter of the host frame whose command is applied (a report's ``ack``).
        received: counter of the newest COMMAND frame accepted.
        obey: ``False`` makes the module accept commands without applying them (a
            firmware fault the emulator injects; the host must notice).
        motor_fault: the motors do not turn although commanded (reported as FAULT).
        trips: every watchdog stop. outbox: datagrams to send and where (the owner
        sends them, with its faults).
    """

    def __init__(self, module: str, number: int, key: bytes, system: int, *, watchdog: float,
                 codec: Codec | None = None):
        self.module = module
        self.number = number
        self.system = system
        self._key = key
        self._aead = Aead(key)
        self.watchdog = watchdog
        self.codec = codec if codec is not None else Codec()
        self.stats = LinkStats()
        self.boots = 1
        self.seen: OrderedDict[bytes, None] = OrderedDict()
        self.pending: _Pending | None = None
        self.live: _Session | None = None
        self.command: ModuleCommand | None = None
        self.version: int | None = None
        self.command_clock = 0.0
        self.applied = 0
        self.received = 0
        self.obey = True
        self.motor_fault = False
        self.trips: list[WatchdogTrip] = []
        self.outbox: list[tuple[bytes, tuple[str, int]]] = []
        self._tripped = False
        self._checked = -math.inf

    def __repr__(self) -> str:
        return f"ModuleLink({self.module!r}, number={self.number})"

    @property
    def session(self) -> bool:
        """Whether a session is live."""
        return self.live is not None

    def reboot(self) -> None:
        """Forget everything of the sessions and the command (a power cycle)."""
        self.seen.clear()
        self.pending = self.live = None
        self._stop()
        self.boots += 1

    def _stop(self) -> None:
        self.command, self.version, self.applied, self.received = None, None, 0, 0
        self._tripped = False

    # -- receiving -----------------------------------------------------------------------

    def handle(self, datagram: bytes, address: tuple[str, int], clock: float) -> str | None:
        """Process one datagram that arrived at module clock ``clock`` [s].

        Returns:
            ``None`` when accepted, else the refusal reason (also counted).
        """
        self.stats.bytes_received += len(datagram)
        try:
            header = read_header(datagram)
            if header.sender != HOST:
                raise Refused("foreign", f"sender {header.sender}")
            if header.type is FrameType.HELLO:
                self._hello(datagram, address, clock)
            elif header.type is FrameType.SETUP:
                self._setup(header, datagram, address, clock)
            elif header.type is FrameType.COMMAND:
                self._command(header, datagram, address, clock)
            elif header.type is FrameType.BYE:
                self._bye(header, datagram, clock)
            else:
                raise Refused("unexpected", f"a {header.type.name} from the host")
        except Refused as exc:
            self.stats.refuse(exc.reason)
            return exc.reason
        self.stats.received += 1
        return None

    def _hello(self, datagram: bytes, address: tuple[str, int], clock: float) -> None:
        plain = open_handshake(self._aead, datagram)
        if plain is None:
            raise Refused("bad_tag")
        payload = decode_map(plain)
        if unsigned(payload, 0, "version") != VERSION:
            raise Refused("version", f"HELLO of version {payload[0]}")
        host_public = want(payload, 1, bytes, "host key", size=32)
        if self.pending is not None and host_public == self.pending.host_public:
            self.outbox.append((self.pending.welcome, address))  # the host missed it
            return
        if host_public in self.seen:
            raise Refused("replayed", "a HELLO already answered since boot")
        mine = Ephemeral()
        shared = mine.shared(host_public)
        if shared is None:
            raise Refused("malformed", "host key")
        keys = session_keys(shared, self._key, host_public, mine.public, self.system,
                            self.number)
        answer = {0: self.module, 1: VERSION, 2: self.boots, 3: mine.public, 4: host_public}
        if self.live is not None:
            answer[5] = self.live.host_public  # the host whose session is live here
        welcome = seal_handshake(self._aead, Header(FrameType.WELCOME, self.number, 1,
                                                    clock_ms(clock)), self.codec.encode(answer))
        self.seen[host_public] = None
        while len(self.seen) > SEEN:
            self.seen.popitem(last=False)
        self.pending = _Pending(host_public, keys, welcome)
        self.outbox.append((welcome, address))
        self.stats.sent += 1
        self.stats.bytes_sent += len(welcome)

    def _setup(self, header: Header, datagram: bytes, address: tuple[str, int],
               clock: float) -> None:
        live, pending = self.live, self.pending
        if live is not None and (plain := open_sealed(live.keys.to_module, datagram)) is not None:
            if header.counter <= live.host_counter:
                raise Refused("replayed", f"counter {header.counter} <= {live.host_counter}")
            live.freshness.check(header.clock, clock)
            settings = self._settings(decode_map(plain))
            live.host_counter = header.counter
            live.freshness.commit(header.clock, clock)
            live.address = address
            self._apply_settings(live, settings)
            return
        if pending is None or (plain := open_sealed(pending.keys.to_module, datagram)) is None:
            raise Refused("bad_tag" if live or pending else "stale_session")
        payload = decode_map(plain)
        settings = self._settings(payload)
        group = Aead(want(payload, 0, bytes, "group key", size=32))
        verifier = Verifier.parse(want(payload, 1, bytes, "host signing key", size=32))
        if verifier is None:
            raise Refused("malformed", "host signing key")
        freshness = Freshness(settings[0], settings[2])
        session = _Session(pending.host_public, pending.keys, group, verifier, header.counter,
                           freshness, address)
        freshness.commit(header.clock, clock)
        self.live, self.pending = session, None  # the new session replaces the old one
        self._stop()
        self._apply_settings(session, settings)

    @staticmethod
    def _settings(payload: dict[int, Any]) -> tuple[float, int, float, int]:
        watchdog = unsigned(payload, 2, "watchdog", limit=600_000) / 1000.0
        every = unsigned(payload, 3, "report period", limit=100)
        window = unsigned(payload, 4, "age window", limit=600_000) / 1000.0
        pose_every = unsigned(payload, 5, "pose spacing", 1, limit=10)
        if watchdog <= 0 or every < 1 or pose_every < 1:
            raise Refused("malformed", "watchdog, report period or pose spacing")
        return watchdog, every, window, pose_every

    def _apply_settings(self, session: _Session, settings: tuple[float, int, float, int]
                        ) -> None:
        self.watchdog, session.every, session.freshness.ceiling, session.pose_every = settings
        session.freshness.ceiling = max(session.freshness.ceiling, session.freshness.floor)

    def _command(self, header: Header, datagram: bytes, address: tuple[str, int],
                 clock: float) -> None:
        live = self.live
        if live is None:
            raise Refused("stale_session", "a COMMAND outside a session")
        plain = open_signed(live.group, live.verifier, datagram)
        if plain is None:
            raise Refused("bad_tag")
        if header.counter <= live.host_counter:
            raise Refused("replayed", f"counter {header.counter} <= {live.host_counter}")
        live.freshness.check(header.clock, clock)
        payload = decode_map(plain)
        watchdog = unsigned(payload, 0, "watchdog", limit=600_000) / 1000.0
        every = unsigned(payload, 1, "report period", live.every, limit=100)
        entries = want(payload, 2, dict, "entries", {})
        asked = want(payload, 4, tuple, "asked", ())
        poll = want(payload, 5, (bool, tuple), "poll", False)
        if not all(isinstance(n, int) and not isinstance(n, bool)
                   for n in (*asked, *(poll if isinstance(poll, tuple) else ()))):
            raise Refused("malformed", "asked or poll")
        names = live.names
        if 3 in payload:
            defs = want(payload, 3, tuple, "names")
            if not (defs and isinstance(defs[0], int) and not isinstance(defs[0], bool)
                    and all(isinstance(n, str) for n in defs[1:])):
                raise Refused("malformed", "names")
            if defs[0] <= len(names):
                names = names + list(defs[1 + len(names) - defs[0]:])
        if watchdog <= 0 or every < 1:
            raise Refused("malformed", "watchdog or report period")
        named = self.number in entries
        entry = entries.get(self.number)
        version, command = parse_entry(entry, names) if entry is not None else (None, None)
        # fully accepted: now the state moves
        live.host_counter = header.counter
        live.freshness.commit(header.clock, clock)
        live.names, live.every, live.address = names, every, address
        live.asked = live.asked or self.number in asked
        self.watchdog = watchdog
        if not named:  # another part of this tick's command, for other modules
            return
        live.polled = live.polled or poll is True or (
            isinstance(poll, tuple) and self.number in poll)
        self.received = header.counter
        if not self.obey:
            return
        if entry is None:  # stop
            self.command, self.version = None, None
        elif command is not None:
            self.command, self.version = command, version
        elif version != self.version or self.command is None:
            return  # unchanged since a version this module never got: not applied
        self.command_clock, self.applied, self._tripped = clock, header.counter, False

    def _bye(self, header: Header, datagram: bytes, clock: float) -> None:
        live = self.live
        if live is None or (plain := open_sealed(live.keys.to_module, datagram)) is None:
            raise Refused("stale_session" if live is None else "bad_tag")
        if header.counter <= live.host_counter:
            raise Refused("replayed", f"counter {header.counter} <= {live.host_counter}")
        decode_map(plain)
        self.live = self.pending = None
        self._stop()

    # -- the control tick ----------------------------------------------------------------

    def current(self, clock: float) -> ModuleCommand | None:
        """The command to apply at ``clock`` [s]: ``None`` (motors stopped) without a
        session, after a stop, or once the watchdog expired (recorded in :attr:`trips`)."""
        previous, self._checked = self._checked, clock
        if self.command is None or self.live is None:
            return None
        if clock - self.command_clock > self.watchdog + 1e-9:
            if not self._tripped:
                self._tripped = True
                self.trips.append(WatchdogTrip(self.module, self.command_clock, clock,
                                               previous))
            return None
        return self.command

    def status(self) -> int:
        """The status bits of the next report."""
        moving = (self.command is not None and not self._tripped
                  and bool(self.command.joints or self.command.wheels))
        return ((MOVING if moving and not self.motor_fault else 0)
                | (WATCHDOG if self._tripped else 0)
                | (FAULT if self.motor_fault and moving else 0))

    def report(self, clock: float, *, sensors: Any = None, pose: Pose | None = None,
               links: tuple[Any, ...] = (), events: list[Any] | None = None,
               battery: float | None = None) -> bool:
        """This control tick's REPORT, if one is due (module doc). Returns whether sent.

        Raises:
            CodecError: sensor data the record table cannot carry.
        """
        live = self.live
        if live is None:
            return False
        live.ticks += 1
        live.since += 1
        live.events.extend(events or ())
        tree = self.codec.to_wire(sensors)
        fields = _fields(tree)
        if len(fields) != len(live.fields) or (fields and tree.value[0] != live.record):
            live.fields = [_Slot() for _ in fields]
            live.record = tree.value[0] if fields else None
        for slot, item in zip(live.fields, fields, strict=True):
            slot.update(self.codec.dumps(item))
        if not fields:
            live.sensors.update(self.codec.dumps(tree))
        wire_pose = pose_wire(pose) if pose is not None else None
        live.pose.update(self.codec.dumps(wire_pose))
        links = tuple(sorted(links))
        changed = live.links.update(self.codec.dumps([list(link) for link in links]))
        status = self.status()
        due = live.polled or live.since >= live.every  # a poll aligns the period's phase
        urgent = (live.reported < REPEAT or changed or bool(live.events) or live.asked
                  or status != live.status or self.received > self.applied)
        if not (due or urgent):
            return False
        payload = self._payload(live, tree, fields, links, wire_pose, status, battery)
        return self._send_report(live, clock, payload, status)

    def _payload(self, live: _Session, tree: Any, fields: list[Any], links: tuple[Any, ...],
                 wire_pose: Any, status: int, battery: float | None) -> dict[int, Any]:
        """A REPORT's payload: what changed lately, everything on a refresh."""
        refresh = live.reported % REFRESH == 0 or live.asked
        payload: dict[int, Any] = {0: self.applied, 2: status}
        live.known.update(len(live.names).to_bytes(4, "little"))
        if live.known.take(refresh):
            payload[8] = len(live.names)
        if self.received > self.applied:
            payload[1] = self.received - self.applied
        if fields:
            sent = [item if slot.take(refresh) else cbor2.undefined
                    for slot, item in zip(live.fields, fields, strict=True)]
            if any(item is not cbor2.undefined for item in sent):
                payload[3] = cbor2.CBORTag(tree.tag, [tree.value[0], *sent])
        elif live.sensors.take(refresh):
            payload[3] = tree
        if live.links.take(refresh):
            payload[4] = [list(link) for link in links]
        if live.events:
            payload[5] = self.codec.to_wire(live.events)
        if battery is not None and refresh:
            payload[6] = self.codec.to_wire(battery)
        live.pose_age += 1
        if wire_pose is not None and (refresh or live.reported < REPEAT or (
                live.pose.repeat > 0 and live.pose_age >= live.pose_every)):
            live.pose.take(refresh)
            payload[7], live.pose_age = wire_pose, 0
        return payload

    def _send_report(self, live: _Session, clock: float, payload: dict[int, Any],
                     status: int) -> bool:
        live.counter += 1
        if live.counter > MAX_COUNTER:  # a session this long ends; the host links again
            self.live = None
            self._stop()
            return False
        data = seal(live.keys.to_host, Header(FrameType.REPORT, self.number, live.counter,
                                              clock_ms(clock)), self.codec.dumps(payload))
        self.outbox.append((data, live.address))
        self.stats.sent += 1
        self.stats.bytes_sent += len(data)
        live.reported += 1
        live.status = status
        live.events, live.asked, live.polled, live.since = [], False, False, 0
        return True


def _fields(tree: Any) -> list[Any]:
    """The field values of a record's wire tree (``[]`` for anything else)."""
    if isinstance(tree, cbor2.CBORTag) and tree.tag == TAG_RECORD:
        return list(tree.value[1:])
    return []
