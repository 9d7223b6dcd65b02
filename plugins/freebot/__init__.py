"""FreeBOT: spherical freeform modules with one internal magnet connector.

Liang et al., "FreeBOT: A Freeform Modular Self-Reconfigurable Robot with Arbitrary
Connection Point", IROS 2020; kinematics as in the freeform autonomy framework.

The module (freeform paper section 2.1, Fig. 1a, Fig. 4a) is a low-carbon-steel
spherical shell with an internal magnet and driving mechanism: the magnet connects to
any point of another module's surface and rolls on it (a spherical rolling-contact
joint, :mod:`.joints`). One connector, so at most one out-connection. ``robot.json``
describes it (geometry nominal, set per lab; fields and units:
:func:`msrr.core.freeform.plugin.freeform_robot`); :mod:`.plugin` registers it with the
freeform family's capabilities. The package imports nothing, so loading the plugin (on
every command's ``--help``) stays cheap.
"""
