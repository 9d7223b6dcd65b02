"""The MMRP PyBullet driver (registered as ``pybullet`` for robot ``mmrp``)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

from msrr.core.configuration import Configuration
from msrr.core.driver import Driver, DriverOption, ModuleCommand, Observation, Pose
from msrr.core.errors import ExecutionError
from msrr.core.witness import Witness

from ..representation import layout
from ..robot import MODULE
from .world import MmrpWorld

__all__ = ["MmrpSimDriver"]


class MmrpSimDriver(Driver):
    """MMRP modules simulated in PyBullet, headless unless ``gui=True``.

    Args:
        gui: open the PyBullet GUI (needs a display).
        physics_rate: physics steps per second [Hz].
        seed: unused by the deterministic simulation; kept for the factory interface.

    Commands: ``wheels={"left": m/s, "right": m/s}`` track speeds (clipped to the
    module's ``max_speed``), ``dock=(face, ...)`` arms a connector until it latches,
    ``undock=(face, ...)`` releases it. Sensors: per module, per face, the
    ``(module, face)`` latched to it, or ``None``; tracked: every module's pose from the
    overhead tracking (exact in simulation; ``--faults noise:...`` adds noise).
    """

    name: ClassVar[str] = "pybullet"
    description: ClassVar[str] = "PyBullet: tracked modules on a plane, faces latch as constraints"
    options: ClassVar[tuple[DriverOption, ...]] = (
        DriverOption("physics_rate", float, "physics steps per second", "Hz", 30.0, 2000.0,
                     default=240.0),
    )

    def __init__(self, *, gui: bool = False, physics_rate: float = 240.0, seed: int = 0,
                 **_: Any):
        self.gui = gui
        self.physics_rate = physics_rate
        self.seed = seed
        self.world: MmrpWorld | None = None
        self.max_speed = float(MODULE.geometry["max_speed"])

    @property
    def is_connected(self) -> bool:
        return self.world is not None

    def connect(self) -> None:
        if self.world is None:
            self.world = MmrpWorld(MODULE.geometry, gui=self.gui, physics_rate=self.physics_rate)

    def disconnect(self) -> None:
        if self.world is not None:
            self.world.close()
            self.world = None

    def _world(self) -> MmrpWorld:
        self.require_connected()
        assert self.world is not None
        return self.world

    def reset(self, start: Configuration) -> None:
        """Rebuild the world with ``start`` laid out on the grid (root at the origin)."""
        self.disconnect()
        self.connect()
        world = self._world()
        for module, pose in layout(start).items():
            world.add_module(module, pose)
        for edge in start.edges():
            if edge.ports is None:
                raise ExecutionError(f"connection {edge.id} has no faces; cannot dock it")
            world.latch(edge.source, edge.ports[0], edge.target, edge.ports[1])

    def get_observation(self) -> Observation:
        world = self._world()
        # MMRP's overhead tracking is a pose sensor the robot has (section 7: the modules
        # are tracked from above), so its poses are reports too
        return Observation(time=world.time, sensors=world.links(), tracked=self._poses())

    def _poses(self) -> dict[str, Pose]:
        world = self._world()
        return {m: Pose(*world.pose(m)) for m in world.bodies}

    def witness(self) -> Witness:
        """Every module's exact pose, for the judge and the recording."""
        return Witness(self._world().time, self._poses())

    def send_action(self, commands: Mapping[str, ModuleCommand]) -> None:
        world = self._world()
        unknown = set(commands) - set(world.bodies)
        if unknown:
            raise ExecutionError(f"commands for unknown module(s) {sorted(unknown)}")
        world.armed = set()
        tracks = {}
        for module, command in commands.items():
            left = float(command.wheels.get("left", 0.0))
            right = float(command.wheels.get("right", 0.0))
            scale = max(1.0, abs(left) / self.max_speed, abs(right) / self.max_speed)
            tracks[module] = (left / scale, right / scale)
            for face in command.undock:
                world.unlatch(module, face)
            world.armed |= {(module, face) for face in command.dock}
        world.set_tracks(tracks)

    def step(self, dt: float) -> None:
        world = self._world()
        for _ in range(max(1, round(dt * self.physics_rate))):
            world.step()

    @property
    def time(self) -> float:
        return self._world().time

    def ground_truth(self) -> Configuration:
        """The configuration of the simulator's dock constraints: one connection per
        constraint, from its active face (T, R) to its passive one (for judging only)."""
        world = self._world()
        truth = Configuration("mmrp", name="ground truth")
        for module in sorted(world.bodies):
            truth.add_module(module, MODULE.name)
        for key in sorted(sorted(k) for k in world.docks):
            (a, face_a), (b, face_b) = key
            if MODULE.port(face_a).role != "active":
                (a, face_a), (b, face_b) = (b, face_b), (a, face_a)
            truth.connect(a, b, ports=(face_a, face_b))
        return truth
