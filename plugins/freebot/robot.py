"""The FreeBOT module (freeform paper section 2.1, Fig. 1a, Fig. 4a).

A low-carbon-steel spherical shell with an internal magnet and driving mechanism:
the magnet connects to any point of another module's surface and rolls on it (a
spherical rolling-contact joint). One connector, so at most one out-connection.
Geometry is nominal; set per lab in ``geometry``.
"""

from __future__ import annotations

from msrr.core import ModuleKind, PortSpec, RobotDefaults, RobotSpec

MODULE = ModuleKind(
    name="freebot",
    symbol="F",
    role="vertex",
    ports=(PortSpec("magnet"),),
    # [m], [kg], [kg], [rad/s] about the parent's centre, [N m] drive torque limit
    geometry={"radius": 0.05, "mass": 0.25, "connector_mass": 0.1, "max_speed": 0.5,
              "max_torque": 1.5},
    description="steel sphere; internal magnet rolls on any point of another module",
)

SPEC = RobotSpec(
    name="freebot",
    title="FreeBOT",
    module_kinds=(MODULE,),
    description=(
        "Spherical freeform modules whose internal magnet connects anywhere on another "
        "module and rolls on it; topologies hold at most one cycle."
    ),
    reference="Liang et al., IROS 2020",
    defaults=RobotDefaults(joint_mode="rolling_contact"),
)
