"""The link's payloads: CBOR (RFC 8949) through ``cbor2``, deterministic and compact.

The frames' fixed header is :mod:`.protocol`'s; every payload is one CBOR item that
``cbor2`` writes in the deterministic form of RFC 8949 section 4.2 (``canonical=True``:
shortest heads, definite lengths, map keys sorted bytewise, floats in their shortest
exact form -- half precision when exact) and reads back with duplicate keys,
indefinite lengths and every tag but the three below refused; a payload that does not
re-encode to the same bytes is refused too (one value, one encoding).

What robot data becomes on the wire (:meth:`Codec.to_wire`):

* floats: rounded to float32 (then the shortest exact form);
* numpy float arrays: RFC 8746 typed arrays, tag 85 (float32 little-endian); an
  array of two or more dimensions is tag 40 ``[shape, tag 85 ...]``; integer and
  boolean arrays are plain arrays;
* records (dataclass instances): tag 27 ``[id, field values...]``, the id being the
  type's place in the system's record table (1, 2, ... in the systems file), not a
  Python path;
* fields the record table marks as **rotations** carry each 3x3 rotation matrix as its
  rotation vector in three little-endian int16 (a 6-byte string, 4 bytes for a rotation
  about a horizontal axis, :func:`rotation_bytes`); fields marked **directions** carry each unit 3-vector in its
  octahedral encoding, two int16 (a 4-byte string, :func:`direction_bytes`). Both
  within 1e-4 rad (0.006 degrees) of the value, far finer than any module's
  orientation filter; a value that is not a rotation (or unit vector) after all
  travels as a typed array instead.

Decoding (:meth:`Codec.from_wire`) turns arrays into tuples, typed arrays into float64
numpy arrays, rotation and direction strings back into matrices and unit vectors (every
string of their sizes is one), and builds records only of the types in
the table (an allow-list: a frame never makes the host import or construct anything
else). Anything else -- another tag, a simple value, a record of an unknown id or with
the wrong fields, a map key that is not an integer or text -- is a :class:`CodecError`,
never another exception.
"""

from __future__ import annotations

import dataclasses
import importlib
import math
import typing
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import cbor2
import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import ConfigurationError, MsrrError

__all__ = ["DIRECTION_BYTES", "INCOMPLETE", "ROTATION_BYTES", "ROTATION_SIZES", "TAG_F32LE", "TAG_NDARRAY",
           "TAG_RECORD", "Codec", "CodecError", "RecordSpec", "RecordTable", "direction_bytes",
           "direction_from_bytes", "infer_records", "record_name", "rotation_bytes",
           "rotation_from_bytes"]

TAG_RECORD = 27
TAG_NDARRAY = 40
TAG_F32LE = 85
MAX_DEPTH = 16
QUANTUM = 32767
ROTATION_BYTES = 6
ROTATION_SIZES = (4, ROTATION_BYTES)
"""A rotation's sizes: 4 bytes about a horizontal axis, else 6."""
DIRECTION_BYTES = 4
_ROTATION_TOLERANCE = 1e-5
INCOMPLETE = object()
"""What :meth:`Codec.update` returns for a partial record it cannot complete."""
_BUILTIN_TAGS = (0, 1, 2, 3, 4, 5, 25, 28, 29, 30, 35, 36, 37, 52, 54, 100, 256, 258, 260, 261,
                 262, 263, 264, 265, 266, 267, 268, 269, 270, 271, 1004, 1040, 55799)
"""Tags ``cbor2`` would interpret itself (dates, bignums, regular expressions, MIME,
shared values...): all refused, so a payload never reaches that code."""


class CodecError(MsrrError):
    """A payload that is not a well-formed link payload (or a value that cannot be one)."""


def record_name(cls: type) -> str:
    """``"module:QualName"`` of a dataclass, as the systems file's record table names it."""
    return f"{cls.__module__}:{cls.__qualname__}"


@dataclass(frozen=True)
class RecordSpec:
    """One row of a record table: a dataclass by name and its quantised fields."""

    type: str
    rotations: tuple[str, ...] = ()
    directions: tuple[str, ...] = ()


@dataclass(frozen=True)
class _Record:
    id: int
    cls: type
    fields: tuple[str, ...]
    required: int
    kinds: Mapping[str, str]


