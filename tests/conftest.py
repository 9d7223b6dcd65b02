"""Shared fixtures: every installed robot, and their shipped configuration files."""

from __future__ import annotations

from pathlib import Path

import pytest

from msrr.core import plugins

ROOT = Path(__file__).resolve().parents[1]


def installed_robots() -> list[str]:
    return list(plugins.robots())


def shipped_configurations() -> list[Path]:
    """Every configuration file shipped with a built-in robot plugin or the example."""
    files = sorted((ROOT / "plugins").glob("*/configs/*.json"))
    return files + sorted((ROOT / "examples").glob("*/*/configs/*.json"))


@pytest.fixture(params=installed_robots())
def robot_name(request: pytest.FixtureRequest) -> str:
    """Runs a test once per installed robot (built-in and third-party)."""
    return request.param
