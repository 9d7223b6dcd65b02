"""What the generic runtime's modules report and take, without the driver that
simulates them: the controller and the recognizer read these, never the driver's state
(:mod:`msrr.core.witness`)."""

from __future__ import annotations

from dataclasses import dataclass

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
    """What one module reports: its kind and the latches it is the source of."""

    kind: str
    latches: tuple[Latch, ...] = ()