class RecordTable:
    """The record types a system's reports may carry, with their ids (1, 2, ...).

    Args:
        specs: the table, in id order.
        packages: top-level packages the types may come from (the robot's plugin);
            empty: any (the emulator, which holds the classes already).

    Raises:
        ConfigurationError: a type that cannot be imported, is not a dataclass, is
            outside ``packages``, or names a field it does not have.
    """

    def __init__(self, specs: Sequence[RecordSpec] = (), packages: tuple[str, ...] = ()):
        self.specs = tuple(specs)
        self._by_id: dict[int, _Record] = {}
        self._by_cls: dict[type, _Record] = {}
        for number, spec in enumerate(self.specs, start=1):
            cls = _import(spec.type, packages)
            fields = dataclasses.fields(cls)
            names = tuple(f.name for f in fields)
            kinds = {**dict.fromkeys(spec.rotations, "rotation"),
                     **dict.fromkeys(spec.directions, "direction")}
            unknown = sorted(set(kinds) - set(names))
            if unknown:
                raise ConfigurationError(f"record {spec.type} has no field(s) {unknown}",
                                         field="records")
            required = sum(1 for f in fields if f.default is dataclasses.MISSING
                           and f.default_factory is dataclasses.MISSING)
            record = _Record(number, cls, names, required, kinds)
            self._by_id[number] = record
            self._by_cls[cls] = record

    def __len__(self) -> int:
        return len(self.specs)

    def of(self, cls: type) -> _Record | None:
        return self._by_cls.get(cls)

    def get(self, number: int) -> _Record | None:
        return self._by_id.get(number)


def _import(name: str, packages: tuple[str, ...]) -> type:
    module, _, qualname = name.partition(":")
    if not qualname or (packages and module.split(".")[0] not in packages):
        raise ConfigurationError(f"record type {name!r} is not allowed (types of "
                                 f"{', '.join(packages) or 'any package'} as 'module:Name')",
                                 field="records")
    try:
        found: Any = importlib.import_module(module)
        for part in qualname.split("."):
            found = getattr(found, part)
    except (ImportError, AttributeError):
        raise ConfigurationError(f"record type {name!r} not found", field="records") from None
    if not (isinstance(found, type) and dataclasses.is_dataclass(found)):
        raise ConfigurationError(f"record type {name!r} is not a dataclass", field="records")
    return found


# -- quantised rotations and directions ------------------------------------------------


def _is_rotation(value: Any) -> bool:
    if not (isinstance(value, np.ndarray) and value.shape == (3, 3)
            and np.issubdtype(value.dtype, np.floating) and np.all(np.isfinite(value))):
        return False
    return bool(np.abs(value @ value.T - np.eye(3)).max() < _ROTATION_TOLERANCE
                and np.linalg.det(value) > 0)


def _is_direction(value: Any) -> bool:
    return bool(isinstance(value, np.ndarray) and value.shape == (3,)
                and np.issubdtype(value.dtype, np.floating) and np.all(np.isfinite(value))
                and abs(float(np.linalg.norm(value)) - 1.0) < _ROTATION_TOLERANCE)


def rotation_bytes(matrix: np.ndarray) -> bytes:
    """A rotation (3x3 matrix) in 6 bytes: its rotation vector (axis times angle, the
    angle in [0, pi]) as three little-endian int16 of ``component / pi * 32767``; a
    rotation about a horizontal axis (the third int16 0: a tilt, a yaw-free attitude) in
    4 bytes, the first two. Resolution pi / 32767 = 9.6e-5 rad per component: at most
    8e-5 rad (0.005 degrees) between a rotation and its decoding, uniformly (no axis or
    angle is worse)."""
    vector = Rotation.from_matrix(matrix).as_rotvec()
    ints = np.round(vector / math.pi * QUANTUM).astype("<i2")
    return (ints[:2] if ints[2] == 0 else ints).tobytes()


