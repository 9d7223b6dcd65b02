"""The module side of the link protocol: what a module's firmware does, in Python.

:class:`ModuleLink` is one module's protocol state: it answers a HELLO of its system
(a session it has not seen since boot) with a WELCOME carrying a fresh link nonce,
obeys COMMAND frames of that session and link only, with increasing sequence numbers
and within the age window, and stops its motors when no valid command arrived for
the watchdog time. The emulator (:mod:`.emulator`) runs one per emulated module;
firmware implements the same state machine (``docs/protocol.md``).
"""

from __future__ import annotations

import math
import secrets
import socket
from dataclasses import dataclass, field
from typing import Any

from ..driver import ModuleCommand
from .protocol import HOST, VERSION, Endpoint, FrameType, Refused, command_from_payload

__all__ = ["DEFAULT_WATCHDOG_PERIODS", "ModuleLink", "WatchdogTrip"]

DEFAULT_WATCHDOG_PERIODS = 3
"""Default watchdog: this many control periods without a valid command stop the motors."""


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
class ModuleLink:
    """One module's end of the link (module doc).

    Attributes:
        module: module id. number: link number. sock: its bound UDP socket.
        endpoint: frame checks and counters. watchdog: [s], until the host sets one.
        host: the host's address once a HELLO was accepted.
        session, link: nonces of the current session (0: none).
        command: the last valid command (``None``: stop). command_clock: when [s].
        stop: the host asked for a stop (module not named in its last command set).
        applied: highest command sequence number applied.
        trips: every watchdog stop.
        reported: reports sent in this session.
        outbox: datagrams to send and where (the owner sends them, with its faults).
    """

    module: str
    number: int
    sock: socket.socket
    endpoint: Endpoint
    watchdog: float
    host: tuple[str, int] | None = None
    session: int = 0
    link: int = 0
    command: ModuleCommand | None = None
    command_clock: float = 0.0
    applied: int = 0
    reported: int = 0
    seen_sessions: set[int] = field(default_factory=set)
    trips: list[WatchdogTrip] = field(default_factory=list)
    outbox: list[tuple[bytes, tuple[str, int]]] = field(default_factory=list)
    boots: int = 1
    _tripped: bool = False
    _checked: float = -math.inf

    def reboot(self) -> None:
        """Forget the session and the command (a power cycle); motors stop."""
        self.host, self.session, self.link = None, 0, 0
        self.command, self.applied, self._tripped = None, 0, False
        self.seen_sessions.clear()
        self.endpoint.peers.clear()
        self.boots += 1

    def handle(self, datagram: bytes, address: tuple[str, int], clock: float) -> str | None:
        """Process one received datagram at module clock ``clock`` [s].

        Returns:
            ``None`` when accepted, else the refusal reason (also counted).
        """
        try:  # refusals of the frame checks are counted by the endpoint
            if self.session and datagram[3:4] == bytes([FrameType.COMMAND]):
                frame = self.endpoint.accept(datagram, clock, session=self.session,
                                             link=self.link)
            else:
                frame = self.endpoint.accept(datagram, clock, session=None, link=None)
        except Refused as exc:
            return exc.reason
        try:
            if frame.sender != HOST:
                raise Refused("foreign", f"sender {frame.sender}")
            if frame.type is FrameType.HELLO:
                if frame.session == self.session and self.host is not None:
                    self.host = address
                    self._send(FrameType.WELCOME, clock, {"id": self.module, "version": VERSION,
                                                          "boot": self.boots})
                    return None  # the host missed our WELCOME: same link again
                if frame.session in self.seen_sessions:
                    raise Refused("replayed", "a HELLO of an earlier session")
                self.seen_sessions.add(frame.session)
                self.host, self.session = address, frame.session
                self.link = secrets.randbits(32) | 1
                self.command, self.applied, self.reported = None, 0, 0
                self._send(FrameType.WELCOME, clock, {"id": self.module, "version": VERSION,
                                                      "boot": self.boots})
                return None
            if frame.type is FrameType.BYE:
                if (frame.session, frame.link) == (self.session, self.link):
                    self.command = None
                    self.session = self.link = 0
                    return None
                raise Refused("stale_session")
            if frame.type is not FrameType.COMMAND or not self.session:
                raise Refused("stale_session", f"{frame.type.name} outside a session")
            payload = frame.payload
            if not isinstance(payload, dict):
                raise Refused("malformed", "command payload is not a map")
            self.command = None if payload.get("s") else command_from_payload(payload)
            wd = payload.get("wd")
            if isinstance(wd, int | float) and not isinstance(wd, bool) and wd > 0:
                self.watchdog = float(wd)
            self.command_clock, self.applied, self._tripped = clock, frame.seq, False
            self.host = address
            return None
        except Refused as exc:
            self.endpoint.stats.refuse(exc.reason)
            return exc.reason

    def current(self, clock: float) -> ModuleCommand | None:
        """The command to apply at ``clock`` [s]: ``None`` (motors stopped) without a
        session, after a stop, or once the watchdog expired (recorded in :attr:`trips`)."""
        previous, self._checked = self._checked, clock
        if self.command is None:
            return None
        if clock - self.command_clock > self.watchdog + 1e-9:
            if not self._tripped:
                self._tripped = True
                self.trips.append(WatchdogTrip(self.module, self.command_clock, clock,
                                               previous))
            return None
        return self.command

    def report(self, clock: float, payload: dict[str, Any]) -> None:
        """Send a REPORT (``ack`` added) to the host, if in a session."""
        if self.session and self.host is not None:
            self._send(FrameType.REPORT, clock, {"ack": self.applied, **payload})
            self.reported += 1

    def _send(self, frame_type: FrameType, clock: float, payload: Any) -> None:
        assert self.host is not None
        data = self.endpoint.encode(frame_type, HOST, session=self.session, link=self.link,
                                    clock=clock, payload=payload)
        self.outbox.append((data, self.host))
