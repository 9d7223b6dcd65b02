"""The MuJoCo driver of single-connector freeform modules (a robot registers it as ``mujoco``).

Commands (per module, :class:`~msrr.core.driver.ModuleCommand`):

* ``joints={"dir_x", "dir_y", "dir_z"}``: the connection vector (from the module toward
  the module it is docked on) in that module's horizontal frame; the drive turns the
  module about its parent's centre toward it. ``"sucker": 1`` engages the vacuum sucker
  (SnailBot), ``0`` releases it; ``"twist"`` [rad] turns a module whose sucker holds
  about the sucker's axis by that angle from where it is now. ``{"roll_x", "roll_y"}``: a free
  module rolls (FreeBOT, pendulum drive) or crawls (SnailBot) on the ground at this velocity
  [m/s] in its own horizontal frame (ignored once it is docked); with ``"turn"`` [rad/s], the
  module rolls as part of a piece travelling as one rigid body that turns at that rate, its
  centre at that velocity (FreeBOT;
  :meth:`~msrr.core.freeform.world.FreeformWorld.command_travel`);
* ``dock=("@Q",)`` arms the connector to latch on ``Q`` when the shells touch (while
  docked on ``P``: a flow, the switch happens at once); ``dock=(port,)`` (the module's
  port name) latches on whatever it touches first;
* ``undock=("@P",)`` (or the port name) releases the connector; while a dock elsewhere is
  armed, the release waits for that switch.

A module that drops out of the commands brakes where it is. Sensors: module id ->
:class:`~msrr.core.freeform.world.ModuleReport`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from ..configuration import Configuration
from ..driver import Companions, DriverFactory, DriverOption, ModuleCommand
from ..errors import ExecutionError
from .design import ModuleDesign
from .mujoco_driver import MujocoDriver
from .world import FreeformOptions, FreeformWorld

__all__ = ["FreeformDriver", "FreeformDriverFactory"]

_JOINTS = ("dir_x", "dir_y", "dir_z")
_ROLL = ("roll_x", "roll_y")


class FreeformDriver(MujocoDriver[FreeformWorld]):
    """Single-connector freeform modules simulated in MuJoCo, headless unless ``gui``.

    Args:
        design: the module.
        gui, seed, options, overrides: as :class:`MujocoDriver`, with
            :class:`~msrr.core.freeform.world.FreeformOptions`.
    """

    name: ClassVar[str] = "mujoco"
    description: ClassVar[str] = "MuJoCo: spheres with one connector on a motor-driven joint"
    options_type = FreeformOptions
    sim_options: FreeformOptions

    def __init__(self, design: ModuleDesign, *, gui: bool = False, seed: int | None = None,
                 options: FreeformOptions | None = None, **overrides: Any):
        super().__init__(gui=gui, seed=seed, options=options, **overrides)
        self.design = design

    def build(self, start: Configuration) -> FreeformWorld:
        return FreeformWorld(start, self.design, self.sim_options)

    def send_action(self, commands: Mapping[str, ModuleCommand]) -> None:
        if self.world is None and not commands:
            return   # nothing to stop: no world was built (its reset failed, and says why)
        world = self._world()
        unknown = set(commands) - set(world.modules)
        if unknown:
            raise ExecutionError(f"commands for unknown module(s) {sorted(unknown)}")
        for module in self._moving - set(commands):
            world.command_hold(module)
        self._moving = set(commands)
        for module, command in commands.items():
            joints = dict(command.joints)
            extra = set(joints) - {*_JOINTS, *_ROLL, "turn", "sucker", "twist"}
            if extra or command.wheels:
                raise ExecutionError(f"module {module}: unknown joint(s) "
                                     f"{sorted(extra | set(command.wheels))} (known: "
                                     f"{', '.join(_JOINTS + _ROLL)}, turn, sucker, twist)")
            for port in command.dock:      # first: an undock with a dock armed is a flow
                world.command_dock(module, self._other(module, port))
            for port in command.undock:
                world.command_undock(module, self._other(module, port))
            if "sucker" in joints:
                world.command_sucker(module, joints["sucker"] > 0.5)
            if "twist" in joints:
                world.command_twist(module, float(joints["twist"]))
            if any(n in joints for n in (*_ROLL, "turn")):
                velocity = np.array([joints.get("roll_x", 0.0), joints.get("roll_y", 0.0), 0.0])
                if "turn" in joints:
                    world.command_travel(module, velocity, float(joints.get("turn", 0.0)))
                else:
                    world.command_roll(module, velocity)
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
        """Docks, undocks (commanded or broken) and flows since :meth:`reset`, from the
        world's constraint switches (a flow is one switch, counted once as a flow and not
        as a dock or an undock)."""
        events = self._world().events
        return {"dock": sum(e.kind == "dock" for e in events),
                "undock": sum(e.kind in ("undock", "break") for e in events),
                "flow": sum(e.kind == "flow" for e in events)}

    def faults(self) -> list[str]:
        """Connections that broke under their load (``"connector broke: ..."``)."""
        return [f"connector broke: {e.module} at {e.target}, {e.load:.1f} N at t={e.time:.2f} s"
                for e in self._world().events if e.kind == "break"]


@dataclass(frozen=True)
class FreeformDriverFactory:
    """What a single-connector robot registers as its ``mujoco`` driver: a
    :class:`FreeformDriver` of its module design.

    Attributes:
        design: the robot's module.
        description: the driver's line in ``platform robots``.
        name: its name.
        companions: its recognizer and controller (``None``: the robot's defaults).
        layout: ``None``: the driver lays out a goal itself.
    """

    design: ModuleDesign
    description: str
    name: str = "mujoco"
    companions: Companions = Companions()
    layout: DriverFactory | None = None

    @property
    def options(self) -> tuple[DriverOption, ...]:
        """The keyword options its drivers take (:attr:`FreeformDriver.options`)."""
        return FreeformDriver.options

    def __call__(self, **options: Any) -> FreeformDriver:
        """A driver of ``design`` (``options`` as :class:`FreeformDriver`'s keywords)."""
        return FreeformDriver(self.design, **options)
