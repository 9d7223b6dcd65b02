"""Library source files: designed groups and trees, recorded sequences, parameter behaviors.

These are the inputs of automatic library creation (FreeSN paper, section 6.2,
Fig. 14(a)-(c)). One source file (``schema_version`` 1) may hold any of:

* ``groups`` -- designed topology groups: a reference skeletal configuration, one or
  more kinematic trees (a joint mode for the default tree, or a serialised tree)
  and optional extra designed configurations (Fig. 14(a));
* ``sequences`` -- recorded configuration sequences in the recording's own ids,
  with the intermediate configurations at topology changes (Fig. 14(b), (c)); a
  sequence may be labelled as a behavior and may loop (squirm, crawl);
* ``behaviors`` -- mappings from low-dimensional behavior parameters to module
  commands, starting from a named configuration of a sequence or a group.

Every configuration is checked against its robot's docking rules when read; a bad
file is refused with one line naming the file and the field.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Literal, TypeVar

from pydantic import Field

from ..configuration import Configuration
from ..errors import ConfigurationError, MsrrError, UnknownNameError
from ..files import Flag, Number, SchemaVersion, StrictModel, parse_model, read_json
from ..io import ConfigurationFile, check_configuration, configuration_from_model
from ..kinematics.tree import KinematicTree
from ..robot import Robot
from .model import CommandGain, LibraryError

_M = TypeVar("_M", bound=StrictModel)

__all__ = [
    "DesignedGroup",
    "DesignedTree",
    "LibrarySourceFile",
    "LibrarySources",
    "MappingBehaviorSource",
    "RecordedSequence",
    "SequenceStep",
    "load_sources",
]


class TreeSourceModel(StrictModel):
    name: str = Field(min_length=1, description="Tree name, unique in its group.")
    joint_mode: str | None = Field(None, description="Joint mode of the default tree.")
    tree: dict | None = Field(None, description="A serialised tree (KinematicTree.to_dict()).")


class GroupSourceModel(StrictModel):
    name: str = Field(min_length=1)
    description: str = ""
    reference: ConfigurationFile
    trees: list[TreeSourceModel] = Field(min_length=1)
    configurations: list[ConfigurationFile] = []


_DRIVE_ROOT_HELP = ("The node the behavior is driven from (a joint controller that drives "
                   "from one node grows its drive from it); default: of the nodes with the "
                   "most connections, the first by id.")


class StepModel(StrictModel):
    configuration: ConfigurationFile
    tree: str | None = Field(None, description="Tree of the target group that executes the "
                             "step into this configuration; the group's first by default.")


class SequenceSourceModel(StrictModel):
    name: str = Field(min_length=1)
    description: str = ""
    behavior: str | None = Field(None, description="Label the sequence as this behavior.")
    loop: Flag = Field(False, description="The last step returns to the first and repeats.")
    steps: list[StepModel] = Field(min_length=1)
    drive_root: str | None = Field(None, description=_DRIVE_ROOT_HELP)


class CommandSourceModel(StrictModel):
    module: str = Field(min_length=1)
    command: str = Field(min_length=1)
    connector: Literal["source", "target"] | None = None
    gains: dict[str, Number]


class MappingBehaviorModel(StrictModel):
    name: str = Field(min_length=1)
    description: str = ""
    start: str = Field(min_length=1, description="Name of a configuration of these sources.")
    parameters: list[str] = Field(min_length=1)
    commands: list[CommandSourceModel] = Field(min_length=1)
    drive_root: str | None = Field(None, description=_DRIVE_ROOT_HELP)


class LibrarySourceFile(StrictModel):
    """A library source file (FreeSN paper, section 6.2)."""

    schema_version: SchemaVersion
    robot: str = Field(min_length=1)
    library: str | None = Field(None, description="Name of the library these sources build.")
    description: str = ""
    groups: list[GroupSourceModel] = []
    sequences: list[SequenceSourceModel] = []
    behaviors: list[MappingBehaviorModel] = []


@dataclass(frozen=True)
class DesignedTree:
    """A designed kinematic tree: a joint mode for the default tree, or a serialised tree."""

    name: str
    joint_mode: str | None = None
    tree: dict | None = None


@dataclass(frozen=True)
class DesignedGroup:
    """A designed topology group (Fig. 14(a)) and where it was read from."""

    name: str
    reference: Configuration
    trees: tuple[DesignedTree, ...]
    configurations: tuple[Configuration, ...] = ()
    description: str = ""
    origin: str = ""


@dataclass(frozen=True)
class SequenceStep:
    configuration: Configuration
    tree: str | None = None


@dataclass(frozen=True)
class RecordedSequence:
    """A recorded configuration sequence in the recording's ids (Fig. 14(b))."""

    name: str
    steps: tuple[SequenceStep, ...]
    loop: bool = False
    behavior: str | None = None
    description: str = ""
    origin: str = ""
    drive_root: str | None = None


