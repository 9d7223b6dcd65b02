"""A single-connector freeform robot's description, and its module's design in the simulator.

* :func:`freeform_robot` -- the :class:`~msrr.core.robot.RobotSpec` of such a robot: one
  module kind, a vertex with one neutral connector, the geometry the MuJoCo world needs;
  :func:`read_freeform_robot` reads its arguments from a robot's ``robot.json``;
* :func:`read_miso_rules` -- the robot's MISO connection rules from the same file
  (``miso``: ``max_in``, ``no_docking_onto``, ``carries``), which its planners obey;
* :class:`ModuleDesign` -- the simulated module: that geometry, and whether the connector
  turns in a bearing inside the shell (FreeBOT) and whether there is a sucker (SnailBot).

Imports nothing heavy (a plugin reads its description on every ``--help``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from ..errors import ExecutionError, PluginError
from ..robot import ModuleKind, PortSpec, RobotDefaults, RobotSpec

__all__ = ["DESIGN_GEOMETRY", "MISO_RULES", "ModuleDesign", "freeform_robot", "read_freeform_robot",
           "read_miso_rules"]

DESIGN_GEOMETRY = ("radius", "mass", "connector_mass", "max_speed", "max_torque",
                   "connection_strength")
"""The module geometry the MuJoCo world is built from (:func:`freeform_robot`)."""


def freeform_robot(*, name: str, title: str, symbol: str, port: str, joint_mode: str,
                   geometry: Mapping[str, float], module: str, description: str,
                   reference: str) -> RobotSpec:
    """The description of a single-connector freeform robot: one module kind, a vertex
    with one neutral connector (it docks anywhere on another module and makes at most
    one out-connection, :class:`~msrr.core.robot.MisoRules`).

    Args:
        name: the robot's name, also its module kind's.
        title: the robot's display name.
        symbol: the module kind's letter in sub-library names.
        port: the connector's port name (a command's ``dock=(port,)``).
        joint_mode: the default joint mode.
        geometry: at least ``radius`` (shell) [m], ``mass`` (the whole module) [kg],
            ``connector_mass`` (the part carrying the connector, within ``mass``) [kg],
            ``max_speed`` (fastest turn about the parent's centre) [rad/s],
            ``max_torque`` (drive torque limit) [N m] and ``connection_strength`` (the
            pull-off and shear force the connector holds) [N]: what the MuJoCo world is
            built from; optionally ``sucker_strength`` [N], what an engaged sucker adds.
        module: the module kind's one-line description.
        description: the robot's description.
        reference: where the robot is published.

    Raises:
        PluginError: a geometry value the world needs is missing or not a number > 0.
    """
    for key in DESIGN_GEOMETRY:
        value = geometry.get(key)
        if isinstance(value, bool) or not isinstance(value, int | float) or not value > 0:
            raise PluginError(f"robot {name!r}: geometry {key!r} must be a number > 0, got "
                              f"{value!r} (the MuJoCo world needs {', '.join(DESIGN_GEOMETRY)})")
    kind = ModuleKind(name=name, symbol=symbol, role="vertex", ports=(PortSpec(port),),
                      geometry=dict(geometry), description=module)
    defaults = RobotDefaults(joint_mode=joint_mode, median_yaw=True)
    return RobotSpec(name=name, title=title, module_kinds=(kind,), description=description,
                     reference=reference, defaults=defaults)


def read_freeform_robot(text: str, where: str) -> RobotSpec:
    """The robot described by the JSON object ``text`` (the arguments of
    :func:`freeform_robot`), read from ``where``.

    Raises:
        PluginError: not a JSON object, a field missing, unknown or of the wrong type (the
            message names ``where`` and the field).
    """
    import json

    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise PluginError(f"{where}: not JSON ({exc})") from None
    if not isinstance(data, dict):
        raise PluginError(f"{where}: expected a JSON object with {', '.join(_FIELDS)}")
    problems = [f"missing {key}" for key in _FIELDS if key not in data]
    problems += [f"unknown {key}" for key in sorted(set(data) - set(_FIELDS))]
    problems += [f"{key} must be a {'JSON object' if key in _OBJECTS else 'string'}, got "
                 f"{data[key]!r}" for key in _FIELDS
                 if key in data and not isinstance(data[key], dict if key in _OBJECTS else str)]
    if problems:
        raise PluginError(f"{where}: {'; '.join(problems)} (fields: {', '.join(_FIELDS)})")
    try:
        return freeform_robot(**{k: v for k, v in data.items() if k != "miso"})
    except PluginError as exc:
        raise PluginError(f"{where}: {exc}") from None


MISO_RULES = {"max_in": "the most connections one module carries (an integer >= 1, or null: "
                        "no limit)",
              "no_docking_onto": "'child' (never onto a module sitting on it) or "
                                 "'descendant' (never onto its own in-tree: no cycle)",
              "carries": "what a docking module takes along: 'in-tree' (every module "
                         "docked on it: pieces travel) or 'nothing' (only a module nothing "
                         "is docked on docks)"}
"""The fields of ``robot.json``'s ``miso`` object and what each holds."""


def read_miso_rules(text: str, where: str) -> dict[str, int | str | None]:
    """The MISO connection rules of the robot described by ``text`` (its ``miso``
    object: :data:`MISO_RULES`), the arguments of
    :class:`msrr.core.freeform.miso.MisoLimits`.

    Raises:
        PluginError: ``miso`` missing or not an object, a field missing, unknown or of
            the wrong value (the message names ``where`` and the field).
    """
    import json

    rules = json.loads(text).get("miso")
    if not isinstance(rules, dict):
        raise PluginError(f"{where}: miso must be a JSON object with "
                          f"{', '.join(MISO_RULES)}, got {rules!r}")
    problems = [f"missing miso.{key}" for key in MISO_RULES if key not in rules]
    problems += [f"unknown miso.{key}" for key in sorted(set(rules) - set(MISO_RULES))]
    cap = rules.get("max_in")
    if "max_in" in rules and cap is not None and (isinstance(cap, bool)
                                                  or not isinstance(cap, int) or cap < 1):
        problems.append(f"miso.max_in must be {MISO_RULES['max_in']}, got {cap!r}")
    rule = rules.get("no_docking_onto")
    if "no_docking_onto" in rules and rule not in ("child", "descendant"):
        problems.append(f"miso.no_docking_onto must be {MISO_RULES['no_docking_onto']}, "
                        f"got {rule!r}")
    carries = rules.get("carries")
    if "carries" in rules and carries not in ("in-tree", "nothing"):
        problems.append(f"miso.carries must be {MISO_RULES['carries']}, got {carries!r}")
    if problems:
        raise PluginError(f"{where}: {'; '.join(problems)}")
    return {"max_in": cap, "no_docking_onto": rule, "carries": carries}


_FIELDS = ("name", "title", "symbol", "port", "joint_mode", "geometry", "module",
           "description", "reference", "miso")
"""The fields of a freeform robot's ``robot.json``, in their order."""

_OBJECTS = ("geometry", "miso")
"""The fields that hold JSON objects."""


@dataclass(frozen=True)
class ModuleDesign:
    """The physical module of one robot.

    Attributes:
        robot: robot name. kind: module kind name. radius: shell radius [m]. mass: whole module [kg].
        connector_mass: the connector body (magnet and drive, FreeBOT) [kg].
        max_rate: fastest turn about the parent's centre [rad/s].
        max_torque: drive torque limit [N m].
        strength: the force a connection holds before it breaks (pull-off and shear) [N].
        sucker_strength: what an engaged sucker adds to it [N].
        bearing: the connector turns freely inside the shell (FreeBOT).
        sucker: the module has a vacuum sucker (SnailBot).
        rgba: shell colour.
    """

    robot: str
    kind: str
    radius: float
    mass: float
    connector_mass: float
    max_rate: float
    max_torque: float
    strength: float
    sucker_strength: float
    bearing: bool
    sucker: bool
    rgba: tuple[float, float, float, float] = (0.6, 0.6, 0.65, 1.0)

    @classmethod
    def from_spec(cls, spec: RobotSpec, kind: str, *, bearing: bool, sucker: bool,
                  rgba: tuple[float, float, float, float] = (0.6, 0.6, 0.65, 1.0)
                  ) -> ModuleDesign:
        """Read :data:`DESIGN_GEOMETRY` (and ``sucker_strength``, 0 when absent) from the
        kind's geometry; an error names the missing key."""
        geometry = spec.kind(kind).geometry
        for key in DESIGN_GEOMETRY:
            if key not in geometry:
                raise ExecutionError(f"robot {spec.name!r}: module kind {kind!r} has no "
                                     f"geometry {key!r}, which the MuJoCo world needs")
        g = {k: float(v) for k, v in geometry.items()}
        return cls(spec.name, kind, g["radius"], g["mass"], g["connector_mass"], g["max_speed"],
                   g["max_torque"], g["connection_strength"], g.get("sucker_strength", 0.0),
                   bearing, sucker, rgba)
