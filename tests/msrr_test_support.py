"""Paths and collections shared by tests in several folders (imported by name)."""

from __future__ import annotations

from pathlib import Path

from msrr.core import plugins

ROOT = Path(__file__).resolve().parents[1]


BUILTIN_ROBOTS = ("freebot", "freesn", "mmrp", "snailbot")
"""The robots this repository ships; each ships at least one configuration file."""


def installed_robots() -> list[str]:
    """Every installed robot: built-in, the example, and any third-party plugin."""
    return list(plugins.robots())


def shipped_configurations() -> list[Path]:
    """Every configuration file shipped with a built-in robot plugin or the example."""
    files = sorted((ROOT / "plugins").glob("*/configs/*.json"))
    return files + sorted((ROOT / "examples").glob("*/*/configs/*.json"))
