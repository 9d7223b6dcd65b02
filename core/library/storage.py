"""Library files: one JSON file per library, pydantic-validated, written atomically.

The format (``schema_version`` 1) mirrors :mod:`msrr.core.library.model`. A group
stores its reference topology once, as a configuration file model; each of its
configurations stores only its ``z`` vector per edge id, so every configuration of
a group has the group's topology by construction. Loading checks the schema and
then every cross-reference (groups, trees, configuration ids, mapped ids); the first
problem is reported as one line naming the file and the field.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable
from typing import Annotated, Literal

from pydantic import AllowInfNan, Field, Strict, field_validator

from ..configuration import Configuration
from ..errors import ConfigurationError
from ..files import (
    Cost,
    Flag,
    Number,
    SchemaVersion,
    StrictModel,
    atomic_write_text,
)
from ..io import ConfigurationFile, configuration_from_model, configuration_to_model
from ..kinematics.tree import KinematicTree
from ..mapping import ModuleMap
from ..plan import ActionType
from ..robot import Robot, RobotSpec
from .model import (
    ActionEdge,
    Behavior,
    CommandGain,
    Group,
    Library,
    LibraryConfiguration,
    LibraryError,
    SubLibrary,
    TreeRef,
)
from .sources import CommandSourceModel, read_model

__all__ = [
    "LIBRARY_SCHEMA_VERSION",
    "LibraryFile",
    "dump_library",
    "library_from_model",
    "library_to_model",
    "load_library",
    "save_library",
]

LIBRARY_SCHEMA_VERSION = 1

Vec3 = Annotated[list[Number], Field(min_length=3, max_length=3)]


class TreeModel(StrictModel):
    name: str = Field(min_length=1, description="Tree name, unique in its group.")
    tree: dict = Field(description="Serialised kinematic tree (KinematicTree.to_dict()).")


class GroupModel(StrictModel):
    id: str = Field(min_length=1, description="Group id, '<sub-library>-<n>'.")
    name: str = ""
    description: str = ""
    reference: ConfigurationFile
    trees: list[TreeModel] = Field(min_length=1)


class ConfigurationModel(StrictModel):
    id: str = Field(min_length=1)
    group: str = Field(min_length=1)
    names: list[str] = []
    origins: list[str] = []
    z: dict[str, Vec3] = Field(description="Unit connection vector per reference edge id.")

    @field_validator("z")
    @classmethod
    def _unit(cls, value: dict[str, list[float]]) -> dict[str, list[float]]:
        for key, vector in value.items():
            norm = math.sqrt(sum(c * c for c in vector))
            if not abs(norm - 1.0) <= 1e-6:
                raise ValueError(f"z of {key!r} must be a unit vector, its norm is {norm:.6g}")
        return value


class BehaviorModel(StrictModel):
    name: str = Field(min_length=1)
    kind: Literal["sequence", "mapping"]
    description: str = ""
    start: str = Field(min_length=1)
    steps: list[str] = []
    loop: Flag = False
    parameters: list[str] = []
    commands: list[CommandSourceModel] = []
    drive_root: str | None = Field(None, description="The node the behavior is driven from, "
                                   "in the start's ids (absent: the controller's choice).")


class TreeRefModel(StrictModel):
    group: str
    name: str


class MappingModel(StrictModel):
    nodes: dict[str, str] = {}
    edges: dict[str, tuple[str, Flag]] = {}


class EdgeModel(StrictModel):
    source: str
    target: str
    action: ActionType
    tree: TreeRefModel
    cost: Cost
    mapping: MappingModel | None = None
    feasible: Flag | None = None


class SubLibraryModel(StrictModel):
    name: str = Field(min_length=1)
    groups: list[GroupModel]
    configurations: list[ConfigurationModel]
    behaviors: list[BehaviorModel] = []
    edges: list[EdgeModel] = []


class SourceRefModel(StrictModel):
    file: str = Field(min_length=1, description="A source file the library was built from.")
    sha256: str = Field(pattern=r"^[0-9a-f]{64}$", description="Its SHA-256 digest (hex).")


class BuildModel(StrictModel):
    """How the library was built (``platform library build``)."""

    merge_threshold: Annotated[float, Strict(), AllowInfNan(False), Field(ge=0.0, le=100.0)] \
        | None = Field(None, description="Largest motion cost at which configurations merged.")
    cost: Literal["distance", "ik"] | None = Field(None, description="The motion cost used.")
    sources: list[SourceRefModel] = []


class LibraryFile(StrictModel):
    """A behavior library file (FreeSN paper, section 6.1)."""

    schema_version: SchemaVersion = Field(description="File format version.")
    robot: str = Field(min_length=1)
    name: str = Field(min_length=1)
    description: str = ""
    build: BuildModel = BuildModel()
    sublibraries: list[SubLibraryModel]


# -- model -> library -----------------------------------------------------------------


_Fail = Callable[[str, str], LibraryError]
"""``fail(field, message)``: the error naming the file and ``field`` under the sub-library."""


def _sublibrary_from_model(model: SubLibraryModel, where: str, source: str | None,
                           library_robot: str, robot: Robot | None) -> SubLibrary:
    def fail(field: str, message: str) -> LibraryError:
        return LibraryError(message, source=source, field=f"{where}.{field}")

    sub = SubLibrary(model.name)
    _add_groups(sub, model, fail, library_robot, robot)
    _add_configurations(sub, model, fail, robot)
    _add_edges(sub, model, fail)
    _add_behaviors(sub, model, fail, robot)
    return sub


def _add_groups(sub: SubLibrary, model: SubLibraryModel, fail: _Fail, library_robot: str,
                robot: Robot | None) -> None:
    """The groups: unique ids, references of the library's robot, unique tree names."""
    for i, gm in enumerate(model.groups):
        if gm.id in sub.groups:
            raise fail(f"groups[{i}].id", f"duplicate group id {gm.id!r}")
        try:
            reference = configuration_from_model(gm.reference)
        except ConfigurationError as exc:
            raise fail(f"groups[{i}].reference.{exc.field or ''}".rstrip("."),
                       exc.message) from None
        if reference.robot != library_robot:
            raise fail(f"groups[{i}].reference.robot", f"is {reference.robot!r}, the library "
                       f"is for {library_robot!r}")
        names = [t.name for t in gm.trees]
        if len(set(names)) != len(names):
            raise fail(f"groups[{i}].trees", "duplicate tree names")
        if robot is not None:
            _check_group(reference, gm, robot, model.name, lambda f, m, i=i: fail(
                f"groups[{i}].{f}", m))
        sub.groups[gm.id] = Group(gm.id, gm.name, reference, {t.name: t.tree for t in gm.trees},
                                  gm.description)


