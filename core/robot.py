"""Robot descriptions: module kinds, their ports and geometry, robot-wide defaults,
and docking rules.

A robot plugin answers ``msrr_robot()`` with a :class:`RobotSpec` (its defaults a
typed :class:`RobotDefaults`) and ``msrr_docking_rules(robot)`` with a
:class:`DockingRules`. The core reads both to validate configurations, name
sub-libraries and build simulations, and never imports a plugin by name.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal

from .errors import PluginError, UnknownNameError

if TYPE_CHECKING:  # a plugin builds its RobotSpec when it loads, on every --help: no graphs
    from .configuration import Configuration

__all__ = [
    "DEFAULT_HALF_SIZE",
    "Body",
    "DockTolerance",
    "DockingRules",
    "Hinge",
    "Robot",
    "MisoRules",
    "ModuleKind",
    "PortSpec",
    "RobotDefaults",
    "RobotSpec",
    "ShapeTolerance",
    "Violation",
    "Wheels",
    "body_half_size",
    "check_structure",
    "out_degree_violations",
    "port_reuse_violations",
    "tree_violations",
    "vector_violations",
]

PortRole = Literal["active", "passive", "neutral"]
PORT_ROLES: tuple[str, ...] = ("active", "passive", "neutral")
"""Every port role; any other is refused when the description loads."""
BodyShape = Literal["box", "sphere", "capsule", "cylinder"]
BODY_SIZES: Mapping[str, tuple[str, ...]] = {
    "box": ("length", "width", "height"), "sphere": ("radius",),
    "capsule": ("radius", "length"), "cylinder": ("radius", "length")}
"""The sizes [m] each body shape takes, in order (a capsule's and a cylinder's
``length`` is that of their axis, the module's x axis, without the capsule's caps)."""


def _vector(owner: str, name: str, value: object, *, unit: bool) -> tuple[float, float, float]:
    """``value`` as three finite floats (of norm 1 when ``unit``); else a one-line PluginError."""
    try:
        out = tuple(float(v) for v in value)  # type: ignore[union-attr]
    except (TypeError, ValueError):
        out = ()
    if len(out) != 3 or not all(math.isfinite(v) for v in out) or (
            unit and abs(math.sqrt(sum(v * v for v in out)) - 1.0) > 1e-6):
        what = "a unit vector (x, y, z)" if unit else "a point (x, y, z) [m]"
        raise PluginError(f"{owner}.{name} must be {what}, got {value!r}")
    return out  # type: ignore[return-value]


@dataclass(frozen=True)
class PortSpec:
    """A discrete docking port of a module kind (MMRP faces T/B/L/R, a FreeBOT magnet).

    Attributes:
        name: the label used in configuration files (``"T"``).
        role: ``"active"`` ports drive the latch, ``"passive"`` ones receive it;
            ``"neutral"`` ports (freeform connectors) have no gender.
        normal: outward unit normal in the module frame, shape (3,), if fixed.
    """

    name: str
    role: PortRole = "neutral"
    normal: tuple[float, float, float] | None = None
    position: tuple[float, float, float] | None = None
    up: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        owner = f"PortSpec {self.name!r}"
        if self.role not in PORT_ROLES:
            raise PluginError(f"{owner}.role must be one of {', '.join(PORT_ROLES)}, "
                              f"got {self.role!r}")
        for name, unit in (("normal", True), ("position", False), ("up", True)):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, _vector(owner, name, value, unit=unit))
        if self.up is not None and (self.normal is None or abs(
                sum(a * b for a, b in zip(self.up, self.normal, strict=True))) > 1e-6):
            raise PluginError(f"{owner}.up must be perpendicular to its normal "
                              f"(normal {self.normal}, up {self.up})")


@dataclass(frozen=True, kw_only=True)
class Body:
    """The rigid body a module kind is simulated as (its frame: x forward, z up).

    Attributes:
        shape: ``"box"``, ``"sphere"``, ``"capsule"`` or ``"cylinder"`` (the last two
            along the module's x axis).
        size: the shape's sizes [m] (:data:`BODY_SIZES`): a box's length, width and
            height; a sphere's radius; a capsule's or cylinder's radius and length.
        mass: [kg], > 0.
        friction: sliding friction coefficient against the floor and other bodies.

    Raises:
        PluginError: an unknown shape, or sizes or mass that are not numbers > 0.
    """

    shape: BodyShape
    size: tuple[float, ...]
    mass: float
    friction: float = 0.8

    def __post_init__(self) -> None:
        names = BODY_SIZES.get(self.shape)
        if names is None:
            raise PluginError(f"Body.shape must be one of {', '.join(BODY_SIZES)}, "
                              f"got {self.shape!r}")
        if not isinstance(self.size, tuple | list) or len(self.size) != len(names):
            raise PluginError(f"Body.size of a {self.shape} is ({', '.join(names)}) [m], "
                              f"got {self.size!r}")
        object.__setattr__(self, "size", tuple(_positive(f"Body({self.shape})", n, v, "m")
                                               for n, v in zip(names, self.size, strict=True)))
        object.__setattr__(self, "mass", _positive("Body", "mass", self.mass, "kg"))
        object.__setattr__(self, "friction", _positive("Body", "friction", self.friction, "1"))

    @property
    def half_extents(self) -> tuple[float, float, float]:
        """Half extents [m] of the body's bounding box in the module frame."""
        if self.shape == "box":
            return tuple(v / 2 for v in self.size)  # type: ignore[return-value]
        r = self.size[0]
        if self.shape == "sphere":
            return r, r, r
        return self.size[1] / 2 + (r if self.shape == "capsule" else 0.0), r, r


@dataclass(frozen=True, kw_only=True)
class Wheels:
    """Differential drive: two wheels on the module's y axis under its body, driving it
    along its x axis on the floor (MMRP's modules), with frictionless casters fore and aft.

    Attributes:
        radius: wheel radius [m].
        track: distance between the two wheels [m].
        speed: largest wheel rim speed [m/s].
        torque: largest wheel torque [N m].
    """

    radius: float
    track: float
    speed: float = 0.2
    torque: float = 0.5

    def __post_init__(self) -> None:
        for name, unit in (("radius", "m"), ("track", "m"), ("speed", "m/s"),
                           ("torque", "N m")):
            object.__setattr__(self, name, _positive("Wheels", name, getattr(self, name), unit))


@dataclass(frozen=True, kw_only=True)
class Hinge:
    """A revolute joint at one port: a module docked there turns about ``axis`` (module
    frame, through the port's position), driven by a position servo of bounded torque.

    Attributes:
        port: the port the hinge is at.
        axis: unit axis in the module frame.
        torque: largest servo torque [N m].
        limit: the joint turns within ``[-limit, limit]`` [rad].
        speed: largest joint speed the servo commands [rad/s].
    """

    port: str
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    torque: float = 2.0
    limit: float = math.pi * 0.75
    speed: float = 1.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "axis", _vector("Hinge", "axis", self.axis, unit=True))
        for name, unit in (("torque", "N m"), ("limit", "rad"), ("speed", "rad/s")):
            object.__setattr__(self, name, _positive("Hinge", name, getattr(self, name), unit))


