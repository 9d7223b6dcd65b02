"""File helpers shared by every reader and writer: atomic writes, strict JSON reading,
strict number types and readable validation errors.

Every msrr file is read by :func:`read_json`, which refuses what :mod:`json` lets
through silently: a document that is not an object (``null``, ``1``, ``"text"``, a
list: every msrr file is an object), ``NaN``/``Infinity`` and numbers that overflow to them, repeated
keys (JSON would keep the last), lone surrogate escapes (``"\\ud800"``: not text),
nesting deeper than :data:`MAX_DEPTH` and integers too large to be a float. File
models number fields as :data:`Number` (finite, never a boolean) and flags as
:data:`Flag` (``true``/``false`` only).
"""

from __future__ import annotations

import json
import math
import os
import re
import tempfile
from collections import Counter
from pathlib import Path
from typing import Annotated, Any, Final, Literal, TypeVar

from pydantic import (
    AllowInfNan,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    Strict,
    ValidationError,
)

from .errors import ConfigurationError, OutputError

__all__ = [
    "MAX_DEPTH",
    "Coordinate",
    "Cost",
    "Flag",
    "Number",
    "SchemaVersion",
    "StrictModel",
    "atomic_write_bytes",
    "atomic_write_text",
    "check_output_place",
    "not_boolean",
    "parse_model",
    "read_json",
    "validation_field",
]

M = TypeVar("M", bound=BaseModel)

MAX_DEPTH: Final = 64
"""Deepest nesting of arrays and objects a file may have (msrr files need about 12)."""

_MAX_INT: Final = 2**63
"""Integers at least this large are refused (no msrr field needs one; float() of one
larger than 1e308 overflows)."""


def not_boolean(value: Any) -> Any:
    """A before-validator: ``true``/``false`` where a number is expected is an error."""
    if isinstance(value, bool):
        raise ValueError("must be a number, not a boolean")
    return value


Number = Annotated[float, Strict(), AllowInfNan(False)]
"""A finite number: an integer or a float, never a boolean, a string, NaN or infinity."""

Coordinate = Annotated[float, Strict(), AllowInfNan(False), Field(ge=-1e6, le=1e6)]
"""A position coordinate: a :data:`Number` within ±1e6 m (a robot a thousand
kilometres wide is a typing error, and squares of larger numbers overflow)."""

Cost = Annotated[float, Strict(), AllowInfNan(False), Field(ge=0.0, le=1e6)]
"""A motion cost or path length: a :data:`Number` in [0, 1e6]."""

Flag = Annotated[bool, Strict()]
"""``true`` or ``false``, never ``0``/``1`` or ``"yes"``."""

SchemaVersion = Annotated[Literal[1], BeforeValidator(not_boolean)]
"""``schema_version`` 1 of every file format (``true`` is not 1)."""


class StrictModel(BaseModel):
    """Base of every file model: unknown fields are errors, not silently dropped; no
    field anywhere accepts NaN or infinity."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` through a temporary file in the same folder and a rename.

    The rename is atomic on POSIX, so an interrupted or failed write (a full disk)
    leaves either the old file or the new one, never half of either, and no temporary
    file. The file gets the permissions of an ordinary new file (``0o666`` minus the
    umask), not the temporary file's ``0o600``. Missing parent folders are created.

    Returns:
        the path written.

    Raises:
        OutputError: the file could not be written (``No space left on device``, no
            permission, a parent that is a file); one line naming it.
    """
    target = Path(path)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    except OSError as exc:
        raise _not_written(target, exc) from None
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, target)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise _not_written(target, exc) from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return target


def _not_written(target: Path, exc: OSError) -> OutputError:
    """The one-line error of a write that failed with ``exc``."""
    return OutputError(f"cannot be written: {exc.strerror or exc}; nothing was written "
                       "under this name", source=str(target))