def _add_configurations(sub: SubLibrary, model: SubLibraryModel, fail: _Fail,
                        robot: Robot | None) -> None:
    """The configurations: unique ids and names, a known group, a ``z`` per group edge."""
    taken: dict[str, str] = {}  # id or name -> the configuration id that has it
    for i, cm in enumerate(model.configurations):
        if cm.id in sub.configurations:
            raise fail(f"configurations[{i}].id", f"duplicate configuration id {cm.id!r}")
        if cm.group not in sub.groups:
            raise fail(f"configurations[{i}].group", f"unknown group {cm.group!r} (known: "
                       f"{', '.join(sub.groups)})")
        for j, key in enumerate([cm.id, *cm.names]):
            if taken.get(key, cm.id) != cm.id:
                field = "id" if j == 0 else f"names[{j - 1}]"
                raise fail(f"configurations[{i}].{field}", f"{key!r} already names "
                           f"configuration {taken[key]!r}")
            taken[key] = cm.id
        reference = sub.groups[cm.group].reference
        if set(cm.z) != set(reference.edge_ids()):
            raise fail(f"configurations[{i}].z", "needs exactly the edges of group "
                       f"{cm.group} ({', '.join(reference.edge_ids())})")
        config = reference.with_vectors(z=cm.z, x={})
        config.name = cm.names[0] if cm.names else cm.id
        if robot is not None:
            found = robot.violations(config)
            if found:
                raise fail(f"configurations[{i}]", f"{found[0].where}: {found[0].message}")
        sub.configurations[cm.id] = LibraryConfiguration(cm.id, cm.group, config,
                                                         tuple(cm.names), tuple(cm.origins))