@dataclass(frozen=True)
class ModuleKind:
    """A kind of module a robot is built from.

    Attributes:
        name: identifier used in configuration files (``"node"``, ``"strut"``).
        symbol: one letter used in sub-library names (``"N"`` in ``S6N3``).
        role: ``"vertex"`` kinds are topology-graph vertices; ``"edge"`` kinds are
            modules drawn as edges (a FreeSN strut joins two node modules).
        ports: the discrete docking ports, empty for freeform surfaces.
        geometry: nominal dimensions in SI units (``radius`` [m], ``mass`` [kg], ...).
        description: one sentence for tables.
        commands: the commands a behavior may give a module of this kind (a library's
            ``commands[].command``, ``"wheel_speed"``); ``None``: not declared, any is
            accepted; ``()``: it takes none.
        body: the rigid body it is simulated as (``None``: no physics description);
            with it, each port with a ``normal`` gets a pose on it (``position`` and
            ``up`` of the :class:`PortSpec`, derived when not given).
        wheels: its differential drive (wheeled mobility), or ``None``.
        hinge: the revolute joint at one of its ports (jointed mobility), or ``None``.

    Raises:
        PluginError: a hinge at a port the kind does not have, wheels or a hinge without
            a body.
    """

    name: str
    symbol: str
    role: Literal["vertex", "edge"]
    ports: tuple[PortSpec, ...] = ()
    geometry: Mapping[str, float] = field(default_factory=dict)
    description: str = ""
    commands: tuple[str, ...] | None = None
    body: Body | None = None
    wheels: Wheels | None = None
    hinge: Hinge | None = None

    def __post_init__(self) -> None:
        if self.body is not None and not isinstance(self.body, Body):
            raise PluginError(f"ModuleKind {self.name!r}: body must be a Body, got {self.body!r}")
        if (self.wheels is not None or self.hinge is not None) and self.body is None:
            raise PluginError(f"ModuleKind {self.name!r}: wheels and a hinge need a body")
        if self.hinge is not None and self.hinge.port not in {p.name for p in self.ports}:
            raise PluginError(f"ModuleKind {self.name!r}: hinge at unknown port "
                              f"{self.hinge.port!r}")
        if self.body is not None and any(p.normal is None for p in self.ports):
            raise PluginError(f"ModuleKind {self.name!r}: with a body every port needs a normal")

    def port(self, name: str) -> PortSpec:
        """The port called ``name``; raises listing the known ports."""
        for port in self.ports:
            if port.name == name:
                return port
        raise UnknownNameError(f"port of module kind {self.name!r}", name, (p.name for p in self.ports))


