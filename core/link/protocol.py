"""The module link protocol, version 2 (``docs/protocol.md`` is its specification).

A frame is one UDP datagram: a 9-byte little-endian header, then the payload sealed by
ChaCha20-Poly1305 (:mod:`.keys`) with the header as associated data::

    offset size  field
         0    1  version (high 4 bits, 2) and type (low 4 bits)
         1    2  sender number (u16; 0 is the host)
         3    4  counter (u32): the sender's frame counter of this session
         7    2  sender clock [ms] mod 65536 (u16)
         9    .  sealed payload (CBOR, :mod:`.codec`) and its 16-byte tag

* session frames (SETUP, REPORT, BYE): the nonce is the counter (12 bytes, little
  endian); the key is the session's key of that direction;
* handshake frames (HELLO, WELCOME): a random 12-byte nonce follows the header (and is
  associated data too); the key is the module key;
* the COMMAND frame of a tick, one for all modules: sealed with the run's group key
  (nonce: the counter), then a 64-byte Ed25519 signature of everything before it.

:class:`Freshness` is the age check of one sender's frames (the window adapts to the
delays measured), :class:`LinkStats` the counters of one end. Payload layouts (integer
map keys) are the ``*_payload`` / ``parse_*`` pairs at the end of this module.
"""

from __future__ import annotations

import math
import secrets
import struct
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from ..driver import ModuleCommand, Pose
from ..errors import ExecutionError
from .codec import (
    DIRECTION_BYTES,
    ROTATION_SIZES,
    Codec,
    CodecError,
    direction_bytes,
    direction_from_bytes,
    rotation_bytes,
    rotation_from_bytes,
)
from .keys import Aead, Signer, Verifier

__all__ = ["HEADER", "HOST", "MAX_FRAME", "NONCE_SIZE", "SIGNATURE_SIZE", "TAG_SIZE",
           "UDP_IP_BYTES", "VERSION", "VERSION_MARKS", "Freshness", "FrameType", "Header", "LinkStats",
           "NameTable", "Refused", "command_entry", "open_handshake", "open_sealed",
           "open_signed", "parse_entry", "read_header", "seal", "seal_handshake",
           "seal_signed"]

VERSION = 2
HOST = 0
"""Sender number of the host."""
HEADER = struct.Struct("<BHIH")
TAG_SIZE = 16
NONCE_SIZE = 12
SIGNATURE_SIZE = 64
MAX_FRAME = 1400
"""Largest frame [bytes]: stays inside one Ethernet/Wi-Fi MTU, no IP fragmentation."""
UDP_IP_BYTES = 28
"""IPv4 (20) and UDP (8) header bytes of every datagram, counted in the link's budget."""
MAX_COUNTER = 0xFFFFFFFF
VERSION_MARKS = 24
"""Command versions travel modulo this (one CBOR byte)."""


class FrameType(IntEnum):
    """What a frame carries (the low 4 bits of the header's first byte)."""

    HELLO = 1
    WELCOME = 2
    SETUP = 3
    COMMAND = 4
    REPORT = 5
    BYE = 6


class Refused(Exception):
    """A frame dropped by a receiver; ``reason`` is a :class:`LinkStats` counter."""

    def __init__(self, reason: str, detail: str = ""):
        super().__init__(f"{reason}: {detail}" if detail else reason)
        self.reason = reason


@dataclass(frozen=True)
class Header:
    """A frame's header (module doc); ``clock`` is in ms modulo 65536."""

    type: FrameType
    sender: int
    counter: int
    clock: int

    def pack(self) -> bytes:
        return HEADER.pack(VERSION << 4 | int(self.type), self.sender, self.counter,
                           self.clock & 0xFFFF)


def clock_ms(seconds: float) -> int:
    """A clock reading [s] as the header's u16 milliseconds."""
    return round(seconds * 1000) & 0xFFFF


def read_header(datagram: bytes) -> Header:
    """The header of ``datagram`` (nothing is authenticated yet).

    Raises:
        Refused: ``malformed`` (too short, unknown type) or ``version``.
    """
    if len(datagram) < HEADER.size + TAG_SIZE or len(datagram) > MAX_FRAME:
        raise Refused("malformed", f"{len(datagram)} bytes")
    first, sender, counter, clock = HEADER.unpack_from(datagram)
    if first >> 4 != VERSION:
        raise Refused("version", f"version {first >> 4}, this end speaks {VERSION}")
    try:
        kind = FrameType(first & 0x0F)
    except ValueError:
        raise Refused("malformed", f"frame type {first & 0x0F}") from None
    return Header(kind, sender, counter, clock)


