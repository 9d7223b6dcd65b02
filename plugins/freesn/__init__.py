"""FreeSN: freeform modular robot of spherical node modules and two-connector struts.

Tu et al., "Locomotion and Self-reconfiguration Autonomy for Spherical Freeform
Modular Robots" (2025); hardware: Tu et al. 2022, Tu and Lam 2023.
"""

from .robot import SPEC
from .rules import FreeSNRules

__all__ = ["SPEC", "FreeSNRules"]