def rotation_from_bytes(data: bytes) -> np.ndarray:
    """The rotation matrix of :func:`rotation_bytes`' 6 (or 4) bytes (every 6 or 4 bytes
    are one)."""
    if len(data) not in ROTATION_SIZES:
        raise CodecError(f"a rotation of {len(data)} bytes, not {ROTATION_BYTES} (or "
                         f"{ROTATION_SIZES[0]})")
    vector = np.zeros(3)
    vector[:len(data) // 2] = np.frombuffer(data, dtype="<i2").astype(float) * (math.pi / QUANTUM)
    return Rotation.from_rotvec(vector).as_matrix()


def _sign(x: float) -> float:
    return -1.0 if x < 0 else 1.0


def direction_bytes(vector: np.ndarray) -> bytes:
    """A unit 3-vector in 4 bytes: its octahedral encoding (the vector divided by its
    1-norm; the lower half, z < 0, folded over the diagonals: ``x' = (1 - |y|) sign(x)``,
    ``y' = (1 - |x|) sign(y)``, sign(0) = +1), x and y as two little-endian int16 of
    ``value * 32767``. At most 6.3e-5 rad (0.004 degrees) between a direction and its
    decoding."""
    v = np.asarray(vector, dtype=float)
    p = v / float(np.abs(v).sum())
    x, y = float(p[0]), float(p[1])
    if p[2] < 0:
        x, y = (1.0 - abs(float(p[1]))) * _sign(x), (1.0 - abs(float(p[0]))) * _sign(y)
    return np.round(np.array([x, y]) * QUANTUM).astype("<i2").tobytes()


def direction_from_bytes(data: bytes) -> np.ndarray:
    """The unit vector of :func:`direction_bytes`' 4 bytes (every 4 bytes are one)."""
    if len(data) != DIRECTION_BYTES:
        raise CodecError(f"a direction of {len(data)} bytes, not {DIRECTION_BYTES}")
    x, y = (float(c) / QUANTUM for c in np.frombuffer(data, dtype="<i2"))
    z = 1.0 - abs(x) - abs(y)
    if z < 0:
        x, y = (1.0 - abs(y)) * _sign(x), (1.0 - abs(x)) * _sign(y)
    v = np.array([x, y, z])
    return v / float(np.linalg.norm(v))


def _quantised(value: Any, kind: str) -> Any:
    """``value`` (a leaf, or a map or sequence of leaves) with rotations / directions
    quantised; anything else unchanged (it travels in its generic form)."""
    if kind == "rotation" and _is_rotation(value):
        return rotation_bytes(value)
    if kind == "direction" and _is_direction(value):
        return direction_bytes(value)
    if isinstance(value, Mapping):
        return {k: _quantised(v, kind) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_quantised(v, kind) for v in value]
    return value


def _dequantised(value: Any, kind: str) -> Any:
    if isinstance(value, bytes):  # of another size: refused
        return rotation_from_bytes(value) if kind == "rotation" else direction_from_bytes(value)
    if isinstance(value, dict):
        return {k: _dequantised(v, kind) for k, v in value.items()}
    if isinstance(value, tuple):
        return tuple(_dequantised(v, kind) for v in value)
    return value


# -- the codec --------------------------------------------------------------------------


def _refuse_tag(value: Any, immutable: bool) -> Any:
    raise CodecError("a CBOR tag the link does not use")


_SEMANTIC = dict.fromkeys(_BUILTIN_TAGS, _refuse_tag)


def _keep_tag(tag: cbor2.CBORTag, immutable: bool) -> cbor2.CBORTag:
    return tag


class Codec:
    """Encodes and decodes link payloads with one record table (module doc)."""

    def __init__(self, records: RecordTable | None = None):
        self.records = records if records is not None else RecordTable()

    # -- encoding ----------------------------------------------------------------------

    def to_wire(self, value: Any, depth: int = 0) -> Any:
        """``value`` as the ``cbor2``-native tree of its wire form.

        Raises:
            CodecError: a type the link cannot carry, a record type not in the table,
                or nesting deeper than 16 levels.
        """
        if depth > MAX_DEPTH:
            raise CodecError(f"value nested deeper than {MAX_DEPTH} levels")
        if value is None or isinstance(value, bool | str | bytes):
            return value
        if isinstance(value, np.bool_):
            return bool(value)
        if isinstance(value, int | np.integer):
            return int(value)
        if isinstance(value, float | np.floating):
            x = float(value)
            return float(np.float32(x)) if math.isfinite(x) and abs(x) < 3.4e38 else x
        if isinstance(value, np.ndarray):
            return self._array(value, depth)
        if isinstance(value, Mapping):
            out = {}
            for key, item in value.items():
                wire_key = self.to_wire(key, depth + 1)
                if not isinstance(wire_key, int | str):
                    raise CodecError(f"map key of type {type(key).__name__}")
                out[wire_key] = self.to_wire(item, depth + 1)
            return out
        if isinstance(value, list | tuple):
            return [self.to_wire(item, depth + 1) for item in value]
        if isinstance(value, set | frozenset):
            return [self.to_wire(item, depth + 1) for item in sorted(value)]
        if dataclasses.is_dataclass(value) and not isinstance(value, type):
            record = self.records.of(type(value))
            if record is None:
                raise CodecError(f"record type {record_name(type(value))} is not in the "
                                 "systems file's record table")
            fields = [getattr(value, name) for name in record.fields]
            for index, name in enumerate(record.fields):
                kind = record.kinds.get(name)
                if kind is not None:
                    fields[index] = _quantised(fields[index], kind)
            return cbor2.CBORTag(TAG_RECORD, [record.id, *(self.to_wire(f, depth + 1)
                                                            for f in fields)])
        raise CodecError(f"cannot encode a {type(value).__name__}")

    def _array(self, value: np.ndarray, depth: int) -> Any:
        if np.issubdtype(value.dtype, np.floating):
            typed = cbor2.CBORTag(TAG_F32LE, np.ascontiguousarray(value, dtype="<f4").tobytes())
            if value.ndim == 1:
                return typed
            return cbor2.CBORTag(TAG_NDARRAY, [list(value.shape), typed])
        if np.issubdtype(value.dtype, np.integer) or value.dtype == np.bool_:
            return self.to_wire(value.tolist(), depth)
        raise CodecError(f"cannot encode an array of {value.dtype}")

    @staticmethod
    def dumps(tree: Any) -> bytes:
        """The deterministic CBOR bytes of a wire tree (:meth:`to_wire`)."""
        try:
            return cbor2.dumps(tree, canonical=True)
        except (cbor2.CBOREncodeError, ValueError, TypeError, OverflowError) as exc:
            raise CodecError(f"cannot encode: {exc}") from None

    def encode(self, value: Any) -> bytes:
        """``value``'s payload bytes."""
        return self.dumps(self.to_wire(value))

    # -- decoding ----------------------------------------------------------------------

    def loads(self, data: bytes) -> Any:
        """The raw tree of ``data`` (tags kept as :class:`cbor2.CBORTag`).

        Raises:
            CodecError: not one deterministic CBOR item of the link's subset.
        """
        try:
            raw = cbor2.loads(data, tag_hook=_keep_tag, semantic_decoders=_SEMANTIC,
                              max_depth=MAX_DEPTH + 2, allow_indefinite=False,
                              allow_duplicate_keys=False)
        except CodecError:
            raise
        except (cbor2.CBORError, ValueError, TypeError, OverflowError, RecursionError,
                MemoryError) as exc:
            raise CodecError(f"not CBOR: {exc}") from None
        try:
            canonical = cbor2.dumps(raw, canonical=True)
        except Exception as exc:  # noqa: BLE001 - whatever it is, the payload is refused
            raise CodecError(f"cannot re-encode: {exc}") from None
        if canonical != bytes(data):
            raise CodecError("not in deterministic form (RFC 8949 section 4.2)")
        return raw

    def from_wire(self, raw: Any, depth: int = 0) -> Any:
        """The value of a raw tree (module doc).

        Raises:
            CodecError: anything outside the link's subset.
        """
        if depth > MAX_DEPTH:
            raise CodecError(f"nested deeper than {MAX_DEPTH} levels")
        if raw is None or isinstance(raw, bool | int | float | str | bytes):
            return raw
        if isinstance(raw, list | tuple):
            return tuple(self.from_wire(item, depth + 1) for item in raw)
        if isinstance(raw, Mapping):
            out: dict[Any, Any] = {}
            for key, item in raw.items():
                if isinstance(key, bool) or not isinstance(key, int | str):
                    raise CodecError("a map key that is neither an integer nor text")
                out[key] = self.from_wire(item, depth + 1)
            return out
        if isinstance(raw, cbor2.CBORTag):
            return self._tagged(raw.tag, raw.value, depth)
        raise CodecError(f"unsupported item {type(raw).__name__}")

    def _tagged(self, tag: int, content: Any, depth: int) -> Any:
        if tag == TAG_F32LE:
            if not isinstance(content, bytes) or len(content) % 4:
                raise CodecError("a float32 typed array of a bad length")
            return np.frombuffer(content, dtype="<f4").astype(np.float64)
        if tag == TAG_NDARRAY:
            if not (isinstance(content, list | tuple) and len(content) == 2
                    and isinstance(content[0], list | tuple) and 2 <= len(content[0]) <= 4
                    and all(isinstance(n, int) and not isinstance(n, bool) and 0 <= n <= 4096
                            for n in content[0])
                    and isinstance(content[1], cbor2.CBORTag) and content[1].tag == TAG_F32LE):
                raise CodecError("tag 40 is not [shape, float32 typed array]")
            flat = self._tagged(TAG_F32LE, content[1].value, depth + 1)
            if math.prod(content[0]) != flat.size:
                raise CodecError("tag 40's shape does not match its data")
            return flat.reshape(tuple(content[0]))
        if tag == TAG_RECORD:
            return self._record(content, depth)
        raise CodecError(f"unsupported tag {tag}")

    def _record(self, content: Any, depth: int) -> Any:
        if not (isinstance(content, list | tuple) and content and isinstance(content[0], int)
                and not isinstance(content[0], bool)):
            raise CodecError("a record is not [id, field values...]")
        record = self.records.get(content[0])
        if record is None:
            raise CodecError(f"record id {content[0]} is not in the record table")
        raw = list(content[1:])
        if not record.required <= len(raw) <= len(record.fields):
            raise CodecError(f"record {record.cls.__name__} with {len(raw)} fields")
        return _build(record, [self._field(record, name, item, depth)
                               for name, item in zip(record.fields, raw, strict=False)])

    def _field(self, record: _Record, name: str, raw: Any, depth: int) -> Any:
        value = self.from_wire(raw, depth + 1)
        kind = record.kinds.get(name)
        return _dequantised(value, kind) if kind is not None else value

    def decode(self, data: bytes) -> Any:
        """The value of payload bytes (:meth:`loads` then :meth:`from_wire`)."""
        return self.from_wire(self.loads(data))

    def update(self, raw: Any, previous: Any) -> Any:
        """The value of ``raw``, which may be a record whose unchanged fields are
        ``undefined`` (a report's sensor data sent field by field): those come from
        ``previous``, the module's last value. :data:`INCOMPLETE` when a field is missing
        and ``previous`` is no record of that type (the full value was lost).

        Raises:
            CodecError: as :meth:`from_wire`.
        """
        if not (isinstance(raw, cbor2.CBORTag) and raw.tag == TAG_RECORD
                and isinstance(raw.value, list | tuple) and len(raw.value) > 1
                and any(v is cbor2.undefined for v in raw.value[1:])):
            return self.from_wire(raw)
        number = raw.value[0]
        record = self.records.get(number) if isinstance(number, int) else None
        if record is None or len(raw.value) - 1 != len(record.fields):
            raise CodecError("a partial record of an unknown id or with missing fields")
        if not isinstance(previous, record.cls):
            return INCOMPLETE
        return _build(record, [
            getattr(previous, name) if item is cbor2.undefined
            else self._field(record, name, item, 0)
            for name, item in zip(record.fields, raw.value[1:], strict=True)])


def _build(record: _Record, values: list[Any]) -> Any:
    try:
        return record.cls(*values)
    except Exception as exc:  # noqa: BLE001 - a record's own checks refuse it
        raise CodecError(f"record {record.cls.__name__}: {exc}") from None


# -- the table a simulator's reports need -------------------------------------------------


def infer_records(values: Iterable[Any]) -> list[RecordSpec]:
    """The record table that carries ``values`` (a simulator's sensor data): every
    dataclass type in them or named in their field annotations, sorted by name; a field
    whose values are all rotation matrices (unit 3-vectors) is marked a rotation
    (direction) field."""
    seen: dict[type, dict[str, set[str]]] = {}

    def leaves(value: Any) -> list[Any]:
        if isinstance(value, Mapping):
            return [x for v in value.values() for x in leaves(v)]
        if isinstance(value, list | tuple):
            return [x for v in value for x in leaves(v)]
        return [value]

    def visit_type(cls: type) -> None:
        if cls in seen:
            return
        seen[cls] = {}
        try:
            hints = typing.get_type_hints(cls)
        except Exception:  # noqa: BLE001 - unresolvable annotations name no records
            hints = {}
        stack = list(hints.values())
        while stack:
            hint = stack.pop()
            if isinstance(hint, type) and dataclasses.is_dataclass(hint):
                visit_type(hint)
            stack.extend(typing.get_args(hint))

    def visit(value: Any, depth: int = 0) -> None:
        if depth > MAX_DEPTH:
            return
        if dataclasses.is_dataclass(value) and not isinstance(value, type):
            cls = type(value)
            visit_type(cls)
            for f in dataclasses.fields(value):
                items = [x for x in leaves(getattr(value, f.name)) if isinstance(x, np.ndarray)]
                kinds = seen[cls].setdefault(f.name, set())
                for item in items:
                    kinds.add("rotation" if _is_rotation(item) else
                              "direction" if _is_direction(item) else "array")
                visit(getattr(value, f.name), depth + 1)
        elif isinstance(value, Mapping):
            for item in value.values():
                visit(item, depth + 1)
        elif isinstance(value, list | tuple):
            for item in value:
                visit(item, depth + 1)

    for value in values:
        visit(value)
    return [RecordSpec(record_name(cls),
                       tuple(sorted(f for f, k in fields.items() if k == {"rotation"})),
                       tuple(sorted(f for f, k in fields.items() if k == {"direction"})))
            for cls, fields in sorted(seen.items(), key=lambda item: record_name(item[0]))]