def _nonce(counter: int) -> bytes:
    return counter.to_bytes(NONCE_SIZE, "little")


def _check_size(data: bytes) -> bytes:
    if len(data) > MAX_FRAME:
        raise ExecutionError(f"link frame of {len(data)} bytes is larger than {MAX_FRAME}")
    return data


def seal(aead: Aead, header: Header, payload: bytes) -> bytes:
    """A session frame: header, then ``payload`` sealed under the counter's nonce."""
    head = header.pack()
    return _check_size(head + aead.seal(_nonce(header.counter), payload, head))


def open_sealed(aead: Aead, datagram: bytes) -> bytes | None:
    """The payload of a session frame, ``None`` if it was not sealed with ``aead``."""
    head = datagram[:HEADER.size]
    return aead.open(_nonce(HEADER.unpack_from(head)[2]), datagram[HEADER.size:], head)


def seal_handshake(aead: Aead, header: Header, payload: bytes) -> bytes:
    """A handshake frame: header, a random nonce, then ``payload`` sealed under it (the
    module key serves many sessions, so its nonces cannot be counters)."""
    head = header.pack() + secrets.token_bytes(NONCE_SIZE)
    return _check_size(head + aead.seal(head[HEADER.size:], payload, head))


def open_handshake(aead: Aead, datagram: bytes) -> bytes | None:
    cut = HEADER.size + NONCE_SIZE
    if len(datagram) < cut + TAG_SIZE:
        return None
    return aead.open(datagram[HEADER.size:cut], datagram[cut:], datagram[:cut])


def seal_signed(aead: Aead, signer: Signer, header: Header, payload: bytes) -> bytes:
    """The COMMAND frame: sealed with the group key, then signed by the host."""
    body = seal(aead, header, payload)
    return _check_size(body + signer.sign(body))


def open_signed(aead: Aead, verifier: Verifier, datagram: bytes) -> bytes | None:
    """The payload of a COMMAND frame, ``None`` unless both signature and tag hold."""
    if len(datagram) < HEADER.size + TAG_SIZE + SIGNATURE_SIZE:
        return None
    body, signature = datagram[:-SIGNATURE_SIZE], datagram[-SIGNATURE_SIZE:]
    if not verifier.verify(signature, body):
        return None
    return open_sealed(aead, body)


# -- receive state ------------------------------------------------------------------------


class Freshness:
    """How late one sender's frames arrive, and the window of an accepted frame's age.

    Clocks are not synchronised: each frame's delay is the receiver's clock at arrival
    minus the sender's clock in the header (network delay plus an unknown offset); the
    smallest delay of the last :attr:`SAMPLES` frames stands for the offset, and a
    frame's *lateness* is its delay beyond that. The window is ``floor`` plus the
    smoothed lateness and four times its mean deviation (as TCP's retransmission timer,
    RFC 6298), at most ``ceiling``: a link that slows down under load widens it, a frame
    held back well beyond its peers is refused (``stale``). Authentic frames refused as
    stale still count as measurements (so the window can follow a sudden slow-down);
    only accepted ones move the offset estimate.

    Args:
        floor, ceiling: bounds of the window [s of the receiver's clock].
    """

    SAMPLES = 256

    def __init__(self, floor: float, ceiling: float):
        self.floor = floor
        self.ceiling = max(floor, ceiling)
        self._ref: int | None = None
        self._delays: deque[float] = deque(maxlen=self.SAMPLES)
        self._mean = 0.0
        self._deviation = 0.0
        self.largest = 0.0
        """Largest lateness [s] of an accepted frame."""

    @property
    def window(self) -> float:
        """The largest lateness [s] accepted now."""
        return min(self.ceiling, self.floor + self._mean + 4.0 * self._deviation)

    def _delay(self, clock: int, arrival: float) -> float:
        raw = (round(arrival * 1000) - clock) & 0xFFFF
        ref = raw if self._ref is None else self._ref
        return (((raw - ref + 0x8000) & 0xFFFF) - 0x8000) / 1000.0

    def lateness(self, clock: int, arrival: float) -> float:
        """A frame's delay beyond the smallest recent one [s] (0 for the first)."""
        if not self._delays:
            return 0.0
        return max(0.0, self._delay(clock, arrival) - min(self._delays))

    def check(self, clock: int, arrival: float) -> None:
        """Raises :class:`Refused` (``stale``) for a frame later than the window."""
        late = self.lateness(clock, arrival)
        if late > self.window + 1e-9:
            self._learn(late)
            raise Refused("stale", f"{late:.3f} s late, window {self.window:.3f} s")

    def _learn(self, late: float) -> None:
        error = late - self._mean
        self._mean += error / 8.0
        self._deviation += (abs(error) - self._deviation) / 4.0

    def commit(self, clock: int, arrival: float) -> None:
        """Record an accepted frame."""
        if self._ref is None:
            self._ref = (round(arrival * 1000) - clock) & 0xFFFF
        late = self.lateness(clock, arrival)
        self._learn(late)
        self.largest = max(self.largest, late)
        self._delays.append(self._delay(clock, arrival))


