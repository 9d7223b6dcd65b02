"""A mapping behavior's heading loop yields to the shape it holds
(:class:`~msrr.core.executor.ShapeYield`, issue 31): report noise and a turn of the
whole body leave it alone; a scissor of the legs mutes it within a second."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from msrr.core.alignment import rot_z
from msrr.core.configuration import Configuration
from msrr.core.executor import ExecutorOptions, ShapeYield, deformation
from msrr.core.io import load_configuration
from msrr.core.library import load_library

FREESN = Path(__file__).resolve().parents[2] / "plugins" / "freesn"
OPTIONS = ExecutorOptions()
DT = 0.1


def _standup() -> Configuration:
    """Fig. 18's stand-up, the shape fig18's node wheels hold while they drive."""
    library = load_library(FREESN / "libraries" / "S4N5.json")
    behavior = library.sublibraries["S4N5"].behaviors["node-wheels"]
    return load_configuration(FREESN / "configs" / "library" / f"{behavior.start}.json")


def _seen(goal: Configuration, rng: np.random.Generator, *, noise: float, yaw: float = 0.0,
          scissor: float = 0.0) -> Configuration:
    """``goal`` turned by ``yaw`` [rad], its edges turned alternately by ``+-scissor``
    about the vertical (two legs close, two open), each ``z`` tilted by ``noise`` [rad]."""
    z = {}
    for i, e in enumerate(e for e in goal.edges() if e.z is not None):
        v = rot_z(yaw + (scissor if i % 2 else -scissor)) @ np.asarray(e.z)
        v = v + rng.normal(0.0, noise, 3)
        z[e.id] = v / np.linalg.norm(v)
    return goal.with_vectors(z=z)


def _scales(goal: Configuration, seen: list[Configuration]) -> list[float]:
    watch = ShapeYield(goal, OPTIONS.yield_from, OPTIONS.yield_to, OPTIONS.yield_time)
    return [watch.scale(c, DT) for c in seen]


@pytest.mark.parametrize("noise_deg", [2.0, 4.0])
def test_report_noise_and_a_turning_body_leave_the_loop_alone(noise_deg) -> None:
    goal, rng = _standup(), np.random.default_rng(7)
    seen = [_seen(goal, rng, noise=math.radians(noise_deg), yaw=0.05 * k) for k in range(600)]
    raw = [math.degrees(float(np.sqrt(np.mean(np.sum(deformation(c, goal) ** 2, axis=0)))))
           for c in seen]
    assert np.mean(raw) > 0.6 * OPTIONS.yield_from / math.radians(1.0)  # noise as big as a yield
    assert min(_scales(goal, seen)) == 1.0


def test_a_scissor_of_the_legs_mutes_the_loop_and_its_end_restores_it() -> None:
    # seed 15 of fig18 at 2 deg + 5 %: the legs scissored 4 -> 16 deg in 2.5 s
    goal, rng = _standup(), np.random.default_rng(3)
    angles = np.concatenate([np.zeros(20), np.linspace(0.0, 16.0, 25), np.full(20, 16.0),
                             np.linspace(16.0, 0.0, 20), np.zeros(20)])
    seen = [_seen(goal, rng, noise=math.radians(2.0), scissor=math.radians(a)) for a in angles]
    scales = _scales(goal, seen)
    assert min(scales[:20]) == 1.0
    muted = next(k for k, s in enumerate(scales) if s == 0.0)
    assert angles[muted] < 13.0        # muted before the 16.7 deg the run ended at
    assert max(scales[45:65]) == 0.0   # held muted while the shape is off
    assert scales[-1] == 1.0           # and back once the connectors restored it
