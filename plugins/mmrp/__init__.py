"""MMRP: the Modular Mobile Reconfigurable Platform (tracked modules with four faces).

Wei et al., "A Graph-Based Hybrid Reconfiguration Deformation Planning for Modular
Robots", Sensors 23 (2023) 7892.
"""

from .robot import FACES, SPEC
from .rules import MmrpRules

__all__ = ["FACES", "SPEC", "MmrpRules"]