def _add_edges(sub: SubLibrary, model: SubLibraryModel, fail: _Fail) -> None:
    """The action edges: known ends, a tree of one end's group, a mapping across groups."""
    for i, em in enumerate(model.edges):
        for end in ("source", "target"):
            if getattr(em, end) not in sub.configurations:
                raise fail(f"edges[{i}].{end}", f"unknown configuration {getattr(em, end)!r}")
        group = sub.groups.get(em.tree.group)
        if group is None or em.tree.name not in group.trees:
            raise fail(f"edges[{i}].tree", f"unknown kinematic tree {em.tree.group}/"
                       f"{em.tree.name}")
        ends = {sub.configurations[em.source].group, sub.configurations[em.target].group}
        if em.tree.group not in ends:
            raise fail(f"edges[{i}].tree.group", f"tree of group {em.tree.group!r}, the edge "
                       f"joins {' and '.join(sorted(ends))}")
        mapping = None
        if em.mapping is not None:
            mapping = _edge_mapping(em.mapping, sub.configurations[em.source].configuration,
                                    sub.configurations[em.target].configuration,
                                    lambda m, i=i: fail(f"edges[{i}].mapping", m))
        elif sub.configurations[em.source].group != sub.configurations[em.target].group:
            raise fail(f"edges[{i}].mapping", "an edge across groups needs a module mapping")
        sub.edges.append(ActionEdge(em.source, em.target, em.action,
                                    TreeRef(em.tree.group, em.tree.name), em.cost, mapping,
                                    em.feasible))


def _edge_mapping(model: MappingModel, src: Configuration, dst: Configuration,
                  fail: Callable[[str], LibraryError]) -> ModuleMap:
    """An edge's module mapping from ``src`` to ``dst``: their ids, one-to-one."""
    mapping = ModuleMap(dict(model.nodes), dict(model.edges))
    bad = [e for e, (image, _) in mapping.edges.items()
           if e not in src.edge_ids() or image not in dst.edge_ids()]
    bad += [v for v, image in mapping.nodes.items() if v not in src or image not in dst]
    if bad:
        raise fail(f"maps ids that are not in its configurations: {', '.join(sorted(bad))}")
    modules = {v for v in src.vertices() if not src.is_virtual(v)} | set(src.edge_ids())
    missing = sorted(modules - {*mapping.nodes, *mapping.edges})
    if missing:
        raise fail(f"leaves out {', '.join(missing)} of the source configuration (a mapping "
                   "names every module and connection)")
    for kind, images in (("edge", [e for e, _ in mapping.edges.values()]),
                         ("node", list(mapping.nodes.values()))):
        if len(set(images)) != len(images):
            raise fail(f"maps two {kind}s to one")
    return mapping


