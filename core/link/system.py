"""The systems file: which modules make up one system, where they are, and its key.

A small JSON file (``docs/hardware.md``)::

    {"schema_version": 1, "system": 4242, "robot": "mmrp",
     "key": {"file": "system.key"},             # or {"env": "MSRR_LINK_KEY"}
     "timeout_s": 1.0, "time_scale": 1.0, "budget_kbps": 60,
     "group": {"address": "192.168.4.255", "port": 47000},
     "records": [{"type": "msrr.plugins.freesn.sim.world:NodeReport", "rotations": ["tilt"]}],
     "vectors": ["a.dir", "a.fwd", "b.dir", "b.fwd"], "pose_every": 2,
     "modules": [{"id": "1", "number": 1, "address": "127.0.0.1", "port": 47001}, ...]}

The key is the *site key*, held by the host only; each module holds its own module
key derived from it (:func:`~.keys.module_key`). It is never in the systems file: it is
read from a key file (64 hexadecimal digits, a path relative to the systems file) or an
environment variable, so the systems file can be copied into run folders, logs and
reports.
"""

from __future__ import annotations

import ipaddress
import os
import secrets
from pathlib import Path

from pydantic import Field, model_validator

from ..errors import ConfigurationError
from ..files import (
    SchemaVersion,
    StrictModel,
    atomic_write_bytes,
    atomic_write_text,
    parse_model,
    read_json,
)

__all__ = ["GroupAddress", "KeyRef", "ModuleEntry", "RecordEntry", "SystemFile", "load_key",
           "load_system", "new_key", "write_key", "write_system"]

KEY_BYTES = 32
MIN_KEY_BYTES = 16


class KeyRef(StrictModel):
    """Where the key is: a key file (relative to the systems file) or an env variable."""

    file: str | None = None
    env: str | None = None

    @model_validator(mode="after")
    def _one(self) -> KeyRef:
        if (self.file is None) == (self.env is None):
            raise ValueError("give exactly one of 'file' and 'env'")
        return self


def _ipv4(address: str) -> str:
    try:
        ipaddress.IPv4Address(address)
    except ValueError:
        raise ValueError(f"address {address!r} is not an IPv4 address "
                         "(the link runs over UDP/IPv4)") from None
    return address


class GroupAddress(StrictModel):
    """Where the host sends the one COMMAND frame of each tick: a broadcast (or
    multicast) address and port every module listens on as well as its own."""

    address: str
    port: int = Field(ge=1, le=65535)

    @model_validator(mode="after")
    def _address(self) -> GroupAddress:
        _ipv4(self.address)
        return self


class RecordEntry(StrictModel):
    """A record type reports may carry; its id is its place in the list (from 1).

    Attributes:
        type: the dataclass, ``"package.module:QualName"`` (of the robot's package).
        rotations: fields whose 3x3 rotation matrices travel as quaternions.
        directions: fields whose unit 3-vectors travel as three int16.
    """

    type: str = Field(min_length=3)
    rotations: list[str] = Field(default_factory=list)
    directions: list[str] = Field(default_factory=list)


class ModuleEntry(StrictModel):
    """One module: its id in configurations, its number on the link, its address.

    Attributes:
        id: the module id of the configuration files.
        number: link number, 1..65535 (0 is the host).
        address: IP address the module listens on. port: its UDP port.
        timeout_s: silence after which the host stops the run [s]; default the system's.
    """

    id: str = Field(min_length=1)
    number: int = Field(ge=1, le=65535)
    address: str
    port: int = Field(ge=1, le=65535)
    timeout_s: float | None = Field(default=None, gt=0)

    @model_validator(mode="after")
    def _address(self) -> ModuleEntry:
        _ipv4(self.address)
        return self