DEFAULT_HALF_SIZE = 0.05
"""Half edge [m] of the cube a module kind is drawn and simulated as when its geometry
gives no size."""


def body_half_size(kind: ModuleKind) -> tuple[float, float, float]:
    """Half extents [m] of ``kind``'s body box, from ``kind.geometry``.

    ``length``/``width``/``height`` (a box, missing ones taken from the others) or
    ``radius`` (its bounding cube); :data:`DEFAULT_HALF_SIZE` when neither is given.
    The timeline draws this box and the generic kinematic driver simulates it.
    """
    if kind.body is not None:
        return kind.body.half_extents
    g = kind.geometry
    if "length" in g or "width" in g or "height" in g:
        length = float(g.get("length", g.get("width", g.get("height", 0.0))))
        width = float(g.get("width", length))
        height = float(g.get("height", min(length, width)))
        return length / 2, width / 2, height / 2
    r = float(g.get("radius", DEFAULT_HALF_SIZE))
    return r, r, r


def _positive(owner: str, name: str, value: object, unit: str) -> float:
    """``value`` as a float if it is a finite number > 0; else a one-line PluginError."""
    if (isinstance(value, bool) or not isinstance(value, int | float)
            or not math.isfinite(value) or value <= 0):
        raise PluginError(f"{owner}.{name} must be a finite number > 0 [{unit}], got {value!r}")
    return float(value)


def _flag(owner: str, name: str, value: object) -> None:
    if not isinstance(value, bool):
        raise PluginError(f"{owner}.{name} must be True or False, got {value!r}")


@dataclass(frozen=True, kw_only=True)
class ShapeTolerance:
    """How close a run's final module poses must come to the goal layout.

    :func:`msrr.core.shape.pose_errors` fits the final positions onto the goal layout
    (rotation about z and translation) and a run reaches the goal shape when every
    module is within both bounds.

    Attributes:
        position: largest position error of a module [m], > 0.
        heading: largest heading error of a module about z [rad], > 0.

    Raises:
        PluginError: a bound is not a finite number > 0 (the message names it).
    """

    position: float
    heading: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "position",
                           _positive("ShapeTolerance", "position", self.position, "m"))
        object.__setattr__(self, "heading",
                           _positive("ShapeTolerance", "heading", self.heading, "rad"))


@dataclass(frozen=True, kw_only=True)
class DockTolerance:
    """How well two ports must be aligned for their latch to hold, and so how closely
    the generic controller brings them together (physics drivers only).

    Attributes:
        position: largest distance between the two ports' positions [m], > 0.
        angle: largest angle between one port's normal and the other's reversed, and
            between their ``up`` vectors (a hinge port: between the hinge axes) [rad], > 0.

    Raises:
        PluginError: a bound is not a finite number > 0 (the message names it).
    """

    position: float = 0.01
    angle: float = 0.1

    def __post_init__(self) -> None:
        object.__setattr__(self, "position",
                           _positive("DockTolerance", "position", self.position, "m"))
        object.__setattr__(self, "angle", _positive("DockTolerance", "angle", self.angle, "rad"))


