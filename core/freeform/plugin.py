"""The hook implementations of a single-connector freeform robot (FreeBOT, SnailBot).

Such robots differ in their module (the robot description), their joint modes, how the
simulated module is built and their scenarios; everything else their plugin answers is
the family's: MISO docking rules, the ``miso`` and ``miso-exact`` planners
(:mod:`.miso`), the MuJoCo world as driver ``mujoco`` (:mod:`.world`), the contact
recognizer named as the robot and one contact controller per joint mode
(:mod:`.recognition`). A robot's ``plugin.py`` is one :class:`FreeformPlugin`::

    plugin = FreeformPlugin(__name__, bearing=True, rgba=(0.6, 0.6, 0.7, 1.0),
                            driver_description="MuJoCo: steel spheres ...")

registered with the entry point ``myrobot = "mypackage.plugin:plugin"``. Its package
holds ``robot.json`` (the robot description: the arguments of
:func:`~msrr.core.freeform.design.freeform_robot`),
``joints.JOINT_MODES`` (the default first) and ``scenarios.SCENARIOS``.

This module imports only the hook marker: a plugin built here loads on every ``--help``
for nothing; each hook imports its robot's parts, and the simulator, when it is called.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import cached_property
from importlib import import_module
from typing import TYPE_CHECKING, Any

from ..hookspecs import hookimpl

if TYPE_CHECKING:
    import numpy as np

    from ..capabilities import Controller, DriverFactory, Planner, Recognizer
    from ..configuration import Configuration
    from ..hookspecs import Register
    from ..kinematics.node import KinematicNode
    from ..robot import DockingRules, RobotSpec
    from ..scenario import Scenario
    from .design import ModuleDesign
    from .driver import FreeformDriverFactory
    from .recognition import ContactController, ContactRecognizer

__all__ = ["FreeformPlugin"]


class FreeformPlugin:
    """A single-connector robot's plugin: an object whose methods are its hooks.

    Args:
        module: the plugin module's name (``__name__``); its package holds
            ``robot.json``, ``joints`` and ``scenarios``.
        driver_description: the ``mujoco`` driver's line in ``platform robots``.
        bearing: the connector turns freely inside the shell, which rolls (FreeBOT).
        sucker: the joint mode whose controller engages the module's vacuum sucker
            (SnailBot: ``"sucker_revolute"``); ``None``: the module has no sucker.
        bends: the controllers aim each connection at its goal's bend at its parent and
            reach moves on those bends (FreeBOT; :class:`~msrr.core.freeform.ContactController`).
        rgba: shell colour in the simulator.
    """

    def __init__(self, module: str, *, driver_description: str, bearing: bool = False,
                 sucker: str | None = None, bends: bool = False,
                 rgba: tuple[float, float, float, float] = (0.6, 0.6, 0.65, 1.0)):
        self.__name__ = module   # what ``platform plugins`` shows as the plugin's module
        self.package = module.rpartition(".")[0]
        self.driver_description = driver_description
        self.bearing = bearing
        self.sucker = sucker
        self.bends = bends
        self.rgba = rgba
        self._driver: FreeformDriverFactory | None = None

    def __repr__(self) -> str:
        return f"FreeformPlugin({self.__name__!r})"

    def hooks(self) -> dict[str, Callable[..., Any]]:
        """The hook implementations, bound, by name: ``globals().update(plugin.hooks())``
        in the plugin module makes the module itself the same plugin (an entry point may
        name the module or the object)."""
        return {name: getattr(self, name) for name in dir(type(self))
                if name.startswith("msrr_")}

    def _part(self, module: str, name: str) -> Any:
        return getattr(import_module(f"{self.package}.{module}"), name)

    # -- the robot's parts, imported on first use (the heavy ones by methods: properties
    # -- may be read when the plugin is registered)

    @cached_property
    def spec(self) -> RobotSpec:
        """The robot description, read from the package's ``robot.json``."""
        from importlib.resources import files

        from .design import read_freeform_robot

        description = files(self.package) / "robot.json"
        return read_freeform_robot(description.read_text(), f"{self.package}/robot.json")

    @cached_property
    def miso_rules(self) -> dict[str, int | str | None]:
        """The robot's MISO connection rules (``robot.json``'s ``miso``), which its
        planners obey."""
        from importlib.resources import files

        from .design import read_miso_rules

        description = files(self.package) / "robot.json"
        return read_miso_rules(description.read_text(), f"{self.package}/robot.json")

    def joint_modes(self) -> Sequence[type[KinematicNode]]:
        """The joint modes (``joints.JOINT_MODES``), the default first."""
        modes: Sequence[type[KinematicNode]] = self._part("joints", "JOINT_MODES")
        return modes

    @cached_property
    def design(self) -> ModuleDesign:
        """The simulated module: the kind's geometry, bearing, sucker and colour."""
        from .design import ModuleDesign

        return ModuleDesign.from_spec(self.spec, self.spec.module_kinds[0].name,
                                      bearing=self.bearing, sucker=self.sucker is not None,
                                      rgba=self.rgba)

    def driver_factory(self) -> FreeformDriverFactory:
        """The ``mujoco`` driver factory (one object, registered on every call)."""
        if self._driver is None:
            from .driver import FreeformDriverFactory

            self._driver = FreeformDriverFactory(self.design, self.driver_description)
        return self._driver

    def recognizer(self) -> ContactRecognizer:
        """The recognizer, named as the robot (module reports only)."""
        from .recognition import ContactRecognizer

        return ContactRecognizer(self.spec.name, self.spec.module_kinds[0].name)

    def controllers(self) -> list[ContactController]:
        """One controller per joint mode, named as the mode's ``controller``; the
        ``sucker`` mode's engages the sucker. They share the recognizer and what they know
        of latched pieces (:class:`~msrr.core.freeform.recognition.Latches`), so they hold
        the same connections and give one reach measure."""
        from functools import partial

        from .recognition import ContactController, Latches
        from .world import FreeformOptions, place

        shared, latches = self.recognizer(), Latches()
        # centre distance of a docked pair, and the start laid out as the world lays it
        # (the lab's placement of the start file)
        spacing = 2.0 * self.design.radius + FreeformOptions().gap
        layout = partial(place, length=spacing, radius=self.design.radius)
        # a piece's shells roll under their arms on their bearings (FreeBOT), its fastest
        # centre at 80 % of a shell's rolling bound, the rest for the motors' loops
        piece = 0.8 * self.design.max_rate * self.design.radius if self.design.bearing else 0.0
        return [ContactController(mode.controller, shared, sucker=mode.name == self.sucker,
                                  spacing=spacing, piece_speed=piece, layout=layout,
                                  bends=self.bends, latches=latches)
                for mode in self.joint_modes()]

    # -- hooks --------------------------------------------------------------------------

    @hookimpl
    def msrr_robot(self) -> RobotSpec:
        return self.spec

    @hookimpl
    def msrr_docking_rules(self, robot: str) -> DockingRules | None:
        from ..robot import MisoRules

        return MisoRules(robot) if robot == self.spec.name else None

    @hookimpl
    def msrr_kinematic_nodes(self, robot: str, register: Register[type[KinematicNode]]
                             ) -> None:
        if robot == self.spec.name:
            for mode in self.joint_modes():
                register(mode)

    @hookimpl
    def msrr_planners(self, robot: str, register: Register[Planner]) -> None:
        if robot == self.spec.name:
            from .miso import MisoLimits, miso_planners

            def layout(config: Configuration) -> dict[str, np.ndarray]:
                """The world's layout of ``config`` (module centres, the world's default
                gap), so the planner pairs pieces of one shape by where they lie when the
                start file says where its modules are (no simulator imported)."""
                from .layout import DOCK_GAP, place

                radius = self.design.radius
                return place(config, 2.0 * radius + DOCK_GAP, radius)[0]

            for planner in miso_planners(MisoLimits(**self.miso_rules), layout):
                register(planner)

    @hookimpl
    def msrr_drivers(self, robot: str, register: Register[DriverFactory]) -> None:
        if robot == self.spec.name:
            register(self.driver_factory())

    @hookimpl
    def msrr_recognizers(self, robot: str, register: Register[Recognizer]) -> None:
        if robot == self.spec.name:
            register(self.recognizer())

    @hookimpl
    def msrr_controllers(self, robot: str, register: Register[Controller]) -> None:
        if robot == self.spec.name:
            for controller in self.controllers():
                register(controller)

    @hookimpl
    def msrr_scenarios(self, robot: str, register: Register[Scenario]) -> None:
        if robot == self.spec.name:
            scenarios: Sequence[Scenario] = self._part("scenarios", "SCENARIOS")
            for scenario in scenarios:
                register(scenario)