@dataclass(frozen=True)
class MappingBehaviorSource:
    """A parameter-to-command behavior in the ids of its start configuration."""

    name: str
    start: str
    parameters: tuple[str, ...]
    commands: tuple[CommandGain, ...]
    description: str = ""
    origin: str = ""
    drive_root: str | None = None


@dataclass(frozen=True)
class LibrarySources:
    """Every input of one library build, in file order.

    Attributes:
        robot: the robot all sources describe.
        name: the library name (from the first source that gives one).
        files: ``(file name, sha256)`` of every source, recorded in the library.
    """

    robot: str
    name: str
    groups: tuple[DesignedGroup, ...]
    sequences: tuple[RecordedSequence, ...]
    behaviors: tuple[MappingBehaviorSource, ...]
    files: tuple[tuple[str, str], ...]
    description: str = ""


def _configuration(model: ConfigurationFile, source: str, field: str, robot: Robot
                   ) -> Configuration:
    try:
        config = configuration_from_model(model)
        if config.robot != robot.name:
            raise ConfigurationError(f"robot is {config.robot!r}, the file is for "
                                     f"{robot.name!r}", field="robot")
        check_configuration(config, robot)
    except ConfigurationError as exc:
        inner = f".{exc.field}" if exc.field else ""
        raise LibraryError(exc.message, source=source, field=f"{field}{inner}") from None
    return config


def _sequence(model: SequenceSourceModel, source: str, where: str, robot: Robot,
              origin: str) -> RecordedSequence:
    """A recorded sequence: every step the same modules, its drive root a node of them."""
    steps = tuple(SequenceStep(_configuration(st.configuration, source,
                                              f"{where}.steps[{j}].configuration", robot),
                               st.tree)
                  for j, st in enumerate(model.steps))
    modules = set(steps[0].configuration.modules())
    for j, step in enumerate(steps):
        if set(step.configuration.modules()) != modules:
            raise LibraryError("every step of a sequence needs the same modules (identical "
                               "module ids, section 6.2)", source=source,
                               field=f"{where}.steps[{j}]")
    if model.drive_root is not None and \
            model.drive_root not in steps[0].configuration.vertices(virtual=False):
        raise LibraryError(f"no node {model.drive_root!r} in the sequence's first step",
                           source=source, field=f"{where}.drive_root")
    return RecordedSequence(model.name, steps, model.loop, model.behavior, model.description,
                            origin, model.drive_root)


def _check_tree(model: TreeSourceModel, reference: Configuration, robot: Robot, source: str,
                field: str) -> None:
    """A designed tree names one of the robot's joint modes, or is a serialised tree that
    loads on its group's reference with the robot's joint modes."""
    if model.tree is not None and model.joint_mode is not None:
        raise LibraryError("give a joint_mode or a tree, not both", source=source, field=field)
    if model.joint_mode is not None and model.joint_mode not in robot.joint_modes:
        raise LibraryError(str(UnknownNameError(f"joint mode for robot {robot.name!r}",
                                                model.joint_mode, robot.joint_modes)),
                           source=source, field=f"{field}.joint_mode")
    if model.tree is not None:
        try:
            KinematicTree.from_dict(model.tree, reference, modes=robot.joint_modes)
        except ConfigurationError as exc:
            inner = f".{exc.field}" if exc.field else ""
            raise LibraryError(exc.message, source=source, field=f"{field}.tree{inner}") from None


def read_model(model: type[_M], path: str | os.PathLike[str]) -> _M:
    """A library or library-source file parsed strictly into ``model``; any error is a
    :class:`LibraryError` naming the file and the field."""
    try:
        return parse_model(model, read_json(path), str(path))
    except LibraryError:
        raise
    except ConfigurationError as exc:
        raise LibraryError(exc.message, source=exc.source, field=exc.field) from None


