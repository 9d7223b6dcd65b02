"""The driver interface: one for simulation and hardware (lerobot-style).

A driver owns the modules' physical state. The executor uses it in a closed loop:

``reset(start)`` places the modules of a configuration; each tick it reads
:meth:`Driver.get_observation` (raw sensor data, turned into a configuration by the
robot's recognizer), sends per-module :class:`ModuleCommand` s with
:meth:`Driver.send_action` and advances time with :meth:`Driver.step`.

Drivers are registered through ``msrr_drivers(robot, register)``: the registered
item is a factory (a class works) with ``name`` and ``description`` attributes,
called with keyword options (``gui``, ``seed``) to build a :class:`Driver`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol, Self, runtime_checkable

import numpy as np

from .configuration import Configuration
from .errors import ExecutionError

__all__ = ["Companions", "Driver", "DriverFactory", "ModuleCommand", "Observation", "Pose"]


@dataclass(frozen=True)
class Pose:
    """A rigid pose in the world frame.

    Attributes:
        position: [m], shape (3,).
        orientation: unit quaternion ``(x, y, z, w)``, shape (4,).
    """

    position: np.ndarray
    orientation: np.ndarray

    @classmethod
    def planar(cls, x: float, y: float, yaw: float, z: float = 0.0) -> Pose:
        """A pose on the ground plane: ``x, y, z`` [m], heading ``yaw`` [rad]."""
        return cls(np.array([x, y, z], dtype=np.float64),
                   np.array([0.0, 0.0, np.sin(yaw / 2), np.cos(yaw / 2)], dtype=np.float64))

    @property
    def yaw(self) -> float:
        """Heading about the world z axis [rad], in (-pi, pi]."""
        x, y, z, w = self.orientation
        return float(np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)))


@dataclass(frozen=True)
class ModuleCommand:
    """What one module is told to do during one control tick.

    Attributes:
        joints: joint position targets by joint name [rad or m].
        wheels: wheel or track speeds by name [m/s] (MMRP: ``left``, ``right``).
        dock: ports whose connector should latch (kept armed while repeated).
        undock: ports whose connector should release.
    """

    joints: Mapping[str, float] = field(default_factory=dict)
    wheels: Mapping[str, float] = field(default_factory=dict)
    dock: tuple[str, ...] = ()
    undock: tuple[str, ...] = ()


@dataclass(frozen=True)
class Observation:
    """What a driver reports at one instant.

    Attributes:
        time: driver time since :meth:`Driver.reset` [s].
        poses: world pose of every module body.
        sensors: raw data for the robot's recognizer (MMRP: per module, per face,
            the ``(other module, other face)`` it is latched to, or ``None``);
            a mapping keyed by module id when ``groups`` is given.
        groups: module sets that are physically separate systems (connected
            components after undocking); each is recognized on its own, with the
            ``sensors`` entries of its modules. Empty: one system.
    """

    time: float
    poses: Mapping[str, Pose]
    sensors: Any
    groups: tuple[frozenset[str], ...] = ()


@dataclass(frozen=True)
class Companions:
    """The recognizer and controller that read and command a driver's modules, by name
    (``None``: the robot's default one)."""

    recognizer: str | None = None
    controller: str | None = None


class Driver(ABC):
    """A simulated or real set of modules.

    Use as a context manager (``with factory(gui=False) as driver:``) or call
    :meth:`connect` and :meth:`disconnect`.
    """

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    companions: ClassVar[Companions] = Companions()
    layout: ClassVar[DriverFactory | None] = None

    @property
    @abstractmethod
    def is_connected(self) -> bool:
        """Whether :meth:`connect` has been called and :meth:`disconnect` not yet."""

    @abstractmethod
    def connect(self) -> None:
        """Open the simulator or the link to the modules."""

    @abstractmethod
    def disconnect(self) -> None:
        """Stop every module and close; safe to call twice."""

    @abstractmethod
    def reset(self, start: Configuration) -> None:
        """Place (or expect) the modules of ``start``, docked as it says; time becomes 0."""

    @abstractmethod
    def get_observation(self) -> Observation:
        """The current poses and raw sensor data."""

    @abstractmethod
    def send_action(self, commands: Mapping[str, ModuleCommand]) -> None:
        """Send one command per module; modules not named stop their motors."""

    @abstractmethod
    def step(self, dt: float) -> None:
        """Advance by ``dt`` [s]: integrate the simulation, or wait on hardware."""

    @property
    @abstractmethod
    def time(self) -> float:
        """Driver time since :meth:`reset` [s]."""

    def ground_truth(self) -> Configuration | None:
        """The configuration as the simulator knows it, for judging a run (never for
        control); ``None`` where there is none (hardware, or a driver without one)."""
        return None

    def faults(self) -> list[str]:
        """Faults the simulator saw since :meth:`reset`, each ``"<reason>: <details>"``
        with a reason of :data:`msrr.core.library.check.CHECK_REASONS` (``"connector
        broke: ..."``); empty where there are none or the driver cannot tell."""
        return []

    def saturation(self) -> dict[str, float]:
        """Actuators saturated now (at their torque limit, stalled against a load):
        ``"<module>:<port>"`` -> how long without a break [s]; empty where there are none
        or the driver cannot tell. A long streak at the end of a run that did not finish
        is the ``"torque limit"`` reason of a feasibility check."""
        return {}

    def constraint_events(self) -> dict[str, int]:
        """Docks and undocks since :meth:`reset` counted from the simulator's constraint
        state (``{"dock": n, "undock": m}``); empty where the driver cannot tell."""
        return {}

    def require_connected(self) -> None:
        """Raise :class:`ExecutionError` unless connected."""
        if not self.is_connected:
            raise ExecutionError(f"driver {self.name!r} is not connected; call connect() first")

    def __enter__(self) -> Self:
        self.connect()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.disconnect()


@runtime_checkable
class DriverFactory(Protocol):
    """What ``msrr_drivers`` registers: a named callable that builds a :class:`Driver`.

    Attributes:
        name: its name on the command line (``--driver NAME``).
        description: one line for ``platform robots``.
        companions: the recognizer and controller its modules need (a
            :class:`Driver` subclass says none: the robot's defaults).
        layout: a driver that can place modules, to lay out a goal for judging the
            final shape, where this one cannot (the network link); ``None``: itself.
    """

    name: str
    description: str
    companions: Companions
    layout: DriverFactory | None

    def __call__(self, **options: Any) -> Driver: ...
