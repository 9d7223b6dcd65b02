"""The application wing: everything that asks the plugin host.

The command line (:mod:`.cli`, :mod:`.commands`, :mod:`.launch`), run orchestration
(:mod:`.run`), batch work (:mod:`.batch`), library feasibility checks
(:mod:`.feasibility`) and the conformance suite (:mod:`.testing`). These resolve a
robot's capabilities once, through :mod:`msrr.core.plugins`, and hand them down; the
layers below never import the host (``tests/core/test_layers.py``).
"""
