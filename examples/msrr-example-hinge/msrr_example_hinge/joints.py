"""The hinge's joint mode, imported by the ``msrr_kinematic_nodes`` hook only (the
kinematics import scipy, which ``platform --help`` must not load)."""

from msrr.core.kinematics.joints import RevoluteJoint


class HingeJoint(RevoluteJoint):
    """The hinge turns about its connection axis ``z`` by ``sigma`` [rad]."""

    name = "hinge"
    controller = "hinge"
