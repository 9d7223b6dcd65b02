"""The MuJoCo driver of single-connector freeform modules (a robot registers it as ``mujoco``).

Commands (per module, :class:`~msrr.core.driver.ModuleCommand`):

* ``joints={"dir_x", "dir_y", "dir_z"}``: the connection vector (from the module toward
  the module it is docked on) in that module's horizontal frame; the drive turns the
  module about its parent's centre toward it. ``"sucker": 1`` engages the vacuum sucker
  (SnailBot), ``0`` releases it. ``{"roll_x", "roll_y"}``: a free FreeBOT rolls on the
  ground at this velocity [m/s] in its own horizontal frame (pendulum drive);
* ``dock=("@Q",)`` arms the connector to latch on ``Q`` when the shells touch (while
  docked on ``P``: a flow, the switch happens at once); ``dock=(port,)`` (the module's
  port name) latches on whatever it touches first;
* ``undock=("@P",)`` (or the port name) releases the connector; while a dock elsewhere is
  armed, the release waits for that switch.

A module that drops out of the commands brakes where it is. Sensors: module id ->
:class:`~msrr.core.freeform.world.ModuleReport`.
"""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Mapping
from dataclasses import fields, replace
from typing import Any, ClassVar

import numpy as np

from ..configuration import Configuration
from ..driver import Driver, ModuleCommand, Observation, Pose
from ..errors import ExecutionError
from .world import FreeformOptions, FreeformWorld, ModuleDesign

__all__ = ["FreeformDriver", "MujocoDriver"]

_JOINTS = ("dir_x", "dir_y", "dir_z")
_ROLL = ("roll_x", "roll_y")


class MujocoDriver(Driver):
    """What every MuJoCo driver shares: its options (a dataclass, with keyword overrides
    of its fields and the seed), a world built by :meth:`build` at each :meth:`reset`,
    MuJoCo's passive viewer where asked, and the observation, time and ground truth read
    from the world. A subclass names its options type and builds its world.

    Args:
        gui: open MuJoCo's passive viewer (needs a display).
        seed: seed of the world's noise (overrides ``options.seed``).
        options: an ``options_type`` instance; keyword overrides of its fields
            (``noise=0.02``) may be given directly.
    """

    options_type: ClassVar[type]
    arguments: ClassVar[tuple[str, ...]] = ("gui", "seed", "options")
    """The constructor's own keywords, named when an unknown option is refused."""

    def __init__(self, *, gui: bool = False, seed: int | None = None,
                 options: Any = None, **overrides: Any):
        known = {f.name for f in fields(self.options_type)}
        unknown = set(overrides) - known
        if unknown:
            raise ExecutionError(f"unknown MuJoCo driver option(s) {sorted(unknown)} (known: "
                                 f"{', '.join([*self.arguments, *sorted(known - set(self.arguments))])})")
        if seed is not None:
            overrides["seed"] = seed
        self.options = replace(options or self.options_type(), **overrides)
        self.gui = gui
        self.world: Any = None
        self._connected = False
        self._viewer: Any = None
        self._moving: set[str] = set()

    @abstractmethod
    def build(self, start: Configuration) -> Any:
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

    def _world(self) -> Any:
        self.require_connected()
        if self.world is None:
            raise ExecutionError(f"driver {self.name!r} has no world yet; call reset(start) first")
        return self.world

    def reset(self, start: Configuration) -> None:
        """Build the world of ``start``; time becomes 0."""
        self.require_connected()
        self.world = self.build(start)
        self._moving = set()
        if self.gui:
            from mujoco import viewer  # the viewer needs a display; imported only then

            if self._viewer is not None:
                self._viewer.close()
            self._viewer = viewer.launch_passive(self.world.model, self.world.data)

    def get_observation(self) -> Observation:
        world = self._world()
        poses = {m: Pose(p, q) for m, (p, q) in world.poses().items()}
        groups = world.groups()
        return Observation(time=world.time, poses=poses, sensors=world.reports(),
                           groups=tuple(groups) if len(groups) > 1 else ())

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


class FreeformDriver(MujocoDriver):
    """Single-connector freeform modules simulated in MuJoCo, headless unless ``gui``.

    Args:
        design: the module.
        gui, seed, options, overrides: as :class:`MujocoDriver`, with
            :class:`~msrr.core.freeform.world.FreeformOptions`.
    """

    name: ClassVar[str] = "mujoco"
    description: ClassVar[str] = "MuJoCo: spheres with one connector on a motor-driven joint"
    options_type = FreeformOptions

    def __init__(self, design: ModuleDesign, *, gui: bool = False, seed: int | None = None,
                 options: FreeformOptions | None = None, **overrides: Any):
        super().__init__(gui=gui, seed=seed, options=options, **overrides)
        self.design = design

    def build(self, start: Configuration) -> FreeformWorld:
        return FreeformWorld(start, self.design, self.options)

    def send_action(self, commands: Mapping[str, ModuleCommand]) -> None:
        world = self._world()
        unknown = set(commands) - set(world.modules)
        if unknown:
            raise ExecutionError(f"commands for unknown module(s) {sorted(unknown)}")
        for module in self._moving - set(commands):
            world.command_hold(module)
        self._moving = set(commands)
        for module, command in commands.items():
            joints = dict(command.joints)
            extra = set(joints) - {*_JOINTS, *_ROLL, "sucker"}
            if extra or command.wheels:
                raise ExecutionError(f"module {module}: unknown joint(s) "
                                     f"{sorted(extra | set(command.wheels))} (known: "
                                     f"{', '.join(_JOINTS + _ROLL)}, sucker)")
            for port in command.dock:      # first: an undock with a dock armed is a flow
                world.command_dock(module, self._other(module, port))
            for port in command.undock:
                world.command_undock(module, self._other(module, port))
            if "sucker" in joints:
                world.command_sucker(module, joints["sucker"] > 0.5)
            if any(n in joints for n in _ROLL):
                world.command_roll(module, np.array([joints.get("roll_x", 0.0),
                                                     joints.get("roll_y", 0.0), 0.0]))
            present = [n in joints for n in _JOINTS]
            if any(present):
                if not all(present):
                    raise ExecutionError(f"module {module}: joints {list(_JOINTS)} must be "
                                         "given together")
                vector = np.array([joints[n] for n in _JOINTS], dtype=np.float64)
                norm = float(np.linalg.norm(vector))
                if not np.isfinite(norm) or norm < 1e-9:
                    raise ExecutionError(f"module {module}: dir must be a non-zero vector")
                world.command_direction(module, vector / norm)

    def _other(self, module: str, port: str) -> str:
        """The module named by a dock/undock entry (``"@Q"``), or ``""`` for a port name
        (the one connector: any module it touches, or whichever it is docked on)."""
        return port[1:] if port.startswith("@") else ""

    def constraint_events(self) -> dict[str, int]:
        """Docks, undocks and flows since :meth:`reset`, from the world's constraint switches
        (a flow is one switch, counted once as a flow and not as a dock or an undock)."""
        events = self._world().events
        return {kind: sum(e.kind == kind for e in events) for kind in ("dock", "undock", "flow")}
