"""SnailBot in the MuJoCo freeform world (:mod:`msrr.core.freeform`).

A SnailBot's body carries its crawling foot rigidly: docked on a substrate it turns
about the substrate's centre in all three directions (the spherical joint,
:class:`~msrr.plugins.snailbot.joints.SphericalJoint`); its vacuum sucker pins the
contact point, leaving only the turn about the sucker axis
(:class:`~msrr.plugins.snailbot.joints.SuckerRevoluteJoint`), whose controller engages it.
"""

from __future__ import annotations

from typing import Any

from msrr.core.freeform import ContactController, ContactRecognizer, FreeformDriver, ModuleDesign

from .joints import JOINT_MODES, SuckerRevoluteJoint
from .robot import MODULE, SPEC

__all__ = ["DESIGN", "SnailBotMujocoDriver", "controllers", "recognizer"]

DESIGN = ModuleDesign.from_spec(SPEC, MODULE.name, bearing=False, sucker=True,
                                rgba=(0.85, 0.6, 0.25, 1.0))
"""The simulated SnailBot module (geometry from the robot description)."""


class SnailBotMujocoDriver(FreeformDriver):
    """SnailBot modules in MuJoCo (see :class:`~msrr.core.freeform.FreeformDriver`)."""

    name = "mujoco"
    description = "MuJoCo: shells with a foot on a drive about the substrate's centre, sucker"

    def __init__(self, **options: Any):
        super().__init__(DESIGN, **options)


def recognizer() -> ContactRecognizer:
    """The SnailBot recognizer (registered as ``snailbot``)."""
    return ContactRecognizer(SPEC.name, MODULE.name)


def controllers() -> list[ContactController]:
    """One controller per joint mode, named as the mode's ``controller``; the
    sucker-revolute one engages the sucker."""
    shared = recognizer()
    return [ContactController(mode.controller, shared, sucker=mode is SuckerRevoluteJoint)
            for mode in JOINT_MODES]


DRIVER = SnailBotMujocoDriver
"""What the plugin registers as the ``mujoco`` driver."""
