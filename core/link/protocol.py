"""The module link protocol, version 1 (``docs/protocol.md`` is its specification).

A frame is one UDP datagram: a fixed 32-byte little-endian header, a CBOR payload
(:mod:`.cbor`) and a 16-byte tag, HMAC-SHA256 (RFC 2104) of header and payload under
the system's key, truncated to 128 bits (RFC 2104 section 5)::

    offset size  field
         0    2  magic b"MS"
         2    1  version (1)
         3    1  type (HELLO 1, WELCOME 2, COMMAND 3, REPORT 4, BYE 5)
         4    4  system id (u32)
         8    2  sender number (u16; 0 is the host)
        10    2  receiver number (u16)
        12    4  session: the host's nonce of this connection (u32)
        16    4  link: the module's nonce of this handshake (u32; 0 in HELLO)
        20    4  sequence number of the sender in this session (u32, from 1)
        24    4  sender clock [ms] (u32)
        28    2  payload length (u16)
        30    2  flags (0)
        32    n  payload (CBOR)
      32+n   16  tag

:class:`Endpoint` is one side's receive check: the frame's tag under the key (else
``bad_tag``), its system and receiver (``foreign``), its session and link nonces
(``stale_session``), a sequence number above the last accepted one of that sender
(``replayed``) and an age within the window (``stale``); each refusal is counted in
:class:`LinkStats`, never logged with the key.
"""

from __future__ import annotations

import hashlib
import hmac
import struct
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Any

from ..driver import ModuleCommand
from ..errors import ExecutionError
from .cbor import CborError, Decoder, dumps

__all__ = ["HEADER", "HOST", "MAGIC", "MAX_FRAME", "TAG_SIZE", "VERSION", "Endpoint", "Frame",
           "FrameType", "LinkStats", "Refused", "command_from_payload", "command_payload",
           "decode_frame", "encode_frame", "tag"]

MAGIC = b"MS"
VERSION = 1
HOST = 0
"""Sender number of the host."""
HEADER = struct.Struct("<2sBBIHHIIIIHH")
TAG_SIZE = 16
MAX_FRAME = 1400
"""Largest frame [bytes]: stays inside one Ethernet/Wi-Fi MTU, no IP fragmentation."""


class FrameType(IntEnum):
    """What a frame carries (the header's ``type``)."""

    HELLO = 1
    WELCOME = 2
    COMMAND = 3
    REPORT = 4
    BYE = 5


@dataclass(frozen=True)
class Frame:
    """One decoded, authenticated frame.

    Attributes:
        type: the frame type. system: system id. sender, receiver: numbers (0: host).
        session: host nonce. link: module nonce. seq: sender's sequence number.
        clock: sender clock [ms]. payload: the decoded CBOR payload.
    """

    type: FrameType
    system: int
    sender: int
    receiver: int
    session: int
    link: int
    seq: int
    clock: int
    payload: Any


class Refused(Exception):
    """A frame dropped by :class:`Endpoint`; ``reason`` is a :class:`LinkStats` counter."""

    def __init__(self, reason: str, detail: str = ""):
        super().__init__(f"{reason}: {detail}" if detail else reason)
        self.reason = reason


def tag(key: bytes, data: bytes) -> bytes:
    """HMAC-SHA256 of ``data`` under ``key``, first :data:`TAG_SIZE` bytes."""
    return hmac.new(key, data, hashlib.sha256).digest()[:TAG_SIZE]


def encode_frame(key: bytes, frame_type: FrameType, *, system: int, sender: int, receiver: int,
                 session: int, link: int, seq: int, clock_ms: int, payload: Any) -> bytes:
    """The datagram of one frame (layout: module doc).

    Raises:
        ExecutionError: the frame would exceed :data:`MAX_FRAME` bytes.
    """
    body = dumps(payload)
    header = HEADER.pack(MAGIC, VERSION, int(frame_type), system, sender, receiver, session,
                         link, seq & 0xFFFFFFFF, clock_ms & 0xFFFFFFFF, len(body), 0)
    data = header + body
    if len(data) + TAG_SIZE > MAX_FRAME:
        raise ExecutionError(f"link frame of {len(data) + TAG_SIZE} bytes is larger than "
                             f"{MAX_FRAME}")
    return data + tag(key, data)


def decode_frame(key: bytes, datagram: bytes, decoder: Decoder) -> Frame:
    """Check the tag and layout of ``datagram`` and decode it.

    Raises:
        Refused: ``malformed`` (length, magic, payload), ``version`` or ``bad_tag``.
    """
    if len(datagram) < HEADER.size + TAG_SIZE:
        raise Refused("malformed", f"{len(datagram)} bytes")
    data, received = datagram[:-TAG_SIZE], datagram[-TAG_SIZE:]
    if not hmac.compare_digest(tag(key, data), received):
        raise Refused("bad_tag")
    (magic, version, kind, system, sender, receiver, session, link, seq, clock, length,
     _flags) = HEADER.unpack_from(data)
    if magic != MAGIC or length != len(data) - HEADER.size:
        raise Refused("malformed", "magic or length")
    if version != VERSION:
        raise Refused("version", f"version {version}, this host speaks {VERSION}")
    try:
        frame_type = FrameType(kind)
        payload = decoder.loads(data[HEADER.size:])
    except (ValueError, CborError) as exc:
        raise Refused("malformed", str(exc)) from None
    return Frame(frame_type, system, sender, receiver, session, link, seq, clock, payload)


