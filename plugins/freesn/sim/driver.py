"""The FreeSN MuJoCo driver (registered as ``mujoco`` for robot ``freesn``)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

from msrr.core.configuration import Configuration
from msrr.core.driver import ModuleCommand
from msrr.core.errors import ExecutionError
from msrr.core.faults import SELF_COLLISION
from msrr.core.freeform.mujoco_driver import MujocoDriver
from msrr.core.robot import RobotSpec

from ..robot import SPEC
from .commands import ENDS, parse_brakes, parse_command, parse_travel, parse_wheels
from .options import SimOptions
from .world import FreeSNWorld

__all__ = ["FreeSNMujocoDriver"]


class FreeSNMujocoDriver(MujocoDriver[FreeSNWorld]):
    """FreeSN modules simulated in MuJoCo, headless unless ``gui=True``.

    Args:
        gui, seed, options, overrides: as :class:`~msrr.core.freeform.mujoco_driver.MujocoDriver`,
            with the run's :class:`~.options.SimOptions` (``noise=np.radians(2)``,
            ``slip=0.05``; the seed drives noise, drift and slip).
        spec: the robot description whose geometry builds the world.

    Commands (per strut, see :mod:`.commands`): ``joints`` with the connection vector
    (and forward vector) of each docked connector in its node's horizontal frame;
    ``dock=("b",)`` extends a magnet array, ``undock=("a",)`` retracts one;
    ``wheels={"a": w}`` runs a connector's wheel pair at ``w`` [rad/s]; an
    ``"a.effort"`` without a direction brakes connector ``a`` where it is. A strut that
    drops out of the commands stops where it is (motors braked); one commanded without
    joints keeps its last targets. Node modules take no command.
    Sensors: module id -> :class:`~.world.NodeReport` or :class:`~.world.StrutReport`.
    """

    name: ClassVar[str] = "mujoco"
    description: ClassVar[str] = ("MuJoCo: node spheres, struts on motor-driven spherical "
                                  "joints, magnets as weld constraints")

    options_type = SimOptions
    sim_options: SimOptions
    arguments = ("gui", "seed", "options", "spec")

    def __init__(self, *, gui: bool = False, seed: int | None = None,
                 options: SimOptions | None = None, spec: RobotSpec = SPEC, **overrides: Any):
        super().__init__(gui=gui, seed=seed, options=options, **overrides)
        self.spec = spec

    def build(self, start: Configuration) -> FreeSNWorld:
        return FreeSNWorld(start, self.spec, self.sim_options)

    def send_action(self, commands: Mapping[str, ModuleCommand]) -> None:
        world = self._world()
        unknown = set(commands) - set(world.struts) - set(world.nodes)
        if unknown:
            raise ExecutionError(f"commands for unknown module(s) {sorted(unknown)}")
        for strut in self._moving - set(commands):
            world.command_stop(strut)
        self._moving = {m for m in commands if m in world.struts}
        for strut, command in commands.items():
            if strut in world.nodes:
                if command.joints or command.dock or command.undock or command.wheels:
                    raise ExecutionError(f"node {strut} takes no command")
                continue
            targets = parse_command(strut, command)
            for end in command.undock:
                world.command_undock(strut, end)
            for end in command.dock:
                world.command_dock(strut, end)
            for end, target in targets.items():
                world.command_target(strut, end, target)
            for end, effort in parse_brakes(strut, command).items():
                world.command_brake(strut, end, effort)
            speeds = parse_wheels(strut, command)
            travel = parse_travel(strut, command)
            for end in ENDS:   # a command is one tick's: wheels it does not name stop
                if end in speeds or world.wheel_speed(strut, end):
                    world.command_wheels(strut, end, speeds.get(end, 0.0))
                world.command_travel(strut, end, *travel.get(end, (0.0, 0.0)))

    def faults(self) -> list[str]:
        """Connector breaks, then module bodies that interpenetrated since the reset (the
        start included, :attr:`FreeSNWorld.interpenetrations`), in the order they first
        did."""
        world = self._world()
        out = [f"connector broke: {e.strut}:{e.end} at {e.node}, {e.load:.1f} N at "
               f"t={e.time:.2f} s" for e in world.events if e.kind == "break"]
        out += [f"{SELF_COLLISION}: {i}" for i in sorted(world.interpenetrations.values(),
                                                            key=lambda i: (i.time, i.a, i.b))]
        return out

    def saturation(self) -> dict[str, float]:
        """Connectors whose motors are saturated now and for how long [s]
        (:meth:`FreeSNWorld.saturation`)."""
        return self._world().saturation()

    def constraint_events(self) -> dict[str, int]:
        """Docks and undocks (commanded or broken) from the world's constraint switches."""
        events = self._world().events
        return {"dock": sum(e.kind == "dock" for e in events),
                "undock": sum(e.kind in ("undock", "break") for e in events)}
