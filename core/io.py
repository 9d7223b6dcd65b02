"""Configuration files: pydantic models, reading, writing and rule validation.

The file format (``schema_version`` 1) is documented by the JSON Schema generated
from :class:`ConfigurationFile` and shipped as ``docs/configuration.schema.json``.
"""

from __future__ import annotations

import json
import os
from typing import Annotated, Final

from pydantic import ConfigDict, Field, ValidationInfo, field_validator

from .bodies import with_port_vectors
from .configuration import Configuration, unit
from .errors import ConfigurationError, DockingRuleError
from .files import (
    Coordinate,
    Number,
    SchemaVersion,
    StrictModel,
    atomic_write_text,
    parse_model,
    read_json,
)
from .robot import Robot

__all__ = [
    "SCHEMA_VERSION",
    "ConfigurationFile",
    "ConnectionModel",
    "ModuleModel",
    "check_configuration",
    "configuration_from_model",
    "configuration_to_model",
    "dump_configuration",
    "load_configuration",
    "parse_configuration",
    "save_configuration",
]

SCHEMA_VERSION: Final = 1

Vec3 = Annotated[list[Number], Field(min_length=3, max_length=3)]


class _Strict(StrictModel):
    """Module ids may be written as numbers (MMRP modules 1..9); they are read as strings."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, coerce_numbers_to_str=True)


class ModuleModel(_Strict):
    """A vertex: a module, or a virtual vertex (``kind: "virtual"``) for a free connector."""

    id: str = Field(min_length=1, description="Module id, unique in the file.")
    kind: str = Field(min_length=1, description="Module kind of the robot, or 'virtual'.")
    position: Annotated[list[Coordinate], Field(min_length=3, max_length=3)] | None = Field(
        None, description="Optional position [m], each coordinate within ±1e6.")


class ConnectionModel(_Strict):
    """An edge: a connection between two vertices (for FreeSN, a strut module)."""

    id: str | None = Field(None, min_length=1,
                           description="Edge id (module id for edge modules); generated if omitted.")
    source: str = Field(min_length=1, description="Vertex the connection leaves (parent).")
    target: str = Field(min_length=1, description="Vertex the connection reaches (child).")
    kind: str | None = Field(None, description="Module kind when the edge is a module.")
    z: Vec3 | None = Field(None, description="Unit connection direction, root horizontal frame.")
    x: Vec3 | None = Field(None, description="Unit forward direction, root horizontal frame.")
    ports: tuple[str, str] | None = Field(None, description="(source port, target port).")

    @field_validator("z", "x")
    @classmethod
    def _unit(cls, value: list[float] | None, info: ValidationInfo) -> list[float] | None:
        if value is not None:
            try:
                unit(value, what=str(info.field_name))
            except ConfigurationError as exc:
                raise ValueError(exc.message) from None
        return value


class ConfigurationFile(_Strict):
    """A configuration file: one robot configuration in its own module ids."""

    schema_version: SchemaVersion = Field(description="File format version.")
    robot: str = Field(min_length=1, description="Name of the robot plugin.")
    name: str = ""
    description: str = ""
    modules: list[ModuleModel]
    connections: list[ConnectionModel] = []


def configuration_from_model(model: ConfigurationFile, source: str | None = None) -> Configuration:
    """Build a :class:`Configuration`; structural errors name the offending field."""
    config = Configuration(model.robot, name=model.name, description=model.description)
    for i, module in enumerate(model.modules):
        try:
            config.add_module(module.id, module.kind, position=module.position)
        except ConfigurationError as exc:
            raise ConfigurationError(exc.message, source=source, field=f"modules[{i}].id") from None
    for i, conn in enumerate(model.connections):
        try:
            config.connect(conn.source, conn.target, id=conn.id, kind=conn.kind, z=conn.z,
                           x=conn.x, ports=conn.ports)
        except ConfigurationError as exc:
            raise ConfigurationError(exc.message, source=source,
                                     field=f"connections[{i}]") from None
    return config


def configuration_to_model(config: Configuration) -> ConfigurationFile:
    """The file model of ``config`` (exact floats, so a round trip is lossless)."""

    def vec(v):
        return None if v is None else [float(c) for c in v]

    return ConfigurationFile(
        schema_version=SCHEMA_VERSION,
        robot=config.robot,
        name=config.name,
        description=config.description,
        modules=[ModuleModel(id=v, kind=config.kind_of(v), position=vec(config.position(v)))
                 for v in config.vertices()],
        connections=[ConnectionModel(id=e.id, source=e.source, target=e.target, kind=e.kind,
                                     z=vec(e.z), x=vec(e.x), ports=e.ports)
                     for e in config.edges()],
    )


def parse_configuration(data: object, source: str | None = None) -> Configuration:
    """A :class:`Configuration` from already-parsed JSON data."""
    return configuration_from_model(parse_model(ConfigurationFile, data, source), source)


def load_configuration(path: str | os.PathLike[str], robot: Robot | None = None
                       ) -> Configuration:
    """Read a configuration file and, when ``robot`` is given, validate it against it.

    The robot is an argument: this layer never asks the plugin host. For "load and
    check against the installed robot the file names" use
    :func:`msrr.core.plugins.load_configuration`.

    Raises:
        ConfigurationError: missing file, bad JSON, a wrong field, or a broken rule
            of ``robot``; the message names the file and the field.
    """
    config = parse_configuration(read_json(path), str(path))
    if robot is not None:
        try:
            check_configuration(config, robot)
        except ConfigurationError as exc:
            raise exc.at(str(path)) from None
        config = with_port_vectors(config, robot.spec)
    return config


def dump_configuration(config: Configuration) -> str:
    """The JSON text of ``config``."""
    return json.dumps(configuration_to_model(config).model_dump(mode="json", exclude_none=True),
                      indent=2) + "\n"


def save_configuration(config: Configuration, path: str | os.PathLike[str]) -> None:
    """Write ``config`` to ``path`` atomically."""
    atomic_write_text(path, dump_configuration(config))


def check_configuration(config: Configuration, robot: Robot) -> None:
    """Validate ``config`` against ``robot``'s module kinds and docking rules.

    Core checks first (:func:`~msrr.core.robot.check_structure`: the file names this
    robot, every vertex kind is a vertex kind of the robot or virtual, every edge kind
    an edge kind, every port a port of its module kind, virtual vertices have exactly
    one connection), then the robot's :class:`~msrr.core.robot.DockingRules`.

    Raises:
        DockingRuleError: naming the first violation (and how many more there are).
    """
    violations = robot.violations(config)
    if violations:
        first = violations[0]
        more = f" (and {len(violations) - 1} more)" if len(violations) > 1 else ""
        raise DockingRuleError(f"{first.message}{more}", field=first.where,
                               problems=tuple((v.where, v.message) for v in violations))
