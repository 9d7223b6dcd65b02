"""The FreeSN MuJoCo driver (registered as ``mujoco`` for robot ``freesn``)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import fields, replace
from typing import Any, ClassVar

from msrr.core.configuration import Configuration
from msrr.core.driver import Driver, ModuleCommand, Observation, Pose
from msrr.core.errors import ExecutionError
from msrr.core.robot import RobotSpec

from ..robot import SPEC
from .commands import parse_brakes, parse_command, parse_wheels
from .options import SimOptions
from .world import FreeSNWorld

__all__ = ["FreeSNMujocoDriver"]


class FreeSNMujocoDriver(Driver):
    """FreeSN modules simulated in MuJoCo, headless unless ``gui=True``.

    Args:
        gui: open MuJoCo's passive viewer (needs a display).
        seed: seed of the noise, drift and slip (overrides ``options.seed``).
        options: the run's :class:`~.options.SimOptions`; keyword overrides of its
            fields (``noise=np.radians(2)``, ``slip=0.05``) may be given directly.
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

    def __init__(self, *, gui: bool = False, seed: int | None = None,
                 options: SimOptions | None = None, spec: RobotSpec = SPEC, **overrides: Any):
        options = options or SimOptions()
        known = {f.name for f in fields(SimOptions)}
        unknown = set(overrides) - known
        if unknown:
            raise ExecutionError(f"unknown MuJoCo driver option(s) {sorted(unknown)} (known: "
                                 f"gui, seed, options, spec, {', '.join(sorted(known))})")
        if seed is not None:
            overrides["seed"] = seed
        self.options = replace(options, **overrides)
        self.gui = gui
        self.spec = spec
        self.world: FreeSNWorld | None = None
        self._connected = False
        self._viewer: Any = None
        self._moving: set[str] = set()
        self._overlaps: set[tuple[str, str]] = set()

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

    def _world(self) -> FreeSNWorld:
        self.require_connected()
        if self.world is None:
            raise ExecutionError("driver 'mujoco' has no world yet; call reset(start) first")
        return self.world

    def reset(self, start: Configuration) -> None:
        """Build the world of ``start`` (its docked ends docked); time becomes 0."""
        self.require_connected()
        self.world = FreeSNWorld(start, self.spec, self.options)
        self._moving = set()
        self._overlaps = {p[:2] for p in self.world.penetrations(0.003)}
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
            for end, speed in parse_wheels(strut, command).items():
                world.command_wheels(strut, end, speed)

    def step(self, dt: float) -> None:
        world = self._world()
        world.step(dt)
        if self._viewer is not None:
            self._viewer.sync()

    @property
    def time(self) -> float:
        return self._world().time

    def ground_truth(self) -> Configuration | None:
        """The world's ground truth (:meth:`FreeSNWorld.ground_truth`), for judging runs."""
        return self._world().ground_truth()

    def faults(self) -> list[str]:
        """Connector breaks, then overlaps of bodies that did not overlap at the start."""
        world = self._world()
        out = [f"connector broke: {e.strut}:{e.end} at {e.node}, {e.load:.1f} N at "
               f"t={e.time:.2f} s" for e in world.events if e.kind == "break"]
        new = [p for p in world.penetrations(0.003) if p[:2] not in self._overlaps]
        out += [f"self-collision: {a} in {b} by {1000 * d:.1f} mm" for a, b, d in new]
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