@dataclass(frozen=True, kw_only=True)
class RobotDefaults:
    """Robot-wide defaults, each read by one part of the core.

    Attributes:
        joint_mode: name of the module joint used where a kinematic tree names none
            (:meth:`Robot.default_joint_mode`); ``None``: the first registered joint
            mode of the ``module_joint`` family.
        shape_tolerance: the final-shape test of a run (:mod:`msrr.core.shape`,
            ``platform run``); ``None``: a run is judged on its topology alone.
        planar: the robot moves on the ground plane, so the timeline adds a top-down
            2-D view (:mod:`msrr.core.timeline.recorder`).
        stay_connected: every intermediate configuration of a plan must be one
            connected system (:class:`msrr.core.generic.planner.GenericPlanner`).
        dock_tolerance: the alignment a latch needs in a physics driver and the
            generic controller reaches (:class:`DockTolerance`).
        median_yaw: the executor's tracking steps hold their yaw at the edges' median
            turn instead of eq. 8's least squares
            (:func:`~msrr.core.kinematics.tracker.held_yaw`): the freeform robots, whose
            every module lies on the floor and whose commands already take the median
            turn out (:func:`~msrr.core.freeform.recognition.common_turn`).

    Raises:
        PluginError: a field has the wrong type (the message names it).
    """

    joint_mode: str | None = None
    shape_tolerance: ShapeTolerance | None = None
    planar: bool = False
    stay_connected: bool = False
    dock_tolerance: DockTolerance = field(default_factory=DockTolerance)
    median_yaw: bool = False

    def __post_init__(self) -> None:
        if not isinstance(self.dock_tolerance, DockTolerance):
            raise PluginError("RobotDefaults.dock_tolerance must be a DockTolerance("
                              f"position=m, angle=rad), got {self.dock_tolerance!r}")
        if self.joint_mode is not None and (not isinstance(self.joint_mode, str)
                                            or not self.joint_mode):
            raise PluginError("RobotDefaults.joint_mode must be a joint mode name or None, "
                              f"got {self.joint_mode!r}")
        if self.shape_tolerance is not None and not isinstance(self.shape_tolerance,
                                                               ShapeTolerance):
            raise PluginError("RobotDefaults.shape_tolerance must be a ShapeTolerance("
                              f"position=m, heading=rad) or None, got {self.shape_tolerance!r}")
        _flag("RobotDefaults", "planar", self.planar)
        _flag("RobotDefaults", "stay_connected", self.stay_connected)
        _flag("RobotDefaults", "median_yaw", self.median_yaw)


@dataclass(frozen=True)
class RobotSpec:
    """What a robot is made of: the answer to ``msrr_robot()``.

    Attributes:
        name: the robot's identifier (``"mmrp"``), used on the command line.
        title: human-readable name.
        module_kinds: kinds in the order used for sub-library names.
        description: one paragraph.
        reference: the paper or page the description follows.
        defaults: robot-wide defaults the core reads (default joint mode, shape
            tolerance, planar, stay connected): a :class:`RobotDefaults`.

    Raises:
        PluginError: ``defaults`` is not a :class:`RobotDefaults` (naming the robot).
    """

    name: str
    title: str
    module_kinds: tuple[ModuleKind, ...]
    description: str = ""
    reference: str = ""
    defaults: RobotDefaults = field(default_factory=RobotDefaults)

    def __post_init__(self) -> None:
        if not isinstance(self.defaults, RobotDefaults):
            raise PluginError(f"robot {self.name!r}: defaults must be a RobotDefaults "
                              f"(msrr.core.RobotDefaults), got {type(self.defaults).__name__}")

    def kind(self, name: str) -> ModuleKind:
        """The module kind called ``name``; raises listing the known kinds."""
        for kind in self.module_kinds:
            if kind.name == name:
                return kind
        raise UnknownNameError(f"module kind of robot {self.name!r}", name, self.kind_names)

    @property
    def kind_names(self) -> tuple[str, ...]:
        return tuple(k.name for k in self.module_kinds)

    def kinds_with_role(self, role: str) -> tuple[ModuleKind, ...]:
        return tuple(k for k in self.module_kinds if k.role == role)


@dataclass(frozen=True)
class Violation:
    """One broken rule: where (a field path or module id) and what."""

    where: str
    message: str

    def __str__(self) -> str:
        return f"{self.where}: {self.message}"


