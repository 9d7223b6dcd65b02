"""Where the system is, as its own sensors tell: the control path's only odometry.

A behavior's distance covered and its heading loop read an :class:`Estimate`, never a
simulator's poses (:mod:`msrr.core.witness`). A recognizer that can estimate from its
robot's reports (FreeSN: each node's IMU, gyro with bias and drift) offers an
:class:`Estimator` through ``estimator()`` (:class:`~msrr.core.capabilities.Localizing`);
for any other robot :func:`estimator_for` falls back to :class:`TrackedEstimator`, the
centre of an external pose sensor's poses where the robot has one
(:attr:`~msrr.core.driver.Observation.tracked`), else nothing (a behavior then runs its
duration or its loops).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from .configuration import Configuration
from .driver import Observation, horizontal_centre

__all__ = ["Estimate", "Estimator", "Filtering", "Localizing", "ReportFilter",
           "TrackedEstimator", "estimator_for", "report_filter_for"]


@dataclass(frozen=True)
class Estimate:
    """The system's place as estimated at one instant (with its sensors' drift).

    Attributes:
        position: horizontal position of the system [m], shape (2,), in the frame its
            estimator started in; ``None``: the sensors cannot tell.
        heading: heading [rad] of the system's reference frame (FreeSN: its root node's
            horizontal frame) about the vertical, from where the estimator started;
            ``None``: the sensors cannot tell.
    """

    position: np.ndarray | None = None
    heading: float | None = None


class Estimator(Protocol):
    """Fed every control tick's observation of a run in order, with the configuration
    recognized from it, returns the estimate after it."""

    def update(self, observation: Observation, configuration: Configuration) -> Estimate:
        """The estimate after ``observation`` (its ``time`` [s] is the driver's)."""
        ...


@runtime_checkable
class Localizing(Protocol):
    """A recognizer that also estimates where the system is from its reports."""

    def estimator(self) -> Estimator:
        """A fresh estimator for one run (it keeps the run's integrals)."""
        ...


class TrackedEstimator:
    """The centre of the tracked poses (an external pose sensor); no heading."""

    def update(self, observation: Observation, configuration: Configuration) -> Estimate:
        """The mean horizontal position of ``observation.tracked`` [m]."""
        return Estimate(position=horizontal_centre(observation.tracked))


def estimator_for(recognizer: Any) -> Estimator:
    """The recognizer's own estimator where it has one, else :class:`TrackedEstimator`."""
    if isinstance(recognizer, Localizing):
        return recognizer.estimator()
    return TrackedEstimator()


class ReportFilter(Protocol):
    """Fed every control tick's observation of a run in order, returns it with its
    reports as the filter estimates them (the same shape: the recognizer and the
    controllers read either)."""

    def update(self, observation: Observation) -> Observation:
        """The filtered ``observation``; the same ``time`` again returns the last answer."""
        ...


@runtime_checkable
class Filtering(Protocol):
    """A recognizer whose robot senses its own motion, so its reports can be filtered
    over a run (FreeSN: node gyros and connector encoders, :mod:`msrr.plugins.freesn.sim.filtering`)."""

    def report_filter(self) -> ReportFilter:
        """A fresh filter for one run."""
        ...


def report_filter_for(recognizer: Any) -> ReportFilter | None:
    """The recognizer's report filter where it has one, else ``None`` (raw reports)."""
    if isinstance(recognizer, Filtering):
        return recognizer.report_filter()
    return None
