"""SnailBot: freeform modules that crawl on each other with one magnetic connector.

Zhao and Lam 2022; Zhao et al. 2024; kinematics as in the freeform autonomy framework.

The robot is ``robot.SPEC``; the package imports nothing, so loading the plugin
(on every command's ``--help``) stays cheap.
"""