@dataclass
class LinkStats:
    """Counters of one endpoint: frames and bytes each way, and every refusal by reason."""

    sent: int = 0
    received: int = 0
    bytes_sent: int = 0
    bytes_received: int = 0
    refused: dict[str, int] = field(default_factory=dict)

    def refuse(self, reason: str) -> None:
        self.refused[reason] = self.refused.get(reason, 0) + 1

    def total_refused(self) -> int:
        return sum(self.refused.values())


@dataclass
class _Peer:
    session: int = 0
    link: int = 0
    seq: int = 0
    delays: deque[float] = field(default_factory=lambda: deque(maxlen=20))


class Endpoint:
    """One side of a system's links: authenticates, de-duplicates and ages frames.

    Args:
        key: the system's shared key (never logged or stored by this object's repr).
        system: the system id. number: this side's number (0: host).
        window: largest age [s] of an accepted frame: its delay beyond the smallest
            delay of the sender's last 20 accepted frames (clock offsets cancel).
        packages: packages whose dataclasses a payload may carry (:class:`Decoder`).
    """

    def __init__(self, key: bytes, system: int, number: int, *, window: float,
                 packages: tuple[str, ...] = ()):
        self._key = key
        self.system = system
        self.number = number
        self.window = window
        self.decoder = Decoder(packages)
        self.stats = LinkStats()
        self.peers: dict[int, _Peer] = {}
        self.seq = 0

    def __repr__(self) -> str:
        return f"Endpoint(system={self.system}, number={self.number})"

    def encode(self, frame_type: FrameType, receiver: int, *, session: int, link: int,
               clock: float, payload: Any) -> bytes:
        """The next frame of this side (sequence number + 1); ``clock`` [s]."""
        self.seq += 1
        data = encode_frame(self._key, frame_type, system=self.system, sender=self.number,
                            receiver=receiver, session=session, link=link, seq=self.seq,
                            clock_ms=round(clock * 1000), payload=payload)
        self.stats.sent += 1
        self.stats.bytes_sent += len(data)
        return data

    def accept(self, datagram: bytes, now: float, *, session: int | None,
               link: int | None) -> Frame:
        """Check ``datagram`` received at this side's clock ``now`` [s].

        Args:
            session, link: nonces the frame must carry (``None``: any, as in a HELLO
                or WELCOME, which start a new session; the sequence restarts then).

        Raises:
            Refused: counted in :attr:`stats` under its reason.
        """
        self.stats.bytes_received += len(datagram)
        try:
            frame = decode_frame(self._key, datagram, self.decoder)
            if frame.system != self.system or frame.receiver != self.number:
                raise Refused("foreign", f"system {frame.system} to {frame.receiver}")
            if ((session is not None and frame.session != session)
                    or (link is not None and frame.link != link)):
                raise Refused("stale_session")
            peer = self.peers.setdefault(frame.sender, _Peer())
            fresh = (frame.session, frame.link) != (peer.session, peer.link)
            if not fresh and frame.seq <= peer.seq:
                raise Refused("replayed", f"sequence {frame.seq} <= {peer.seq}")
            delay = now - frame.clock / 1000.0
            if fresh:
                peer.delays.clear()
            if peer.delays and delay - min(peer.delays) > self.window:
                raise Refused("stale", f"{delay - min(peer.delays):.3f} s late")
        except Refused as exc:
            self.stats.refuse(exc.reason)
            raise
        peer.session, peer.link, peer.seq = frame.session, frame.link, frame.seq
        peer.delays.append(delay)
        self.stats.received += 1
        return frame


def command_payload(command: ModuleCommand, undock: tuple[str, ...] = ()) -> dict[str, Any]:
    """The COMMAND payload of ``command`` (``undock`` adds ports to release)."""
    out: dict[str, Any] = {}
    if command.joints:
        out["j"] = {str(k): float(v) for k, v in command.joints.items()}
    if command.wheels:
        out["w"] = {str(k): float(v) for k, v in command.wheels.items()}
    if command.dock:
        out["d"] = list(command.dock)
    ports = tuple(dict.fromkeys((*command.undock, *undock)))
    if ports:
        out["u"] = list(ports)
    return out


def command_from_payload(payload: Any) -> ModuleCommand:
    """The :class:`ModuleCommand` of a COMMAND payload.

    Raises:
        Refused: ``malformed`` when a field has the wrong type.
    """
    if not isinstance(payload, Mapping):
        raise Refused("malformed", "command payload is not a map")

    def numbers(name: str) -> dict[str, float]:
        value = payload.get(name, {})
        if not isinstance(value, Mapping) or not all(
                isinstance(k, str) and isinstance(v, int | float) and not isinstance(v, bool)
                for k, v in value.items()):
            raise Refused("malformed", f"command field {name!r}")
        return {k: float(v) for k, v in value.items()}

    def ports(name: str) -> tuple[str, ...]:
        value = payload.get(name, ())
        if not isinstance(value, tuple) or not all(isinstance(p, str) for p in value):
            raise Refused("malformed", f"command field {name!r}")
        return value

    return ModuleCommand(joints=numbers("j"), wheels=numbers("w"), dock=ports("d"),
                         undock=ports("u"))