@dataclass
class LinkStats:
    """Counters of one end: frames and bytes each way, and every refusal by reason."""

    sent: int = 0
    received: int = 0
    bytes_sent: int = 0
    bytes_received: int = 0
    refused: dict[str, int] = field(default_factory=dict)

    def refuse(self, reason: str) -> None:
        self.refused[reason] = self.refused.get(reason, 0) + 1

    def total_refused(self) -> int:
        return sum(self.refused.values())


# -- payloads -------------------------------------------------------------------------------

PLAIN = Codec()
"""The codec of payloads without records (everything but a report's robot data)."""


def decode_map(data: bytes, codec: Codec = PLAIN) -> dict[int, Any]:
    """A payload that must be a map with unsigned integer keys.

    Raises:
        Refused: ``malformed``.
    """
    try:
        value = codec.decode(data)
    except CodecError as exc:
        raise Refused("malformed", str(exc)) from None
    if not isinstance(value, dict) or not all(isinstance(k, int) and k >= 0 for k in value):
        raise Refused("malformed", "payload is not a map of unsigned integer keys")
    return value


def want(payload: Mapping[int, Any], key: int, kind: type | tuple[type, ...], what: str,
         default: Any = None, *, size: int | None = None) -> Any:
    """``payload[key]`` checked to be of ``kind`` (and ``size`` bytes), or ``default``
    when absent (``None`` default: required).

    Raises:
        Refused: ``malformed``, naming ``what``.
    """
    if key not in payload:
        if default is None:
            raise Refused("malformed", f"no {what}")
        return default
    value = payload[key]
    if isinstance(value, bool) and bool not in (kind if isinstance(kind, tuple) else (kind,)):
        raise Refused("malformed", what)
    if not isinstance(value, kind) or (size is not None and len(value) != size):
        raise Refused("malformed", what)
    if isinstance(value, float) and not math.isfinite(value):
        raise Refused("malformed", what)
    return value


def unsigned(payload: Mapping[int, Any], key: int, what: str, default: int | None = None,
             limit: int = MAX_COUNTER) -> int:
    value = want(payload, key, int, what, default)
    if not 0 <= value <= limit:
        raise Refused("malformed", what)
    return value


class NameTable:
    """The host's table of names (joint, wheel and port names) sent as small integers.

    A name's id is its place in the table. A COMMAND frame carries the table's entries
    from the smallest size its modules reported knowing (``[first, names...]``), so a
    module always learns a name in the frame that first uses its id.
    """

    def __init__(self) -> None:
        self.names: list[str] = []
        self._ids: dict[str, int] = {}

    def __len__(self) -> int:
        return len(self.names)

    def ref(self, name: str) -> int:
        """``name``'s id (a new name joins the table)."""
        number = self._ids.get(name)
        if number is None:
            number = self._ids[name] = len(self.names)
            self.names.append(name)
        return number


def _name(value: Any, names: list[str], what: str) -> str:
    if isinstance(value, str):
        return value
    if isinstance(value, int) and not isinstance(value, bool) and 0 <= value < len(names):
        return names[value]
    raise Refused("malformed", f"{what}: name {value!r}")


AXES = ("_x", "_y", "_z")
"""The joints ``N_x``, ``N_y``, ``N_z`` of a vector ``N`` (a systems file's ``vectors``)."""
UNIT_TOLERANCE = 1e-6
"""How far from 1 the norm of a declared vector may be for it to travel packed."""


def _unit(joints: Mapping[str, float], stem: str) -> np.ndarray | None:
    """The unit vector of joints ``stem_x/_y/_z``, or ``None`` (absent, or not unit)."""
    names = [stem + axis for axis in AXES]
    if not all(n in joints for n in names):
        return None
    v = np.array([joints[n] for n in names], dtype=float)
    norm = float(np.linalg.norm(v))
    return v if math.isfinite(norm) and abs(norm - 1.0) < UNIT_TOLERANCE else None


def _number(value: float) -> float | int:
    """A joint value on the wire: float32, an integer when integral (1 byte for 0 or 1,
    not 3)."""
    x = float(np.float32(value))
    return int(x) if x.is_integer() and abs(x) < 2**31 else x


