"""The MMRP module: a tracked mobile robot with four docking faces (paper section 2).

Faces: Top (front, active), Right (active), Bottom (back, passive), Left (passive).
Module frame: x forward (through T), y to the left (through L), z up.
Geometry is nominal (the paper gives none); set per lab in ``geometry``.
"""

from __future__ import annotations

from msrr.core import ModuleKind, PortSpec, RobotDefaults, RobotSpec, ShapeTolerance

FACES = (
    PortSpec("T", "active", (1.0, 0.0, 0.0)),
    PortSpec("B", "passive", (-1.0, 0.0, 0.0)),
    PortSpec("L", "passive", (0.0, 1.0, 0.0)),
    PortSpec("R", "active", (0.0, -1.0, 0.0)),
)

MODULE = ModuleKind(
    name="mmrp",
    symbol="M",
    role="vertex",
    ports=FACES,
    geometry={
        "length": 0.20,        # body along x [m]
        "width": 0.20,         # body along y [m]
        "height": 0.10,        # [m]
        "pitch": 0.30,         # centre-to-centre distance of two docked modules [m]
        "mass": 1.5,           # [kg]
        "max_speed": 0.15,     # track speed [m/s]
        "dock_tolerance": 0.01,  # lateral misalignment the cam-ball latch accepts [m]
    },
    description="tracked module; faces T,R active and B,L passive; T-B and L-R pairs only",
)

SPEC = RobotSpec(
    name="mmrp",
    title="MMRP",
    module_kinds=(MODULE,),
    description=(
        "Modular Mobile Reconfigurable Platform: each module is a tracked mobile robot "
        "with four cam-ball docking faces; configurations are trees planned by MCS "
        "decomposition and potential-field mapping of free modules."
    ),
    reference="Wei et al., Sensors 23 (2023) 7892",
    defaults=RobotDefaults(
        planar=True,  # moves on the ground plane: the timeline adds a top view
        # final module poses against the goal layout: two lateral latch windows [m],
        # one angular latch window [rad] (msrr.core.shape)
        shape_tolerance=ShapeTolerance(position=0.02, heading=0.06),
    ),
)
