"""What a simulator knows and the modules do not: for the judge and the recording only.

A driver's :class:`~msrr.core.driver.Observation` is what the modules report, and the
poses of an external pose sensor where the robot really has one
(:attr:`~msrr.core.driver.Observation.tracked`); the control path -- executor, IK
tracking, controllers, recognizers, planners -- decides on nothing else. What a
simulator knows besides (every body's world pose, which modules its constraints hold
together) is the *witness channel*: :meth:`Driver.witness
<msrr.core.driver.Driver.witness>` (a :class:`Witness`), :meth:`Driver.ground_truth
<msrr.core.driver.Driver.ground_truth>` (the configuration), and the simulator's own
counts (``faults``, ``saturation``, ``constraint_events``). Only the judge
(:mod:`msrr.core.judge`), the recording (:mod:`msrr.core.timeline`), the application
wing (a goal's layout, a check's verdict) and the drivers themselves read it: the
control path cannot import this module (``tests/core/test_layers.py``) nor call those
methods (``tests/core/test_ground_truth.py``), and a run with the channel removed sends
the same commands.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Protocol

from .driver import Observation, Pose

__all__ = ["Witness", "poses_seen"]


@dataclass(frozen=True)
class Witness:
    """The simulator's own state at one instant.

    Attributes:
        time: driver time since :meth:`~msrr.core.driver.Driver.reset` [s].
        poses: world pose of every module body (exact: no sensor noise).
    """

    time: float
    poses: Mapping[str, Pose]


class _Seen(Protocol):
    def witness(self) -> Witness | None: ...

    def get_observation(self) -> Observation: ...


def poses_seen(driver: _Seen) -> Mapping[str, Pose]:
    """Every module's world pose as the judge sees it: the simulator's own (the witness)
    where it has them, else what the robot's pose sensor reports (hardware; empty for a
    robot without one)."""
    seen = driver.witness()
    return seen.poses if seen is not None else driver.get_observation().tracked
