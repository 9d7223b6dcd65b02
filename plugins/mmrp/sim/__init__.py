"""MMRP simulation in PyBullet: tracked modules on a plane, docking faces as constraints.

* :mod:`.geometry` -- pure planar maths (face frames, latch alignment, track speeds);
* :mod:`.paths` -- grid A* for a module group's centroid around the other modules;
* :mod:`.world` -- the PyBullet world (bodies, velocity control, dock constraints);
* :mod:`.driver` -- the :class:`~msrr.core.driver.Driver` registered as ``pybullet``;
* :mod:`.controller` -- the controller that follows moving goals and docks.
"""

from .controller import MmrpController
from .driver import MmrpSimDriver

__all__ = ["MmrpController", "MmrpSimDriver"]
