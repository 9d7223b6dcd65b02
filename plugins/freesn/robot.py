"""FreeSN modules (paper section 2.1, Fig. 2).

A node module is a low-carbon-steel sphere; a strut module has two symmetric
magnetic connectors, each a magnet array with two wheels forming a differential
drive that moves on a node's surface (a spherical joint). In the topology graph
node modules are vertices and struts are edges; a free strut end is a virtual
vertex.

Where each figure comes from (docs/freesn.md, "Hardware parameters and their
sources"): [P] the autonomy-framework paper; [F] the FreeSN strut firmware (the
first commit, 6ec7c74, of the public repository d0h0s/snailbot_esp32, which imports
it). No source reachable here gives the modules' sizes, masses, torques or
connection strength: those are assumptions, set per lab in ``geometry``.
"""

from __future__ import annotations

from msrr.core import ModuleKind, PortSpec, RobotDefaults, RobotSpec

STRUT = ModuleKind(
    name="strut",
    symbol="S",
    role="edge",
    ports=(PortSpec("a"), PortSpec("b")),
    geometry={  # sources: docs/freesn.md, "Hardware parameters and their sources"
        "length": 0.20,          # node centre to node centre when both ends dock [m]; assumed
        "radius": 0.02,          # body radius [m]; assumed
        "mass": 0.30,            # [kg]; assumed
        # per wheel radian [F] rolls 0.1715 rad about the node centre and turns 0.3673 rad
        # about the strut axis, these 0.24 and 0.51: the radius assumed, the base from the
        # firmware's ratio b / 2R = 0.17151 / 0.36727 on our node (see the doc)
        "wheel_radius": 0.012,   # connector wheel radius [m]
        "wheel_base": 0.0467,  # distance between a connector's two wheels [m]
        "max_wheel_speed": 6.0,  # [rad/s]; [F] bounds its wheels at 2.25 (kept, see the doc)
        # assumed: the hardware's (the simulation takes less: torque_factor, strength_factor)
        "max_torque": 2.0,       # connector drive torque about the node centre, hardware [N m]
        "connection_strength": 40.0,  # magnetic pull-off force of a connector, hardware [N]
        "dock_tolerance": 0.02,  # extended magnet: gap to a node surface within which it pulls [m]; assumed
        "connector_mass": 0.03,  # magnet array, wheels and motors of one connector [kg]; assumed
    },
    description="two magnetic differential-drive connectors, one at each end",
    # [rad/s] of one connector's wheel pair; its node's travel (sim/commands.py)
    commands=("wheel_speed", "travel_along", "travel_across"),
)

NODE = ModuleKind(
    name="node",
    symbol="N",
    role="vertex",
    geometry={"radius": 0.05, "mass": 0.20},  # assumptions (no source gives them)
    description="steel sphere that struts connect to anywhere on its surface",
    commands=(),
)

SPEC = RobotSpec(
    name="freesn",
    title="FreeSN",
    module_kinds=(STRUT, NODE),
    description=(
        "Freeform truss robot: struts whose magnetic connectors roll on spherical node "
        "modules as spherical joints; skeletal kinematics, library-driven locomotion "
        "and self-reconfiguration."
    ),
    reference="Tu, Liang, Wu, Li and Lam (2025), freeform autonomy framework",
    defaults=RobotDefaults(joint_mode="opposite_steering"),
)
