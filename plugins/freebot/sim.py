"""FreeBOT in the MuJoCo freeform world (:mod:`msrr.core.freeform`).

A FreeBOT is a steel shell around a magnet and drive unit that turns freely inside it
(``bearing``): docked on another module, the drive turns the module about that
module's centre while the magnet stays pointed at it -- the SRC joint's motion
(:class:`~msrr.plugins.freebot.joints.RollingContactJoint`); a flow slides the magnet
over the seam onto a neighbouring sphere.
"""

from __future__ import annotations

from typing import Any

from msrr.core.freeform import ContactController, ContactRecognizer, FreeformDriver, ModuleDesign

from .joints import JOINT_MODES
from .robot import MODULE, SPEC

__all__ = ["DESIGN", "FreeBOTMujocoDriver", "controllers", "recognizer"]

DESIGN = ModuleDesign.from_spec(SPEC, MODULE.name, bearing=True, sucker=False,
                                rgba=(0.62, 0.64, 0.7, 1.0))
"""The simulated FreeBOT module (geometry from the robot description)."""


class FreeBOTMujocoDriver(FreeformDriver):
    """FreeBOT modules in MuJoCo (see :class:`~msrr.core.freeform.FreeformDriver`)."""

    name = "mujoco"
    description = "MuJoCo: steel spheres, magnets on a drive about the parent's centre, welds"

    def __init__(self, **options: Any):
        super().__init__(DESIGN, **options)


def recognizer() -> ContactRecognizer:
    """The FreeBOT recognizer (registered as ``freebot``)."""
    return ContactRecognizer(SPEC.name, MODULE.name)


def controllers() -> list[ContactController]:
    """One controller per joint mode, named as the mode's ``controller``."""
    shared = recognizer()
    return [ContactController(mode.controller, shared) for mode in JOINT_MODES]


DRIVER = FreeBOTMujocoDriver
"""What the plugin registers as the ``mujoco`` driver."""
