"""The latch recognizer: the configuration that the modules' latched ports report.

It reads only :attr:`Observation.sensors <msrr.core.driver.Observation.sensors>` in
the format of the kinematic driver (per module a
:class:`~msrr.core.generic.driver.ModuleReading`), never a simulator's state: every
latch a module reports as its source becomes a connection with the two ports and the
sensed direction ``z``; an edge module (a FreeSN strut) becomes an edge between the
modules its two ends are latched to, a free end resting on a virtual vertex named by
:func:`msrr.core.mapping.free_vertex_name`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..configuration import Configuration
from ..errors import ConfigurationError
from ..mapping import free_vertex_name
from ..robot import RobotSpec
from .readings import ModuleReading

__all__ = ["LatchRecognizer"]


class LatchRecognizer:
    """Latched ports to a :class:`Configuration` of robot ``spec`` (see the module docstring)."""

    name = "latches"
    description = "latched ports to a configuration (generic runtime)"
    generic = True

    def __init__(self, spec: RobotSpec):
        self.spec = spec

    def recognize(self, sensors: Mapping[str, Any], *, seed: int = 0) -> Configuration:
        """The configuration ``sensors`` shows, in the modules' own ids.

        Raises:
            ConfigurationError: a reading that is not a ``ModuleReading``, or a latch to a
                module that reported nothing.
        """
        config = Configuration(self.spec.name)
        edge_kinds = {k.name for k in self.spec.kinds_with_role("edge")}
        readings: dict[str, ModuleReading] = {}
        for module, reading in sensors.items():
            if not isinstance(reading, ModuleReading):
                raise ConfigurationError(f"module {module}: the latch recognizer reads "
                                         f"ModuleReading sensors, got {type(reading).__name__}")
            readings[module] = reading
            if reading.kind not in edge_kinds:
                config.add_module(module, reading.kind)
        for module, reading in readings.items():
            if reading.kind in edge_kinds:
                self._edge_module(config, module, reading)
                continue
            for latch in reading.latches:
                if latch.other not in config.graph:
                    raise ConfigurationError(f"module {module} reports a latch to {latch.other}, "
                                             "which reported nothing")
                ports = (None if latch.port is None or latch.other_port is None
                         else (latch.port, latch.other_port))
                config.connect(module, latch.other, z=latch.z, ports=ports)
        return config

    @staticmethod
    def _edge_module(config: Configuration, module: str, reading: ModuleReading) -> None:
        ends: dict[str, str] = {}
        z = None
        for latch in reading.latches:
            ends[latch.port or ""] = latch.other
            z = latch.z if latch.z is not None else z
        vertices = []
        for end, at_source in (("a", True), ("b", False)):
            vertex = ends.get(end)
            if vertex is None:
                vertex = free_vertex_name(module, at_source, set(config.vertices()))
                config.add_virtual(vertex)
            vertices.append(vertex)
        config.connect(vertices[0], vertices[1], id=module, kind=reading.kind, z=z)