def _read(path: Path, robot: str | None) -> tuple[LibrarySourceFile, str]:
    source = str(path)
    model = read_model(LibrarySourceFile, path)
    if robot is not None and model.robot != robot:
        raise LibraryError(f"is for robot {model.robot!r}, the other sources for {robot!r}",
                           source=source, field="robot")
    return model, source


def _source_files(path: Path) -> list[Path]:
    """``path``, or a folder's ``*.json`` files in name order."""
    if not path.is_dir():
        return [path]
    found = sorted(path.glob("*.json"))
    if not found:
        raise LibraryError("is a folder without a *.json library source file", source=str(path))
    return found


def _commands(robot: Robot) -> set[str] | None:
    """Every behavior command the robot's module kinds declare; ``None``: none declares."""
    declared = [k.commands for k in robot.spec.module_kinds if k.commands is not None]
    return None if not declared else {c for kind in declared for c in kind}


def load_sources(paths: Iterable[str | os.PathLike[str]], robots: Callable[[str], Robot]
                 ) -> LibrarySources:
    """Read library source files (designs, sequences, behaviors) in the given order.

    Args:
        paths: the source files; a folder stands for its ``*.json`` files in name order.
        robots: the :class:`~msrr.core.robot.Robot` of a robot name (the sources name
            their robot; ``msrr.core.plugins.resolve`` at the top layer).

    Raises:
        LibraryError: no file, a bad file, sources for different robots, or a
            configuration that breaks its robot's docking rules; names file and field.
    """
    paths = [f for p in map(Path, paths) for f in _source_files(p)]
    if not paths:
        raise LibraryError("no library source files given")
    robot: Robot | None = None
    name = description = ""
    groups: list[DesignedGroup] = []
    sequences: list[RecordedSequence] = []
    behaviors: list[MappingBehaviorSource] = []
    files = []
    for path in paths:
        model, source = _read(path, None if robot is None else robot.name)
        if robot is None:
            try:
                robot = robots(model.robot)
            except MsrrError as exc:
                raise LibraryError(str(exc), source=source, field="robot") from None
        name = name or (model.library or "")
        description = description or model.description
        files.append((path.name, hashlib.sha256(path.read_bytes()).hexdigest()))
        for i, g in enumerate(model.groups):
            where = f"groups[{i}]"
            reference = _configuration(g.reference, source, f"{where}.reference", robot)
            for k, t in enumerate(g.trees):
                _check_tree(t, reference, robot, source, f"{where}.trees[{k}]")
            groups.append(DesignedGroup(
                name=g.name, description=g.description, reference=reference,
                trees=tuple(DesignedTree(t.name, t.joint_mode, t.tree) for t in g.trees),
                configurations=tuple(
                    _configuration(c, source, f"{where}.configurations[{j}]", robot)
                    for j, c in enumerate(g.configurations)),
                origin=path.name))
        sequences += [_sequence(s, source, f"sequences[{i}]", robot, path.name)
                      for i, s in enumerate(model.sequences)]
        taken = _commands(robot)
        for i, b in enumerate(model.behaviors):
            for j, c in enumerate(b.commands):
                if taken is not None and c.command not in taken:
                    raise LibraryError(f"unknown command {c.command!r} (robot {robot.name!r} "
                                       f"takes: {', '.join(sorted(taken)) or 'none'})",
                                       source=source, field=f"behaviors[{i}].commands[{j}]"
                                       ".command")
                unknown = sorted(set(c.gains) - set(b.parameters))
                if unknown:
                    raise LibraryError(f"unknown parameter {unknown[0]!r} (parameters: "
                                       f"{', '.join(b.parameters)})", source=source,
                                       field=f"behaviors[{i}].commands[{j}].gains")
            commands = tuple(CommandGain(c.module, c.command, tuple(sorted(c.gains.items())),
                                         c.connector) for c in b.commands)
            behaviors.append(MappingBehaviorSource(b.name, b.start, tuple(b.parameters), commands,
                                                   b.description, path.name, b.drive_root))
    assert robot is not None
    return LibrarySources(robot.name, name or paths[0].stem, tuple(groups), tuple(sequences),
                          tuple(behaviors), tuple(files), description)
