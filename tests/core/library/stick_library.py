"""Library sources for the ``stick`` test robot (hubs and rods), built in code.

The core library is robot-agnostic, so its tests use the kinematics tests' ``stick``
robot (``tests/core/kinematics/kin_helpers.py``: hubs are vertices, rods are edges
carrying ``z``, a gimbal joint per rod) instead of a built-in plugin.

Sub-library ``H3R3``: three hubs and three rods.

* group ``open`` -- a path H1 -R1- H2 -R2- H3 with R3 from H3 to a free end;
* group ``closed`` -- the triangle H1 H2 H3 (R3 docked to H1; one fixed node holds it).

The recorded sequence ``close-and-open`` uses its own ids (hubs ``a b c``, rods
``p q r``): flat, R3 swung toward H1 (``S_conn``), docked (connection), undocked
(disconnection), swung down (moving). The flat start is recorded twice, at a yaw, so
the build merges it.
"""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path

import numpy as np

from msrr.core.configuration import Configuration
from msrr.core.library import LibrarySources
from msrr.core.library.model import CommandGain
from msrr.core.library.sources import (
    DesignedGroup,
    DesignedTree,
    MappingBehaviorSource,
    RecordedSequence,
    SequenceStep,
)

_PATH = Path(__file__).resolve().parents[1] / "kinematics" / "kin_helpers.py"
if "kin_helpers" not in sys.modules:
    _spec = importlib.util.spec_from_file_location("kin_helpers", _PATH)
    sys.modules["kin_helpers"] = importlib.util.module_from_spec(_spec)
    _spec.loader.exec_module(sys.modules["kin_helpers"])
STICK = sys.modules["kin_helpers"].STICK
"""The ``stick`` robot (spec, permissive docking rules, gimbal/twist/brace joint modes)."""

S = math.sqrt(3.0) / 2.0
TO_H2 = (1.0, 0.0, 0.0)
TO_H3 = (-0.5, S, 0.0)
TO_H1 = (-0.5, -S, 0.0)          # from H3: where R3 docks
DOWN = (0.0, 0.0, -1.0)
FLAT = (0.0, 1.0, 0.0)


def _turned(z, yaw: float) -> list[float]:
    c, s = math.cos(yaw), math.sin(yaw)
    return [c * z[0] - s * z[1], s * z[0] + c * z[1], z[2]]


def open_chain(r3, *, ids=("H1", "H2", "H3", "R1", "R2", "R3"), yaw: float = 0.0,
               name: str = "") -> Configuration:
    """The path with R3 free, R3 pointing along ``r3``; ``ids`` rename hubs and rods."""
    h1, h2, h3, r1, r2, r3_id = ids
    config = Configuration("stick", name=name)
    for hub in (h1, h2, h3):
        config.add_module(hub, "hub")
    config.add_virtual(f"{r3_id}:end")
    config.connect(h1, h2, id=r1, kind="rod", z=_turned(TO_H2, yaw))
    config.connect(h2, h3, id=r2, kind="rod", z=_turned(TO_H3, yaw))
    config.connect(h3, f"{r3_id}:end", id=r3_id, kind="rod", z=_turned(r3, yaw))
    return config


def closed_triangle(*, ids=("H1", "H2", "H3", "R1", "R2", "R3"), name: str = "") -> Configuration:
    """The triangle: R3 docked from H3 to H1."""
    h1, h2, h3, r1, r2, r3_id = ids
    config = Configuration("stick", name=name)
    for hub in (h1, h2, h3):
        config.add_module(hub, "hub")
    config.connect(h1, h2, id=r1, kind="rod", z=TO_H2)
    config.connect(h2, h3, id=r2, kind="rod", z=TO_H3)
    config.connect(h3, h1, id=r3_id, kind="rod", z=TO_H1)
    return config


RECORDING = ("a", "b", "c", "p", "q", "r")


def stick_sources() -> LibrarySources:
    """The ``H3R3`` sources: two designed groups, one recorded sequence, one mapping behavior."""
    groups = (
        DesignedGroup("open", open_chain(FLAT, name="flat"),
                      (DesignedTree("K1", joint_mode="gimbal"),), origin="design"),
        DesignedGroup("closed", closed_triangle(name="triangle"),
                      (DesignedTree("K1"),), origin="design"),
    )
    steps = [open_chain(FLAT, ids=RECORDING, yaw=0.7, name="flat-again"),
             open_chain(TO_H1, ids=RECORDING, name="aim"),
             closed_triangle(ids=RECORDING, name="docked"),
             open_chain(TO_H1, ids=RECORDING, name="undocked"),
             open_chain(DOWN, ids=RECORDING, name="leg-down")]
    sequence = RecordedSequence("close-and-open", tuple(SequenceStep(c) for c in steps),
                                origin="recording")
    behavior = MappingBehaviorSource("spin", "aim", ("rate",),
                                     (CommandGain("r", "spin", (("rate", 2.0),)),),
                                     origin="recording")
    return LibrarySources("stick", "H3R3", groups, (sequence,), (behavior,),
                          (("design", "0" * 64), ("recording", "1" * 64)))


def relabelled(config: Configuration, *, noise: float, seed: int) -> Configuration:
    """``config`` with every id renamed (``m*``) and every ``z`` perturbed by ``noise``."""
    rng = np.random.default_rng(seed)
    vertices = {v: f"m{i}" for i, v in enumerate(reversed(config.vertices()))}
    edges = {e: f"me{i}" for i, e in enumerate(reversed(config.edge_ids()))}
    out = config.relabel(vertices, edges)
    z = {}
    for edge in out.edges():
        v = edge.z + rng.normal(scale=noise, size=3)
        z[edge.id] = v / np.linalg.norm(v)
    return out.with_vectors(z=z, x={})
