"""Hook implementations of the FreeBOT robot plugin: the single-connector family's
(:class:`msrr.core.freeform.FreeformPlugin`) with FreeBOT's parts -- ``robot.json``,
the rolling-contact joint (``joints``) and the row-to-star scenarios (``scenarios``).

In the simulator a FreeBOT is a steel shell around a magnet and drive unit that turns
freely inside it (``bearing``): docked on another module, the drive turns the module
about that module's centre while the magnet stays pointed at it -- the SRC joint's
motion (:class:`~msrr.plugins.freebot.joints.RollingContactJoint`); a flow slides the
magnet over the seam onto a neighbouring sphere, and a free FreeBOT rolls on the ground.

Loaded by the command line on every ``--help``: the module imports only the factory;
each hook imports what it answers with when it is called.
"""

from __future__ import annotations

from msrr.core.freeform.plugin import FreeformPlugin

__all__ = ["plugin"]

plugin = FreeformPlugin(
    __name__, bearing=True, bends=True, rgba=(0.62, 0.64, 0.7, 1.0),
    driver_description="MuJoCo: steel spheres, magnets on a drive about the parent's centre, welds")
"""The plugin; its hooks are this module's too, so the entry point may name either
(``msrr.plugins.freebot.plugin`` or ``msrr.plugins.freebot.plugin:plugin``)."""

globals().update(plugin.hooks())
