"""FreeSN: freeform modular robot of spherical node modules and two-connector struts.

Tu et al., "Locomotion and Self-reconfiguration Autonomy for Spherical Freeform
Modular Robots" (2025); hardware: Tu et al. 2022, Tu and Lam 2023.

The robot is ``robot.SPEC``; the package imports nothing, so loading the plugin
(on every command's ``--help``) stays cheap.
"""