def check_output_place(path: str | os.PathLike[str], *, option: str, folder: bool = False) -> Path:
    """Refuse, before any work, a place the command could not write to.

    Refused: an empty path; for a file, an existing folder; for a folder (``folder``),
    an existing file; a path under a file; a place where nothing can be created (a
    temporary entry is made in the nearest existing folder and removed at once).

    Args:
        path: the output file or folder.
        option: the option that named it (``"--out"``), for the message.
        folder: whether ``path`` is a folder to write into.

    Returns:
        ``path`` as a :class:`~pathlib.Path`.

    Raises:
        ConfigurationError: one line naming the option and the path.
    """
    text = os.fspath(path)
    if not str(text).strip():
        raise ConfigurationError(f"is empty; give a {'folder' if folder else 'file'}",
                                 field=option)
    target = Path(path)
    source = str(text)
    try:
        if folder and target.exists() and not target.is_dir():
            raise ConfigurationError("is a file, expected a folder", field=option, source=source)
        if not folder and target.is_dir():
            raise ConfigurationError("is a folder, expected a file", field=option, source=source)
        ancestor = target.absolute() if folder else target.absolute().parent
        while not ancestor.exists() and ancestor != ancestor.parent:
            ancestor = ancestor.parent
        if not ancestor.is_dir():
            raise ConfigurationError(f"is under {ancestor}, which is a file", field=option,
                                     source=source)
        os.rmdir(tempfile.mkdtemp(prefix=".msrr-probe-", dir=ancestor))
    except OSError as exc:
        raise ConfigurationError(f"cannot be written: {exc.strerror or exc}", field=option,
                                 source=source) from None
    return target


