"""MMRP: the Modular Mobile Reconfigurable Platform (tracked modules with four faces).

Wei et al., "A Graph-Based Hybrid Reconfiguration Deformation Planning for Modular
Robots", Sensors 23 (2023) 7892.
"""

from .check import check_plan
from .exact import CertifiedOptimum, certified_optimum
from .optimum import Optimum, optimum
from .planner import HybridResult, McsHybridPlanner, plan_hybrid
from .recognition import DistributedRecognizer, Recognition, recognize_with_stats
from .representation import layout, to_tree
from .robot import FACES, SPEC
from .rules import MmrpRules

__all__ = [
    "FACES",
    "SPEC",
    "CertifiedOptimum",
    "DistributedRecognizer",
    "HybridResult",
    "McsHybridPlanner",
    "MmrpRules",
    "Optimum",
    "Recognition",
    "certified_optimum",
    "check_plan",
    "layout",
    "optimum",
    "plan_hybrid",
    "recognize_with_stats",
    "to_tree",
]