class DockingRules:
    """Which ports may connect and which topologies and actions are legal.

    Subclasses override :meth:`ports_compatible` and :meth:`check_topology`; the
    defaults allow everything. :meth:`check` runs both over a configuration.
    """

    robot: str = ""

    def ports_compatible(self, source_kind: str, source_port: str | None,
                         target_kind: str, target_port: str | None) -> bool:
        """Whether a connection from ``source_port`` to ``target_port`` may exist."""
        return True

    def check_topology(self, config: Configuration) -> list[Violation]:
        """Robot-specific topology rules (trees only, out-degree limits, ...)."""
        return []

    def check(self, config: Configuration) -> list[Violation]:
        """Every violation of these rules in ``config``, port pairs first."""
        found: list[Violation] = []
        for edge in config.edges():
            source_port, target_port = edge.ports if edge.ports else (None, None)
            if not self.ports_compatible(config.kind_of(edge.source), source_port,
                                         config.kind_of(edge.target), target_port):
                pair = f"{edge.source}{source_port or ''}-{edge.target}{target_port or ''}"
                found.append(Violation(f"connection {edge.id}",
                                       f"illegal port pair {pair}"))
        return found + self.check_topology(config)

    def check_action(self, before: Configuration, after: Configuration) -> list[Violation]:
        """Violations caused by going from ``before`` to ``after`` in one action."""
        return self.check(after)


@dataclass(frozen=True)
class Robot:
    """One robot as the core's pure layers need it, resolved from the plugins once.

    Kinematics, matching, library and file code receive this (or one of its fields)
    as an argument and never ask the plugin host; :func:`msrr.core.plugins.resolve`
    builds it from every installed plugin.

    Attributes:
        spec: module kinds, geometry and defaults (``msrr_robot``).
        rules: docking rules (``msrr_docking_rules``; permissive if none).
        joint_modes: kinematic node types by name (``msrr_kinematic_nodes``), always
            including ``"fixed"``; values are ``KinematicNode`` subclasses.
    """

    spec: RobotSpec
    rules: DockingRules = field(default_factory=lambda: DockingRules())
    joint_modes: Mapping[str, type] = field(default_factory=dict)

    @property
    def name(self) -> str:
        return self.spec.name

    def default_joint_mode(self) -> type:
        """The module joint used where a tree names none: ``spec.defaults.joint_mode``,
        else the first registered node type of the ``module_joint`` family."""
        name = self.spec.defaults.joint_mode
        if name is not None:
            if name not in self.joint_modes:
                raise UnknownNameError(f"joint mode for robot {self.name!r}", name,
                                       self.joint_modes)
            return self.joint_modes[name]
        for cls in self.joint_modes.values():
            if getattr(cls, "family", None) == "module_joint":
                return cls
        raise UnknownNameError(f"module joint mode for robot {self.name!r}", "(default)",
                               [n for n, c in self.joint_modes.items()
                                if getattr(c, "family", None) == "module_joint"])

    def violations(self, config: Configuration) -> list[Violation]:
        """Structural violations (:func:`check_structure`), else the docking rules', then
        the geometric consistency of described bodies
        (:func:`msrr.core.bodies.geometry_problems`)."""
        found = check_structure(config, self.spec) or self.rules.check(config)
        if found or not any(k.body is not None for k in self.spec.module_kinds):
            return found
        from .bodies import geometry_problems  # numpy: not on every plugin's load

        return [Violation(where, message) for where, message in
                geometry_problems(config, self.spec)]