def _add_behaviors(sub: SubLibrary, model: SubLibraryModel, fail: _Fail,
                   robot: Robot | None = None) -> None:
    """The behaviors: unique names, known configurations, command modules in the start
    configuration, gains of declared parameters and, with ``robot``, commands its module
    kinds take (:func:`command_problem`)."""
    for i, bm in enumerate(model.behaviors):
        if bm.name in sub.behaviors:
            raise fail(f"behaviors[{i}].name", f"duplicate behavior {bm.name!r}")
        for j, step in enumerate([bm.start, *bm.steps]):
            if step not in sub.configurations:
                field = "start" if j == 0 else f"steps[{j - 1}]"
                raise fail(f"behaviors[{i}].{field}", f"unknown configuration {step!r}")
        start = sub.configurations[bm.start].configuration
        for j, c in enumerate(bm.commands):
            where_c = f"behaviors[{i}].commands[{j}]"
            if c.module not in start and c.module not in start.edge_ids():
                raise fail(f"{where_c}.module", f"no module {c.module!r} in the start "
                           f"configuration {bm.start!r}")
            problem = None if robot is None else command_problem(c, start, robot.spec)
            if problem is not None:
                raise fail(f"{where_c}.{problem[0]}", problem[1])
            unknown = sorted(set(c.gains) - set(bm.parameters))
            if unknown:
                raise fail(f"{where_c}.gains", f"unknown parameter {unknown[0]!r} (parameters: "
                           f"{', '.join(bm.parameters) or 'none'})")
        if bm.drive_root is not None and bm.drive_root not in start.vertices(virtual=False):
            raise fail(f"behaviors[{i}].drive_root", f"no node {bm.drive_root!r} in the start "
                       f"configuration {bm.start!r}")
        commands = tuple(CommandGain(c.module, c.command, tuple(sorted(c.gains.items())),
                                     c.connector) for c in bm.commands)
        sub.behaviors[bm.name] = Behavior(bm.name, bm.kind, bm.start, tuple(bm.steps), bm.loop,
                                          tuple(bm.parameters), commands, bm.description,
                                          bm.drive_root)


def command_problem(command: CommandSourceModel, start: Configuration, spec: RobotSpec
                    ) -> tuple[str, str] | None:
    """What is wrong with a behavior's command of a module of ``start``, as ``(field,
    message)``: a command its module kind does not declare
    (:attr:`~msrr.core.robot.ModuleKind.commands`), or a connector (an end of a
    connection) on a module that is not a connection; ``None``: nothing."""
    is_edge = command.module not in start
    kind_name = start.edge(command.module).kind if is_edge else start.kind_of(command.module)
    kind = next((k for k in spec.module_kinds if k.name == kind_name), None)
    if kind is not None and kind.commands is not None and command.command not in kind.commands:
        return "command", (f"unknown command {command.command!r} of a {kind.name} module "
                           f"(known: {', '.join(kind.commands) or 'none: it takes none'})")
    if command.connector is not None and not is_edge:
        return "connector", (f"{command.connector!r} names an end of a connection; "
                             f"{command.module} is a {kind_name} module")
    return None


def _check_group(reference: Configuration, gm: GroupModel, robot: Robot, sub_name: str,
                 fail: _Fail) -> None:
    """A group's reference follows the robot's rules, names its sub-library, and every
    tree loads on it with the robot's joint modes."""
    found = robot.violations(reference)
    if found:
        raise fail("reference", f"{found[0].where}: {found[0].message}")
    label = reference.signature().label(robot.spec)
    if label != sub_name:
        raise fail("reference", f"has modules {label}, not those of sub-library {sub_name}")
    for k, tm in enumerate(gm.trees):
        named = tm.tree.get("configuration", gm.reference.name)
        if named != gm.reference.name:
            raise fail(f"trees[{k}].tree.configuration", f"is {named!r}, the group's "
                       f"reference is {gm.reference.name!r}")
        try:
            KinematicTree.from_dict(tm.tree, reference, modes=robot.joint_modes)
        except ConfigurationError as exc:
            inner = f".{exc.field}" if exc.field else ""
            raise fail(f"trees[{k}].tree{inner}", exc.message) from None


