"""The driver interface: one for simulation and hardware (lerobot-style).

A driver owns the modules' physical state. The executor uses it in a closed loop:

``reset(start)`` places the modules of a configuration; each tick it reads
:meth:`Driver.get_observation` (raw sensor data, turned into a configuration by the
robot's recognizer), sends per-module :class:`ModuleCommand` s with
:meth:`Driver.send_action` and advances time with :meth:`Driver.step`.

Drivers are registered through ``msrr_drivers(robot, register)``: the registered
item is a factory (a class works) with ``name`` and ``description`` attributes,
called with keyword options (``gui``, ``seed``) to build a :class:`Driver`.

A factory declares the further keyword options it takes (``--driver-option
NAME=VALUE``) in ``options``, a tuple of :class:`DriverOption` (name, type, bounds,
unit, description); :func:`check_driver_options` checks what a user gave against it
before anything is written. A :class:`Driver` subclass inherits ``options = ()`` (no
options besides ``gui`` and ``seed``); a factory without the attribute is not checked.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar, Protocol, Self, runtime_checkable

import numpy as np

from .configuration import Configuration
from .errors import ConfigurationError, ExecutionError, PluginError

if TYPE_CHECKING:  # the control path imports this module, never the witness channel
    from .witness import Witness

__all__ = ["RESERVED_OPTIONS", "Companions", "Driver", "DriverFactory", "DriverOption",
           "ModuleCommand", "Observation", "OptionValue", "Pose", "check_driver_options",
           "declared_options", "horizontal_centre"]

OptionValue = float | int | bool | str
"""The value of one driver option."""

RESERVED_OPTIONS = ("gui", "seed")
"""Keywords every factory is called with; their own command-line options set them."""

_TYPES: dict[type, str] = {float: "a number", int: "a whole number", bool: "true or false",
                           str: "text"}
_FIELD = "--driver-option"


@dataclass(frozen=True)
class DriverOption:
    """One keyword option a driver factory takes (``--driver-option NAME=VALUE``).

    Attributes:
        name: the keyword.
        type: ``float``, ``int``, ``bool`` or ``str``.
        description: one line for ``platform robots --options``.
        unit: the value's unit (``"rad"``, ``"m/s"``), ``""`` for none.
        low: smallest value (numbers), ``None`` for no bound.
        high: largest value (numbers), ``None`` for no bound.
        low_open: ``low`` itself is refused (``> low``).
        high_open: ``high`` itself is refused (``< high``).
        choices: the values a ``str`` option may take (empty: any non-empty text).
        default: the value the driver uses when the option is not given (shown only).

    Raises:
        PluginError: a malformed declaration (the message names it).
    """

    name: str
    type: type
    description: str = ""
    unit: str = ""
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    choices: tuple[str, ...] = ()
    default: OptionValue | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise PluginError(f"DriverOption name must be an identifier, got {self.name!r}")
        if self.name in RESERVED_OPTIONS:
            raise PluginError(f"DriverOption {self.name!r}: {self.name} is set by --{self.name}")
        if self.type not in _TYPES:
            raise PluginError(f"DriverOption {self.name!r}: type must be float, int, bool or "
                              f"str, got {self.type!r}")
        for bound in (self.low, self.high):
            if bound is not None and (isinstance(bound, bool) or not isinstance(bound, int | float)
                                      or not math.isfinite(bound)):
                raise PluginError(f"DriverOption {self.name!r}: bounds must be finite numbers, "
                                  f"got {bound!r}")
        if self.low is not None and self.high is not None and self.low > self.high:
            raise PluginError(f"DriverOption {self.name!r}: low {self.low} > high {self.high}")

    @property
    def bounds(self) -> str:
        """``"in (0, 0.05]"``, ``">= 0"``, ``"one of pose, sensors"``, or ``""``."""
        if self.choices:
            return f"one of {', '.join(self.choices)}"
        low, high = self.low, self.high
        if low is not None and high is not None:
            return (f"in {'(' if self.low_open else '['}{low:g}, {high:g}"
                    f"{')' if self.high_open else ']'}")
        if low is not None:
            return f"{'>' if self.low_open else '>='} {low:g}"
        if high is not None:
            return f"{'<' if self.high_open else '<='} {high:g}"
        return ""

    @property
    def takes(self) -> str:
        """What the option takes: ``"a number [rad] in [0, 0.5]"``."""
        unit = f" [{self.unit}]" if self.unit else ""
        bounds = f" {self.bounds}" if self.bounds else ""
        return f"{_TYPES[self.type]}{unit}{bounds}"

    def __str__(self) -> str:
        """``"noise: a number [rad] in [0, 0.5]"``."""
        return f"{self.name}: {self.takes}"

    def parse(self, value: object) -> OptionValue:
        """``value`` (the text after ``=``, or a value already typed) as this option's
        type, within its bounds.

        Raises:
            ConfigurationError: naming ``--driver-option``, the option and what it takes.
        """
        typed = self._typed(value)
        if typed is None:
            raise self._refuse(value)
        if isinstance(typed, int | float) and not isinstance(typed, bool):
            low_bad = self.low is not None and (typed <= self.low if self.low_open
                                                else typed < self.low)
            high_bad = self.high is not None and (typed >= self.high if self.high_open
                                                  else typed > self.high)
            if low_bad or high_bad:
                raise self._refuse(value)
        if self.choices and typed not in self.choices:
            raise self._refuse(value)
        return typed

    def _typed(self, value: object) -> OptionValue | None:
        text = value.strip() if isinstance(value, str) else None
        if self.type is str:
            out = text if text is not None else (None if isinstance(value, bool)
                                                 else str(value))
            return out or None
        if self.type is bool:
            if isinstance(value, bool):
                return value
            return {"true": True, "false": False}.get((text or "").lower())
        if isinstance(value, bool):
            return None
        number: float | int | None = value if isinstance(value, int | float) else None
        if text is not None:
            try:
                number = int(text) if self.type is int else float(text)
            except ValueError:
                try:
                    number = float(text)
                except ValueError:
                    return None
        if number is None or not math.isfinite(number):
            return None
        if self.type is int:
            return int(number) if float(number).is_integer() and abs(number) < 2**63 else None
        return float(number)

    def _refuse(self, value: object) -> ConfigurationError:
        shown = value if isinstance(value, str) else repr(value)
        return ConfigurationError(f"{self.name}={shown}: must be {self.takes}", field=_FIELD)


def declared_options(factory: object) -> tuple[DriverOption, ...] | None:
    """The options ``factory`` declares (its ``options``), or ``None`` when it declares
    none (it is then called with whatever was given)."""
    declared = getattr(factory, "options", None)
    if declared is None:
        return None
    if not isinstance(declared, tuple) or not all(isinstance(o, DriverOption)
                                                  for o in declared):
        raise PluginError(f"driver {getattr(factory, 'name', factory)!r}: options must be a "
                          "tuple of DriverOption")
    return declared


def check_driver_options(factory: object, given: Iterable[tuple[str, object]]
                         ) -> tuple[tuple[str, OptionValue], ...]:
    """The options ``given`` for ``factory`` (``--driver-option`` pairs), typed and
    checked against its declaration (:func:`declared_options`).

    Refused: ``gui`` and ``seed`` (their own options set them), a name given twice, and,
    for a factory that declares its options, an unknown name or a value of the wrong
    type or out of bounds. A factory that declares none gets the values as given,
    numbers and ``true``/``false`` converted.

    Raises:
        ConfigurationError: one line naming ``--driver-option``, the option and what the
            driver takes.
    """
    name = getattr(factory, "name", "?")
    declared = declared_options(factory)
    known = {} if declared is None else {o.name: o for o in declared}
    out: dict[str, OptionValue] = {}
    for key, value in given:
        if key in RESERVED_OPTIONS:
            raise ConfigurationError(f"{key} is not a driver option; use --{key}", field=_FIELD)
        if key in out:
            raise ConfigurationError(f"{key} given twice", field=_FIELD)
        if declared is None:
            out[key] = _converted(value)
            continue
        option = known.get(key)
        if option is None:
            takes = ", ".join(o.name for o in declared) or "none"
            raise ConfigurationError(f"unknown option {key!r} of driver {name!r} (known: "
                                     f"{takes}; see platform robots --options)", field=_FIELD)
        out[key] = option.parse(value)
    return tuple(out.items())


def _converted(value: object) -> OptionValue:
    """A value for a factory that declares no options: text that is a number or
    ``true``/``false`` converted, anything else as given."""
    if not isinstance(value, str):
        return value  # type: ignore[return-value]
    if value.lower() in ("true", "false"):
        return value.lower() == "true"
    for kind in (int, float):
        try:
            return kind(value)
        except ValueError:
            continue
    return value


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


def horizontal_centre(poses: Mapping[str, Pose]) -> np.ndarray | None:
    """Mean horizontal position of ``poses`` [m], shape (2,); ``None`` without poses."""
    if not poses:
        return None
    return np.mean([np.asarray(p.position, dtype=float)[:2] for p in poses.values()], axis=0)


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
    """What the robot senses at one instant: all the control path ever reads.

    Never a simulator's state: a body's true pose or which modules its constraints
    hold together is the witness channel's (:meth:`Driver.witness`,
    :meth:`Driver.ground_truth`; :mod:`msrr.core.witness`), read by the judge and the
    recording only.

    Attributes:
        time: driver time since :meth:`Driver.reset` [s].
        sensors: the modules' reports, for the robot's recognizer, keyed by module id
            (MMRP: per face, the ``(other module, other face)`` it is latched to, or
            ``None``; FreeSN: :class:`~msrr.plugins.freesn.sim.world.NodeReport` and
            ``StrutReport``). Physically separate groups are the recognizer's to find
            from what the reports say is latched.
        tracked: world poses from an external pose sensor the robot really has (MMRP's
            overhead tracking, the link protocol's ``pose`` field), with that sensor's
            noise; empty for a robot without one (FreeSN, FreeBOT, SnailBot).
    """

    time: float
    sensors: Any
    tracked: Mapping[str, Pose] = field(default_factory=dict)


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
    options: ClassVar[tuple[DriverOption, ...]] = ()
    """The keyword options the constructor takes besides ``gui`` and ``seed``."""

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
        """What the modules report now (and a pose sensor the robot has)."""

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

    def witness(self) -> Witness | None:
        """The simulator's own state now (every body's exact world pose), for the judge
        and the recording only, never for control (:mod:`msrr.core.witness`); ``None``
        where there is none (hardware: the judge then reads what the robot reports)."""
        return None

    def ground_truth(self) -> Configuration | None:
        """The configuration as the simulator knows it, for judging a run (never for
        control; :mod:`msrr.core.witness`), its vectors in the world's frame (the judge
        turns a behavior's direction onto it and measures the shift in the world);
        ``None`` where there is none (hardware, or a driver without one)."""
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

    A factory should also declare ``options``, a tuple of :class:`DriverOption`: the
    keyword options it takes besides ``gui`` and ``seed`` (``()``: none). It is not a
    member of the protocol, so a factory without it still registers; its options are
    then passed on unchecked (:func:`check_driver_options`). A factory is called once
    when a run is prepared, without :meth:`Driver.connect`, so its options are refused
    before anything is written: a driver opens nothing before ``connect``.
    """

    name: str
    description: str
    companions: Companions
    layout: DriverFactory | None

    def __call__(self, **options: Any) -> Driver: ...
