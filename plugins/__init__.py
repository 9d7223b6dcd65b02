"""msrr.plugins: the built-in robot plugins (freesn, mmrp, freebot, snailbot).

Each registers through the ``msrr.plugins`` entry-point group like any
third-party plugin; the core never imports them by name.
"""