def command_entry(command: ModuleCommand, version: int, names: NameTable,
                  vectors: tuple[str, ...] = ()) -> list[Any]:
    """A module's full entry in the COMMAND frame: ``[version, joints, wheels, dock,
    undock]`` without trailing empties; values float32 (integers when integral), except
    that each declared vector
    ``N`` in ``vectors`` whose joints ``N_x``, ``N_y``, ``N_z`` form a unit vector
    travels as one joint ``N`` whose value is its 4-byte direction
    (:func:`~.codec.direction_bytes`: within 6.3e-5 rad)."""
    joints: dict[Any, Any] = {}
    rest = dict(command.joints)
    for stem in vectors:
        unit = _unit(rest, stem)
        if unit is not None:
            for axis in AXES:
                del rest[stem + axis]
            joints[names.ref(stem)] = direction_bytes(unit)
    for key, value in rest.items():
        joints[names.ref(str(key))] = _number(value)
    out: list[Any] = [version % VERSION_MARKS, joints,
                      {names.ref(str(k)): _number(v) for k, v in command.wheels.items()},
                      [names.ref(p) for p in command.dock],
                      [names.ref(p) for p in command.undock]]
    while len(out) > 1 and not out[-1]:
        out.pop()
    return out


def parse_entry(entry: Any, names: list[str]) -> tuple[int, ModuleCommand | None]:
    """``(version, command)`` of a module's entry; ``None``: the entry is only the
    version (the command is unchanged). A joint whose value is a 4-byte string is a
    unit vector: the joints ``N_x``, ``N_y``, ``N_z`` of its name ``N``.

    Raises:
        Refused: ``malformed``.
    """
    if isinstance(entry, int) and not isinstance(entry, bool):
        if not 0 <= entry < VERSION_MARKS:
            raise Refused("malformed", "command version")
        return entry, None
    if not (isinstance(entry, tuple) and 1 <= len(entry) <= 5 and isinstance(entry[0], int)
            and not isinstance(entry[0], bool) and 0 <= entry[0] < VERSION_MARKS):
        raise Refused("malformed", "command entry")
    parts = list(entry[1:]) + [None] * (5 - len(entry))

    def numbers(value: Any, what: str, vectors: bool = False) -> dict[str, float]:
        if value is None:
            return {}
        if not isinstance(value, dict):
            raise Refused("malformed", what)
        out: dict[str, float] = {}
        for key, number in value.items():
            name = _name(key, names, what)
            if vectors and isinstance(number, bytes) and len(number) == DIRECTION_BYTES:
                unit = direction_from_bytes(number)
                for axis, component in zip(AXES, unit, strict=True):
                    if name + axis in out:
                        raise Refused("malformed", f"{what}: {name + axis} given twice")
                    out[name + axis] = float(component)
                continue
            if (isinstance(number, bool) or not isinstance(number, int | float)
                    or not math.isfinite(number)):
                raise Refused("malformed", f"{what} value")
            if name in out:
                raise Refused("malformed", f"{what}: {name} given twice")
            out[name] = float(number)
        return out

    def ports(value: Any, what: str) -> tuple[str, ...]:
        if value is None:
            return ()
        if not isinstance(value, tuple):
            raise Refused("malformed", what)
        return tuple(_name(p, names, what) for p in value)

    return entry[0], ModuleCommand(joints=numbers(parts[0], "joints", vectors=True),
                                   wheels=numbers(parts[1], "wheels"),
                                   dock=ports(parts[2], "dock"), undock=ports(parts[3], "undock"))


POSITION_QUANTUM = 1e-4
"""A reported position's resolution [m]."""


def pose_wire(pose: Pose) -> list[Any]:
    """A pose as ``[x, y, z, rotation]``: position in units of 0.1 mm, orientation as a
    rotation field's 6 bytes (:func:`~.codec.rotation_bytes`)."""
    q = np.asarray(pose.orientation, dtype=float)
    norm = float(np.linalg.norm(q))
    q = q / norm if math.isfinite(norm) and norm > 0 else np.array([0.0, 0.0, 0.0, 1.0])
    return [round(float(x) / POSITION_QUANTUM) for x in pose.position] + [
        rotation_bytes(Rotation.from_quat(q).as_matrix())]


def pose_from_wire(value: Any) -> Pose:
    if not (isinstance(value, tuple) and len(value) == 4
            and all(isinstance(x, int) and not isinstance(x, bool) for x in value[:3])
            and isinstance(value[3], bytes) and len(value[3]) in ROTATION_SIZES):
        raise Refused("malformed", "pose")
    q = Rotation.from_matrix(rotation_from_bytes(value[3])).as_quat()
    return Pose(np.array(value[:3], dtype=float) * POSITION_QUANTUM, q)
