"""Fixtures for the whole suite: the same tests run once per installed robot."""

from __future__ import annotations

import pytest

from msrr_test_support import installed_robots


@pytest.fixture(params=installed_robots())
def robot_name(request: pytest.FixtureRequest) -> str:
    """Runs a test once per installed robot (built-in and third-party)."""
    return request.param
