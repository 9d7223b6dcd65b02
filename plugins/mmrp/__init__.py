"""MMRP: the Modular Mobile Reconfigurable Platform (tracked modules with four faces).

Wei et al., "A Graph-Based Hybrid Reconfiguration Deformation Planning for Modular
Robots", Sensors 23 (2023) 7892.

Its public names load lazily (PEP 562), as :mod:`msrr.core`'s do: importing the plugin
(on every command's ``--help``) imports neither the planner nor numpy.
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS: dict[str, str] = {
    "certified_optimum": "exact",
    "CertifiedOptimum": "exact",
    "check_plan": "check",
    "DistributedRecognizer": "recognition",
    "FACES": "robot",
    "HybridResult": "planner",
    "layout": "representation",
    "McsHybridPlanner": "planner",
    "MmrpRules": "rules",
    "Optimum": "optimum",
    "optimum": "optimum",
    "plan_hybrid": "planner",
    "Recognition": "recognition",
    "recognize_with_stats": "recognition",
    "SPEC": "robot",
    "to_tree": "representation",
}
"""Public name -> the module of this package that defines it (imported on first use)."""

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
