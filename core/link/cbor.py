"""A small, dependency-free CBOR codec (RFC 8949) for the link protocol's payloads.

Only what the protocol needs, in the deterministic form of RFC 8949 section 4.2.1
(shortest integer and length heads, definite lengths, map keys in encoding order):

* unsigned and negative integers (major types 0, 1; 64-bit range), byte and text
  strings (2, 3), arrays (4), maps (5), ``false``/``true``/``null`` (7);
* floats: float32 when it round-trips exactly, otherwise float64 (major type 7);
* numpy arrays of reals: tag 40 (RFC 8746 section 3.1, row-major multi-dimensional
  array) ``[shape, tag 85 (float32 little-endian typed array) bytes]``; a 1-D array
  is the typed array alone;
* records (dataclass instances): tag 27 (the registered "serialised
  language-independent object with type name and constructor arguments")
  ``["module:QualName", field values...]`` in the dataclass's field order.

Decoding turns arrays into tuples (hashable, immutable), typed arrays into float64
numpy arrays, and tag-27 records into instances of an allow-listed dataclass only
(:class:`Decoder` ``records``): a frame never imports or builds anything else.
A microcontroller can produce this with any CBOR library (TinyCBOR, QCBOR, NanoCBOR).
"""

from __future__ import annotations

import dataclasses
import importlib
import math
import struct
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from ..errors import MsrrError

__all__ = ["CborError", "Decoder", "dumps", "loads", "record_name"]

TAG_RECORD = 27
TAG_NDARRAY = 40
TAG_F32LE = 85
MAX_DEPTH = 32
MAX_ITEMS = 1 << 16


class CborError(MsrrError):
    """A payload that is not the CBOR subset of this module (or too deep or large)."""


def record_name(cls: type) -> str:
    """``"module:QualName"`` of a dataclass, as tag 27 carries it."""
    return f"{cls.__module__}:{cls.__qualname__}"


def _head(major: int, value: int) -> bytes:
    if value < 24:
        return bytes([major << 5 | value])
    for extra, fmt in ((24, "<B"), (25, ">H"), (26, ">I"), (27, ">Q")):
        if value < 1 << (8 * struct.calcsize(fmt)):
            return bytes([major << 5 | extra]) + struct.pack(fmt, value)
    raise CborError(f"integer {value} does not fit 64 bits")


def _encode(value: Any, out: bytearray, depth: int) -> None:
    if depth > MAX_DEPTH:
        raise CborError(f"value nested deeper than {MAX_DEPTH} levels")
    if value is None:
        out += b"\xf6"
    elif value is True or value is False or isinstance(value, np.bool_):
        out += b"\xf5" if bool(value) else b"\xf4"
    elif isinstance(value, int | np.integer):
        n = int(value)
        out += _head(0, n) if n >= 0 else _head(1, -1 - n)
    elif isinstance(value, float | np.floating):
        x = float(value)
        single = struct.pack(">f", x) if math.isfinite(x) and abs(x) < 3.4e38 else None
        if single is not None and struct.unpack(">f", single)[0] == x:
            out += b"\xfa" + single
        else:
            out += b"\xfb" + struct.pack(">d", x)
    elif isinstance(value, str):
        data = value.encode("utf-8")
        out += _head(3, len(data)) + data
    elif isinstance(value, bytes | bytearray):
        out += _head(2, len(value)) + bytes(value)
    elif isinstance(value, np.ndarray):
        data = np.ascontiguousarray(value, dtype="<f4").tobytes()
        typed = _head(6, TAG_F32LE) + _head(2, len(data)) + data
        if value.ndim == 1:
            out += typed
        else:
            out += _head(6, TAG_NDARRAY) + _head(4, 2)
            _encode(list(value.shape), out, depth + 1)
            out += typed
    elif isinstance(value, Mapping):
        out += _head(5, len(value))
        for key, item in value.items():
            _encode(key, out, depth + 1)
            _encode(item, out, depth + 1)
    elif isinstance(value, list | tuple | frozenset | set):
        items = sorted(value) if isinstance(value, frozenset | set) else value
        out += _head(4, len(items))
        for item in items:
            _encode(item, out, depth + 1)
    elif dataclasses.is_dataclass(value) and not isinstance(value, type):
        fields = dataclasses.fields(value)
        out += _head(6, TAG_RECORD) + _head(4, 1 + len(fields))
        _encode(record_name(type(value)), out, depth + 1)
        for f in fields:
            _encode(getattr(value, f.name), out, depth + 1)
    else:
        raise CborError(f"cannot encode a {type(value).__name__}")


def dumps(value: Any) -> bytes:
    """The deterministic CBOR encoding of ``value`` (see the module doc for the types)."""
    out = bytearray()
    _encode(value, out, 0)
    return bytes(out)


