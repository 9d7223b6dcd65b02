"""FreeBOT: spherical freeform modules with one internal magnet connector.

Liang et al., "FreeBOT: A Freeform Modular Self-Reconfigurable Robot with Arbitrary
Connection Point", IROS 2020; kinematics as in the freeform autonomy framework.

The robot is ``robot.SPEC``; the package imports nothing, so loading the plugin
(on every command's ``--help``) stays cheap.
"""
