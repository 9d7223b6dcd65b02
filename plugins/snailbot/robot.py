"""The SnailBot module (freeform paper section 2.1, Fig. 1b, Fig. 4b).

A module moves on another module's surface with a large contact area (a spherical
joint) through magnet-embedded rocker-bogie suspension or tracks, and can lock the
connection with a vacuum sucker, leaving one revolute degree of freedom about the
sucker. One connector, so at most one out-connection. Geometry is nominal.
"""

from __future__ import annotations

from msrr.core import ModuleKind, PortSpec, RobotDefaults, RobotSpec

MODULE = ModuleKind(
    name="snailbot",
    symbol="B",
    role="vertex",
    ports=(PortSpec("foot"),),
    # [m], [kg], [kg], [rad/s] about the substrate's centre, [N m] crawling torque limit
    geometry={"radius": 0.05, "mass": 0.35, "connector_mass": 0.1, "max_speed": 0.3,
              "max_torque": 2.0},
    description="shell with a magnetic crawling foot and a vacuum sucker",
)

SPEC = RobotSpec(
    name="snailbot",
    title="SnailBot",
    module_kinds=(MODULE,),
    description=(
        "Freeform modules that crawl over each other's shells with a magnetic foot "
        "(spherical joint) and can lock with a sucker (revolute joint)."
    ),
    reference="Zhao and Lam 2022; Zhao et al. 2024",
    defaults=RobotDefaults(joint_mode="spherical"),
)