class Decoder:
    """Decodes the CBOR subset; builds records only of allow-listed dataclasses.

    Args:
        packages: top-level packages whose dataclasses a tag-27 record may name (the
            robot's plugin package); a record of any other type is refused.
    """

    def __init__(self, packages: tuple[str, ...] = ()):
        self.packages = packages
        self._classes: dict[str, Callable[..., Any]] = {}

    def _record(self, name: str, args: tuple[Any, ...]) -> Any:
        cls = self._classes.get(name)
        if cls is None:
            module, _, qualname = name.partition(":")
            if module.split(".")[0] not in self.packages or not qualname:
                raise CborError(f"record type {name!r} is not allowed")
            try:
                found: Any = importlib.import_module(module)
                for part in qualname.split("."):
                    found = getattr(found, part)
            except (ImportError, AttributeError):
                raise CborError(f"record type {name!r} not found") from None
            if not (isinstance(found, type) and dataclasses.is_dataclass(found)):
                raise CborError(f"record type {name!r} is not a dataclass")
            cls = self._classes[name] = found
        try:
            return cls(*args)
        except TypeError as exc:
            raise CborError(f"record {name!r}: {exc}") from None

    def loads(self, data: bytes) -> Any:
        """Decode one complete item; trailing bytes are an error."""
        value, end = self._item(memoryview(data), 0, 0)
        if end != len(data):
            raise CborError(f"{len(data) - end} trailing bytes")
        return value

    def _length(self, data: memoryview, pos: int) -> tuple[int, int, int]:
        if pos >= len(data):
            raise CborError("truncated item")
        first = data[pos]
        major, info = first >> 5, first & 31
        if info < 24:
            return major, info, pos + 1
        sizes = {24: 1, 25: 2, 26: 4, 27: 8}
        if info not in sizes:
            raise CborError(f"unsupported head byte 0x{first:02x}")
        size = sizes[info]
        if pos + 1 + size > len(data):
            raise CborError("truncated item")
        return major, int.from_bytes(data[pos + 1:pos + 1 + size], "big"), pos + 1 + size

    def _item(self, data: memoryview, pos: int, depth: int) -> tuple[Any, int]:
        if depth > MAX_DEPTH:
            raise CborError(f"nested deeper than {MAX_DEPTH} levels")
        first = data[pos] if pos < len(data) else None
        if first in (0xFA, 0xFB):
            size, fmt = (4, ">f") if first == 0xFA else (8, ">d")
            if pos + 1 + size > len(data):
                raise CborError("truncated float")
            return struct.unpack(fmt, data[pos + 1:pos + 1 + size])[0], pos + 1 + size
        major, arg, pos = self._length(data, pos)
        if major == 0:
            return arg, pos
        if major == 1:
            return -1 - arg, pos
        if major in (2, 3):
            if pos + arg > len(data):
                raise CborError("truncated string")
            raw = bytes(data[pos:pos + arg])
            if major == 2:
                return raw, pos + arg
            try:
                return raw.decode("utf-8"), pos + arg
            except UnicodeDecodeError:
                raise CborError("text string is not UTF-8") from None
        if major in (4, 5):
            if arg > MAX_ITEMS:
                raise CborError(f"{arg} items, more than {MAX_ITEMS}")
            if major == 4:
                items = []
                for _ in range(arg):
                    item, pos = self._item(data, pos, depth + 1)
                    items.append(item)
                return tuple(items), pos
            out: dict[Any, Any] = {}
            for _ in range(arg):
                key, pos = self._item(data, pos, depth + 1)
                value, pos = self._item(data, pos, depth + 1)
                try:
                    out[key] = value
                except TypeError:
                    raise CborError("unhashable map key") from None
            return out, pos
        if major == 6:
            content, pos = self._item(data, pos, depth + 1)
            return self._tagged(arg, content), pos
        if major == 7 and arg in (20, 21, 22):
            return (False, True, None)[arg - 20], pos
        raise CborError(f"unsupported simple value {arg}")

    def _tagged(self, tag: int, content: Any) -> Any:
        if tag == TAG_F32LE:
            if not isinstance(content, bytes) or len(content) % 4:
                raise CborError("typed float32 array of a bad length")
            return np.frombuffer(content, dtype="<f4").astype(np.float64)
        if tag == TAG_NDARRAY:
            ok = isinstance(content, tuple) and len(content) == 2
            shape, flat = content if ok else ((), None)
            if (not isinstance(flat, np.ndarray) or not all(isinstance(n, int) for n in shape)
                    or math.prod(shape) != flat.size):
                raise CborError("multi-dimensional array with a bad shape")
            return flat.reshape(shape)
        if tag == TAG_RECORD:
            if not (isinstance(content, tuple) and content and isinstance(content[0], str)):
                raise CborError("record is not [type name, arguments...]")
            return self._record(content[0], content[1:])
        raise CborError(f"unsupported tag {tag}")


def loads(data: bytes, packages: tuple[str, ...] = ()) -> Any:
    """Decode ``data`` (records only of dataclasses in ``packages``)."""
    return Decoder(packages).loads(data)