class SystemFile(StrictModel):
    """A systems file (module doc).

    Attributes:
        system: the system id (u32; it enters every module key, so two systems on one
            network never accept each other's frames).
        robot: the robot the modules are.
        key: where the site key is.
        timeout_s: default silence timeout of a module [s]; also the largest age of an
            accepted frame.
        watchdog_s: the modules' command watchdog [s]; ``None``: 3 control periods.
        time_scale: module clock / wall clock (an emulator running faster; 1 on hardware).
        budget_kbps: the link's budget [kbit/s, UDP/IP headers included]: the host
            spaces the modules' reports (every 1 to 6 control periods) to stay within
            it; ``None``: a report every period.
        group: where COMMAND frames go; ``None``: to each module's own address.
        records: the record types reports may carry (ids 1, 2, ...).
        vectors: joint names ``N`` of the robot's commands whose joints ``N_x``, ``N_y``,
            ``N_z`` carry a unit vector (FreeSN: ``a.dir``, ...): each travels as one
            4-byte direction instead of three floats.
        pose_every: a report carries the module's pose at most every this many reports
            (1: every report that changed it). Both as the robot declares them
            (:mod:`.declarations`).
        modules: the modules, distinct ids, numbers and addresses.
    """

    schema_version: SchemaVersion = 1
    system: int = Field(ge=0, le=0xFFFFFFFF)
    robot: str = Field(min_length=1)
    key: KeyRef
    timeout_s: float = Field(default=1.0, gt=0)
    watchdog_s: float | None = Field(default=None, gt=0)
    time_scale: float = Field(default=1.0, gt=0, le=100)
    budget_kbps: float | None = Field(default=None, gt=0)
    group: GroupAddress | None = None
    records: list[RecordEntry] = Field(default_factory=list)
    vectors: list[str] = Field(default_factory=list)
    pose_every: int = Field(default=1, ge=1, le=10)
    modules: list[ModuleEntry] = Field(min_length=1)

    @model_validator(mode="after")
    def _distinct(self) -> SystemFile:
        for what, values in (("id", [m.id for m in self.modules]),
                             ("number", [m.number for m in self.modules]),
                             ("address", [(m.address, m.port) for m in self.modules])):
            if len(set(values)) != len(values):
                raise ValueError(f"two modules with one {what}")
        if len(set(self.vectors)) != len(self.vectors) or not all(
                v.strip() and v == v.strip() for v in self.vectors):
            raise ValueError("vectors must be distinct joint names without blanks")
        return self

    def timeout(self, module: ModuleEntry) -> float:
        """The silence timeout of ``module`` [s]."""
        return module.timeout_s if module.timeout_s is not None else self.timeout_s


def load_system(path: str | os.PathLike[str]) -> SystemFile:
    """Read and check a systems file.

    Raises:
        ConfigurationError: naming the file and field.
    """
    return parse_model(SystemFile, read_json(path), str(path))


def write_system(path: str | os.PathLike[str], system: SystemFile) -> Path:
    """Write ``system`` as JSON (atomically); the key is not in it."""
    return atomic_write_text(path, system.model_dump_json(indent=2, exclude_none=True) + "\n")


def new_key() -> bytes:
    """A fresh random site key of 32 bytes."""
    return secrets.token_bytes(KEY_BYTES)


def write_key(path: str | os.PathLike[str], key: bytes) -> Path:
    """Write ``key`` as hexadecimal text to a file only its owner can read (0600)."""
    written = atomic_write_bytes(path, key.hex().encode("ascii") + b"\n")
    os.chmod(written, 0o600)
    return written


def parse_key(text: str, where: str, field: str) -> bytes:
    try:
        key = bytes.fromhex(text.strip())
    except ValueError:
        raise ConfigurationError("is not hexadecimal", source=where, field=field) from None
    if len(key) < MIN_KEY_BYTES:
        raise ConfigurationError(f"has {len(key)} bytes, at least {MIN_KEY_BYTES} needed",
                                 source=where, field=field)
    return key


def load_key(system: SystemFile, path: str | os.PathLike[str]) -> bytes:
    """The key ``system.key`` refers to; a key file is relative to the systems file
    ``path``. The error names where the key was looked for, never its value.

    Raises:
        ConfigurationError: a missing or unreadable key, or one shorter than 16 bytes.
    """
    if system.key.env is not None:
        text = os.environ.get(system.key.env)
        if text is None:
            raise ConfigurationError(f"environment variable {system.key.env} is not set",
                                     source=str(path), field="key.env")
        return parse_key(text, f"${system.key.env}", "key")
    assert system.key.file is not None
    key_path = Path(path).parent / system.key.file
    try:
        text = key_path.read_text(encoding="ascii")
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigurationError(f"cannot read the key file {key_path}: "
                                 f"{getattr(exc, 'strerror', None) or exc}", source=str(path),
                                 field="key.file") from None
    return parse_key(text, str(key_path), "key")
