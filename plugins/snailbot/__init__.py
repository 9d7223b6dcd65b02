"""SnailBot: freeform modules that crawl on each other with one magnetic connector.

Zhao and Lam 2022; Zhao et al. 2024; kinematics as in the freeform autonomy framework.

A module (freeform paper section 2.1, Fig. 1b, Fig. 4b) moves on another module's
surface with a large contact area (a spherical joint) through magnet-embedded
rocker-bogie suspension or tracks, and can lock the connection with a vacuum sucker,
leaving one revolute degree of freedom about the sucker (:mod:`.joints`). One
connector, so at most one out-connection. Its description is ``robot.json`` (nominal
geometry; the fields: :func:`msrr.core.freeform.plugin.freeform_robot`), registered by
:mod:`.plugin` with what every single-connector robot has. Importing the package imports
nothing: the command line loads the plugin on every ``--help``.
"""
