"""File helpers shared by every writer: atomic writes and readable JSON errors."""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import Any, TypeVar

from pydantic import BaseModel, ConfigDict, ValidationError

from .errors import ConfigurationError

__all__ = ["StrictModel", "atomic_write_bytes", "atomic_write_text", "parse_model", "read_json", "validation_field"]

M = TypeVar("M", bound=BaseModel)


class StrictModel(BaseModel):
    """Base of every file model: unknown fields are errors, not silently dropped."""

    model_config = ConfigDict(extra="forbid")


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` through a temporary file in the same folder and a rename.

    The rename is atomic on POSIX, so an interrupted write leaves either the old file
    or the new one, never half of either, and no temporary file. The file gets the
    permissions of an ordinary new file (``0o666`` minus the umask), not the
    temporary file's ``0o600``. Missing parent folders are created.

    Returns:
        the path written.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return target


def atomic_write_text(path: str | os.PathLike[str], text: str) -> Path:
    """:func:`atomic_write_bytes` of ``text`` in UTF-8."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def _umask() -> int:
    mask = os.umask(0)  # reading the umask means setting it; put it straight back
    os.umask(mask)
    return mask


def read_json(path: str | os.PathLike[str]) -> Any:
    """Parse a JSON file; a missing file or bad JSON becomes a one-line ConfigurationError."""
    source = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigurationError("no such file", source=source) from None
    except IsADirectoryError:
        raise ConfigurationError("is a directory, expected a JSON file", source=source) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigurationError(f"cannot read: {exc}", source=source) from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise ConfigurationError(f"invalid JSON at line {exc.lineno} column {exc.colno}: "
                                 f"{exc.msg}", source=source) from None


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
    except ValidationError as exc:
        errors = exc.errors()
        first = errors[0]
        more = f" (and {len(errors) - 1} more)" if len(errors) > 1 else ""
        raise ConfigurationError(f"{first['msg']}{more}", source=source,
                                 field=validation_field(tuple(first["loc"]))) from None