def library_from_model(model: LibraryFile, source: str | None = None,
                       robot: Robot | None = None) -> Library:
    """A :class:`Library` from its file model; errors name ``source`` and the field.

    Always checked: every cross-reference (groups, trees, configurations, edges,
    behaviors, mapped ids, command modules and parameters), one robot throughout, and
    that no id or name is used by two configurations. With ``robot`` also: it is the
    library's robot, every reference and configuration follows its rules, every
    sub-library holds the module counts it is named after, and every kinematic tree
    loads on its group's reference with the robot's joint modes.
    """
    if robot is not None and robot.name != model.robot:
        raise LibraryError(f"is a library for robot {model.robot!r}, not {robot.name!r}",
                           source=source, field="robot")
    library = Library(model.robot, model.name, build=model.build.model_dump(exclude_none=True),
                      description=model.description)
    for i, sm in enumerate(model.sublibraries):
        if sm.name in library.sublibraries:
            raise LibraryError(f"duplicate sub-library {sm.name!r}", source=source,
                               field=f"sublibraries[{i}].name")
        library.sublibraries[sm.name] = _sublibrary_from_model(
            sm, f"sublibraries[{i}]", source, model.robot, robot)
    return library


# -- library -> model -----------------------------------------------------------------


def _vec(v) -> list[float]:
    return [float(c) for c in v]


def _sublibrary_to_model(sub: SubLibrary) -> SubLibraryModel:
    return SubLibraryModel(
        name=sub.name,
        groups=[GroupModel(id=g.id, name=g.name, description=g.description,
                           reference=configuration_to_model(g.reference.skeletal()),
                           trees=[TreeModel(name=n, tree=t) for n, t in g.trees.items()])
                for g in sub.groups.values()],
        configurations=[ConfigurationModel(
            id=c.id, group=c.group, names=list(c.names), origins=list(c.origins),
            z={e: _vec(c.configuration.edge(e).z)
               for e in sub.groups[c.group].reference.edge_ids()})
            for c in sub.configurations.values()],
        behaviors=[BehaviorModel(
            name=b.name, kind=b.kind, description=b.description, start=b.start,
            steps=list(b.steps), loop=b.loop, parameters=list(b.parameters),
            commands=[CommandSourceModel(module=c.module, command=c.command, connector=c.connector,
                                   gains=dict(c.gains)) for c in b.commands],
            drive_root=b.drive_root)
            for b in sub.behaviors.values()],
        edges=[EdgeModel(
            source=e.source, target=e.target, action=e.action,
            tree=TreeRefModel(group=e.tree.group, name=e.tree.name), cost=e.cost,
            mapping=None if e.mapping is None else MappingModel(**e.mapping.to_dict()),
            feasible=e.feasible) for e in sub.edges],
    )


def library_to_model(library: Library) -> LibraryFile:
    """The file model of ``library``."""
    return LibraryFile(schema_version=LIBRARY_SCHEMA_VERSION, robot=library.robot,
                       name=library.name, description=library.description,
                       build=library.build,
                       sublibraries=[_sublibrary_to_model(s)
                                     for s in library.sublibraries.values()])


def dump_library(library: Library) -> str:
    """The JSON text of ``library`` (stable: the same library gives the same text)."""
    data = library_to_model(library).model_dump(mode="json")
    return json.dumps(data, indent=1) + "\n"


def save_library(library: Library, path: str | os.PathLike[str]) -> None:
    """Write ``library`` to ``path`` atomically (temporary file, then rename)."""
    atomic_write_text(path, dump_library(library))


def load_library(path: str | os.PathLike[str],
                 robot: Robot | Callable[[str], Robot] | None = None) -> Library:
    """Read and validate a library file (:func:`library_from_model`; ``robot`` adds the
    checks against the robot; it may be a function giving the robot of the name the
    file holds, as :func:`msrr.core.plugins.load_library` passes).

    Raises:
        LibraryError: missing file, bad or truncated JSON, a wrong field, a broken
            cross-reference or rule; the message names the file and the field.
    """
    source = str(path)
    model = read_model(LibraryFile, path)
    if robot is not None and not isinstance(robot, Robot):
        robot = robot(model.robot)
    return library_from_model(model, source, robot)

