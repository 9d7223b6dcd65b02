"""FreeSN simulation in MuJoCo (paper sections 2.1, 4.1-4.2, 6.2).

* :mod:`.options` -- :class:`SimOptions` (per run) and the physical figures they give;
* :mod:`.geometry` -- pure maths: placing a configuration, horizontal frames;
* :mod:`.world` -- the MuJoCo world built with ``MjSpec``: nodes, struts, motor-driven
  spherical joints, docking welds, breaks, module reports;
* :mod:`.commands` -- the joint names of a strut's command;
* :mod:`.recognizer` -- configuration identification from the reports (``freesn``);
* :mod:`.controller` -- joint vectors -> per-connector commands (``freesn.<mode>``);
* :mod:`.driver` -- the :class:`~msrr.core.driver.Driver` registered as ``mujoco``.
"""

from .controller import (
    FOLLOW_EFFORT,
    FORWARD_MODES,
    FreeSNController,
    bridges,
    connector_commands,
    driving_ends,
)
from .driver import FreeSNMujocoDriver
from .options import Physical, SimOptions
from .recognizer import FreeSNRecognizer, node_headings
from .world import DockEvent, FreeSNWorld, NodeReport, StrutReport

__all__ = [
    "FOLLOW_EFFORT",
    "FORWARD_MODES",
    "DockEvent",
    "FreeSNController",
    "FreeSNMujocoDriver",
    "FreeSNRecognizer",
    "FreeSNWorld",
    "NodeReport",
    "Physical",
    "SimOptions",
    "StrutReport",
    "bridges",
    "connector_commands",
    "driving_ends",
    "node_headings",
]
