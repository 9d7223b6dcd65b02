"""What the generic runtime's modules report and take, without the driver that
simulates them: the controller and the recognizer read these, never the driver's state
(:mod:`msrr.core.witness`)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

__all__ = ["FREEFORM_PREFIX", "SLIDE_KEYS", "Latch", "ModuleReading"]

FREEFORM_PREFIX = "@"
"""Dock/undock commands for connections without ports name the other module: ``"@b"``."""

SLIDE_KEYS = ("slide_x", "slide_y", "slide_z")


@dataclass(frozen=True)
class Latch:
    """One connection as the module at its source end senses it.

    Attributes:
        port: this module's port (``"a"``/``"b"`` for the ends of an edge module), or
            ``None`` for a freeform connector.
        other: the module it is latched to.
        other_port: that module's port, or ``None``.
        z: unit direction from this module to the other, world frame, or ``None``.
    """

    port: str | None
    other: str
    other_port: str | None
    z: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class ModuleReading:
    """What one module reports: its kind and the latches it is the source of; in a
    physics driver also its joint encoders (hinge port -> angle [rad]) and its IMU's
    orientation (unit quaternion ``(w, x, y, z)``, world frame)."""

    kind: str
    latches: tuple[Latch, ...] = ()
    joints: Mapping[str, float] = field(default_factory=dict)
    imu: tuple[float, float, float, float] | None = None
