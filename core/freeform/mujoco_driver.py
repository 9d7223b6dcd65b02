"""What every MuJoCo driver of freeform modules shares (FreeBOT, SnailBot, FreeSN).

Apart from the worlds (:mod:`.mujoco`) so that what reads a world's reports -- the
recognizers, which import a world module for its report types -- cannot reach the
witness channel (:mod:`msrr.core.witness`) this driver gives the judge.
"""

from __future__ import annotations

from abc import abstractmethod
from dataclasses import fields, replace
from typing import Any, ClassVar, Generic, TypeVar

from ..configuration import Configuration
from ..driver import Driver, Observation, Pose
from ..errors import ExecutionError
from ..witness import Witness
from .mujoco import MujocoOptions, MujocoWorld

__all__ = ["MujocoDriver"]


W = TypeVar("W", bound="MujocoWorld[Any, Any]")
"""The world a driver builds."""


class MujocoDriver(Driver, Generic[W]):
    """What every MuJoCo driver shares: its options (an ``options_type``, with keyword
    overrides of its fields and the seed), a world built by :meth:`build` at each
    :meth:`reset`, MuJoCo's passive viewer where asked, and the observation, time and
    ground truth read from the world. A subclass names its options type and builds its
    world.

    Args:
        gui: open MuJoCo's passive viewer (needs a display).
        seed: seed of the world's noise (overrides ``options.seed``).
        options: an ``options_type`` instance; keyword overrides of its fields
            (``noise=0.02``) may be given directly.

    Attributes:
        sim_options: the run's options (``options`` with the overrides); the class's
            ``options`` declares the overrides a run may give (``options_type.OPTIONS``).
    """

    options_type: ClassVar[type[MujocoOptions]]
    arguments: ClassVar[tuple[str, ...]] = ("gui", "seed", "options")
    """The constructor's own keywords, named when an unknown option is refused."""

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if "options_type" in cls.__dict__:  # the declared options follow the options type
            cls.options = cls.options_type.driver_options()

    def __init__(self, *, gui: bool = False, seed: int | None = None,
                 options: MujocoOptions | None = None, **overrides: Any):
        known = {f.name for f in fields(self.options_type)}
        unknown = set(overrides) - known
        if unknown:
            raise ExecutionError(f"unknown MuJoCo driver option(s) {sorted(unknown)} (known: "
                                 f"{', '.join([*self.arguments, *sorted(known - set(self.arguments))])})")
        if seed is not None:
            overrides["seed"] = seed
        self.sim_options = replace(options or self.options_type(), **overrides)
        self.gui = gui
        self.world: W | None = None
        self._connected = False
        self._viewer: Any = None
        self._moving: set[str] = set()

    @abstractmethod
    def build(self, start: Configuration) -> W:
        """The world of ``start`` (its connections docked, time 0)."""

    @property
    def is_connected(self) -> bool:
        return self._connected

    def connect(self) -> None:
        self._connected = True

    def disconnect(self) -> None:
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None
        self.world = None
        self._connected = False

    def _world(self) -> W:
        self.require_connected()
        if self.world is None:
            raise ExecutionError(f"driver {self.name!r} has no world yet; call reset(start) first")
        return self.world

    def reset(self, start: Configuration) -> None:
        """Build the world of ``start``; time becomes 0."""
        self.require_connected()
        world = self.world = self.build(start)
        self._moving = set()
        if self.gui:
            from mujoco import viewer  # the viewer needs a display; imported only then

            if self._viewer is not None:
                self._viewer.close()
            self._viewer = viewer.launch_passive(world.model, world.data)

    def get_observation(self) -> Observation:
        """The modules' reports (no pose sensor: the bodies' poses are the witness's)."""
        world = self._world()
        return Observation(time=world.time, sensors=world.reports())

    def witness(self) -> Witness:
        """Every body's exact world pose, for the judge and the recording."""
        world = self._world()
        return Witness(world.time, {m: Pose(p, q) for m, (p, q) in world.poses().items()})

    def step(self, dt: float) -> None:
        self._world().step(dt)
        if self._viewer is not None:
            self._viewer.sync()

    @property
    def time(self) -> float:
        return self._world().time

    def ground_truth(self) -> Configuration | None:
        """The world's ground truth, for judging runs (never for recognition)."""
        return self._world().ground_truth()