def check_structure(config: Configuration, spec: RobotSpec) -> list[Violation]:
    """Violations of the robot's module kinds, independent of its docking rules.

    Every vertex kind must be a vertex kind of ``spec`` (or virtual); every edge kind
    an edge kind; robots with edge kinds need a kind on every edge; every port must
    exist on its module kind; a virtual vertex has exactly one connection.
    """
    found: list[Violation] = []
    vertex_kinds = {k.name for k in spec.kinds_with_role("vertex")}
    edge_kinds = {k.name for k in spec.kinds_with_role("edge")}
    if config.robot != spec.name:
        found.append(Violation("robot", f"is {config.robot!r}, expected {spec.name!r}"))
    for vertex in config.vertices():
        kind = config.kind_of(vertex)
        if config.is_virtual(vertex):
            if config.degree(vertex) != 1:
                found.append(Violation(f"module {vertex}", "a virtual vertex needs exactly one "
                                       f"connection, it has {config.degree(vertex)}"))
        elif kind not in vertex_kinds:
            found.append(Violation(f"module {vertex}", f"unknown module kind {kind!r} for "
                                   f"{spec.name} (known: {', '.join(sorted(vertex_kinds))})"))
    for edge in config.edges():
        where = f"connection {edge.id}"
        if edge_kinds and edge.kind is None:
            found.append(Violation(where, f"needs a module kind ({', '.join(sorted(edge_kinds))})"))
        elif edge.kind is not None and edge.kind not in edge_kinds:
            known = ", ".join(sorted(edge_kinds)) or "none: this robot's connections are not modules"
            found.append(Violation(where, f"unknown connection module kind {edge.kind!r} "
                                   f"(known: {known})"))
        if edge.ports is None:
            continue
        for end, port in zip((edge.source, edge.target), edge.ports, strict=True):
            kind = config.kind_of(end)
            if config.is_virtual(end) or kind not in vertex_kinds:
                continue
            names = {p.name for p in spec.kind(kind).ports}
            if port not in names:
                found.append(Violation(where, f"module {end} has no port {port!r} "
                                       f"(ports of {kind}: {', '.join(sorted(names)) or 'none'})"))
    return found


def tree_violations(config: Configuration) -> list[Violation]:
    """Violations of "the topology is one tree" (connected, no cycle, no parallel edge)."""
    import networkx as nx  # for the message only; robot descriptions load without it

    if len(config) == 0:
        return [Violation("modules", "a configuration needs at least one module")]
    found = []
    if not config.is_connected():
        parts = sorted(sorted(c) for c in nx.weakly_connected_components(config.graph))
        found.append(Violation("connections", f"the modules form {len(parts)} separate groups "
                               f"({'; '.join(' '.join(p) for p in parts)}), expected one tree"))
    elif len(config.edges()) != len(config) - 1:
        cycle = nx.find_cycle(config.undirected())
        loop = " - ".join(str(step[0]) for step in cycle)
        found.append(Violation("connections", f"closed loop {loop}: the topology must be a tree "
                               "(make one loop edge a virtual connection)"))
    return found


def out_degree_violations(config: Configuration, limit: int) -> list[Violation]:
    """Modules with more than ``limit`` outgoing connections (one connector each)."""
    return [Violation(f"module {v}", f"has {config.graph.out_degree(v)} out-connections, at most "
                      f"{limit} allowed (it has {limit} connector{'s' if limit > 1 else ''})")
            for v in config.vertices(virtual=False) if config.graph.out_degree(v) > limit]


def port_reuse_violations(config: Configuration) -> list[Violation]:
    """Ports used by more than one connection of the same module."""
    used: dict[tuple[str, str], str] = {}
    found = []
    for edge in config.edges():
        if edge.ports is None:
            continue
        for end, port in zip((edge.source, edge.target), edge.ports, strict=True):
            if (end, port) in used:
                found.append(Violation(f"connection {edge.id}", f"port {port} of module {end} is "
                                       f"already used by connection {used[end, port]}"))
            used[end, port] = edge.id
    return found


def vector_violations(config: Configuration, attribute: str = "z") -> list[Violation]:
    """Connections that lack the ``z`` (or ``x``) vector a freeform robot needs."""
    return [Violation(f"connection {e.id}", f"needs a unit {attribute} vector")
            for e in config.edges() if getattr(e, attribute) is None]


class MisoRules(DockingRules):
    """Rules of MISO robots (multiple in-degree, single out-degree: FreeBOT, SnailBot).

    Each module has one freeform connector: it makes at most one out-connection,
    onto any point of another module's surface (so no discrete ports), and every
    connection carries its vector ``z``. The topology therefore holds at most one
    cycle per connected group.
    """

    def __init__(self, robot: str):
        self.robot = robot

    def ports_compatible(self, source_kind: str, source_port: str | None,
                         target_kind: str, target_port: str | None) -> bool:
        return source_port is None and target_port is None

    def check_topology(self, config: Configuration) -> list[Violation]:
        return out_degree_violations(config, 1) + vector_violations(config, "z")