def atomic_write_text(path: str | os.PathLike[str], text: str) -> Path:
    """:func:`atomic_write_bytes` of ``text`` in UTF-8."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def _umask() -> int:
    mask = os.umask(0)  # reading the umask means setting it; put it straight back
    os.umask(mask)
    return mask


class _Refused:
    """A JSON value :func:`read_json` refuses, kept in place so the error names its field."""

    __slots__ = ("why",)

    def __init__(self, why: str):
        self.why = why


class _Duplicates(dict):
    """A JSON object that repeated some keys (the repeated keys in ``repeated``)."""

    repeated: list[str]


class _Decoder:
    """The hooks of one :func:`json.loads`; they note whether anything was refused, so
    the common case (nothing) needs no walk with field paths."""

    def __init__(self) -> None:
        self.flagged = False

    def object(self, pairs: list[tuple[str, Any]]) -> dict[str, Any]:
        obj = dict(pairs)
        if len(obj) == len(pairs):
            return obj
        self.flagged = True
        marked = _Duplicates(obj)
        marked.repeated = [k for k, n in Counter(k for k, _ in pairs).items() if n > 1]
        return marked

    def float(self, text: str) -> float | _Refused:
        value = float(text)
        if math.isfinite(value):
            return value
        self.flagged = True
        return _Refused(f"number {text[:40]} is too large")

    def int(self, text: str) -> int | _Refused:
        if len(text) <= 18:
            return int(text)
        value = int(text) if len(text) <= 20 else None
        if value is not None and abs(value) < _MAX_INT:
            return value
        self.flagged = True
        return _Refused(f"integer of {len(text)} digits is too large")

    def constant(self, text: str) -> _Refused:
        self.flagged = True
        return _Refused(f"{text} is not a finite number")


def _too_deep(data: Any) -> bool:
    """Whether ``data`` nests arrays and objects deeper than :data:`MAX_DEPTH`."""
    level, depth = [data], 0
    while level:
        depth += 1
        if depth > MAX_DEPTH:
            return True
        deeper: list[Any] = []
        for value in level:
            if isinstance(value, dict | list):
                items = value.values() if isinstance(value, dict) else value
                deeper.extend(v for v in items if isinstance(v, dict | list))
        level = deeper
    return False


_SURROGATE_ESCAPE: Final = re.compile(r"\\u[dD][89a-fA-F]")


def _surrogate(text: str) -> bool:
    return not text.isprintable() and any("\ud800" <= c <= "\udfff" for c in text)


def _check_document(data: Any, source: str) -> None:
    """Find what :func:`read_json` refuses and raise naming its field (see module doc)."""
    stack: list[tuple[Any, tuple[Any, ...]]] = [(data, ())]
    while stack:
        value, loc = stack.pop()
        if isinstance(value, str):
            if _surrogate(value):
                raise ConfigurationError("a lone surrogate escape is not text",
                                         source=source, field=validation_field(loc))
        elif isinstance(value, _Refused):
            raise ConfigurationError(value.why, source=source, field=validation_field(loc))
        elif isinstance(value, dict | list):
            if len(loc) >= MAX_DEPTH:
                raise ConfigurationError(f"nested deeper than {MAX_DEPTH} levels",
                                         source=source, field=validation_field(loc[:3]) + "…")
            if isinstance(value, _Duplicates):
                raise ConfigurationError(f"repeated key {value.repeated[0]!r}", source=source,
                                         field=validation_field(loc))
            if isinstance(value, dict):
                for key, item in value.items():
                    if _surrogate(key):
                        raise ConfigurationError("a lone surrogate escape is not text",
                                                 source=source, field=validation_field(loc))
                    stack.append((item, (*loc, key)))
            else:
                stack.extend((item, (*loc, i)) for i, item in enumerate(value))


def read_json(path: str | os.PathLike[str]) -> Any:
    """Parse a JSON file strictly (see the module doc).

    Raises:
        ConfigurationError: a missing file, a folder, text that is not UTF-8, bad JSON,
            a document that is not an object, or one of the refusals of the module doc; one line naming the file and, when
            there is one, the field.
    """
    source = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigurationError("no such file", source=source) from None
    except IsADirectoryError:
        raise ConfigurationError("is a directory, expected a JSON file", source=source) from None
    except UnicodeDecodeError as exc:
        raise ConfigurationError(f"not UTF-8 text (byte {exc.start})", source=source) from None
    except OSError as exc:
        raise ConfigurationError(f"cannot read: {exc.strerror or exc}", source=source) from None
    decoder = _Decoder()
    try:
        data = json.loads(text, object_pairs_hook=decoder.object, parse_float=decoder.float,
                          parse_int=decoder.int, parse_constant=decoder.constant)
    except json.JSONDecodeError as exc:
        raise ConfigurationError(f"invalid JSON at line {exc.lineno} column {exc.colno}: "
                                 f"{exc.msg}", source=source) from None
    except RecursionError:
        raise ConfigurationError(f"nested deeper than {MAX_DEPTH} levels",
                                 source=source) from None
    if not isinstance(data, dict):
        raise ConfigurationError(f"holds {_what(data)}, not a JSON object ({{...}})",
                                 source=source)
    # a lone surrogate can only come from a \\u escape: the text itself was valid UTF-8
    if decoder.flagged or _SURROGATE_ESCAPE.search(text) or _too_deep(data):
        _check_document(data, source)
    return data


def _what(data: Any) -> str:
    """What a JSON document that is not an object holds, in words."""
    if data is None:
        return "null"
    if isinstance(data, bool):
        return "a boolean"
    if isinstance(data, str):
        return "a string"
    if isinstance(data, list):
        return "a list"
    return "a number"


def validation_field(loc: tuple[Any, ...]) -> str:
    """``("connections", 3, "z")`` -> ``"connections[3].z"``."""
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += f".{part}" if out else str(part)
    return out or "(document)"


def parse_model(model: type[M], data: Any, source: str | None = None) -> M:
    """Validate ``data`` against a pydantic model; the first error names its field."""
    try:
        return model.model_validate(data)
    except RecursionError:  # data that did not come through read_json
        raise ConfigurationError(f"nested deeper than {MAX_DEPTH} levels",
                                 source=source) from None
    except ValidationError as exc:
        errors = exc.errors()
        first = errors[0]
        more = f" (and {len(errors) - 1} more)" if len(errors) > 1 else ""
        raise ConfigurationError(f"{first['msg']}{more}", source=source,
                                 field=validation_field(tuple(first["loc"])),
                                 problems=tuple((validation_field(tuple(e["loc"])), e["msg"])
                                                for e in errors)) from None
