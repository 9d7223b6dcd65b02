"""Hook implementations of the SnailBot robot plugin, built by the freeform family's
factory (:class:`msrr.core.freeform.FreeformPlugin`) from what is SnailBot's own: its
module (``robot.json``), the crawling and sucker joints (``joints``) and the chain and
tree scenarios (``scenarios``).

Simulated, a SnailBot's body carries its crawling foot rigidly: docked on a substrate
it turns about the substrate's centre in all three directions (the spherical joint,
:class:`~msrr.plugins.snailbot.joints.SphericalJoint`); its vacuum sucker pins the
contact point, leaving only the turn about the sucker axis
(:class:`~msrr.plugins.snailbot.joints.SuckerRevoluteJoint`), whose controller engages it.

The command line loads this module on every ``--help``, so it imports the factory alone;
the hooks import the robot's parts and the simulator when called.
"""

from __future__ import annotations

from msrr.core.freeform.plugin import FreeformPlugin

__all__ = ["plugin"]

plugin = FreeformPlugin(
    __name__, sucker="sucker_revolute", rgba=(0.85, 0.6, 0.25, 1.0),
    driver_description="MuJoCo: shells with a foot on a drive about the substrate's centre, sucker")
"""The plugin; its hooks are this module's too, so the entry point may name either
(``msrr.plugins.snailbot.plugin`` or ``msrr.plugins.snailbot.plugin:plugin``)."""

globals().update(plugin.hooks())
