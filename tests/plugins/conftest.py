"""Fixtures of the robot plugins' tests."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest

from msrr.core import plugins
from msrr.core.driver import Driver
from msrr.core.io import load_configuration

from msrr_test_support import ROOT


@pytest.fixture
def mujoco_driver() -> Iterator[Callable[..., Any]]:
    """``mujoco_driver(robot, name, **options)``: the robot's ``mujoco`` driver with
    ``options``, connected and reset to its shipped configuration ``name``; disconnected
    after the test."""
    made: list[Driver] = []

    def make(robot: str, name: str, **options: Any) -> Any:
        driver = plugins.drivers.get(robot, "mujoco")(**options)
        made.append(driver)
        driver.connect()
        driver.reset(load_configuration(ROOT / "plugins" / robot / "configs" / f"{name}.json"))
        return driver

    yield make
    for driver in made:
        driver.disconnect()


@pytest.fixture
def contact() -> Callable[[np.random.Generator], tuple[np.ndarray, np.ndarray]]:
    """``contact(rng)``: a random unit ``z`` and a unit forward vector ``x``
    perpendicular to it, each (3, 1) (a connection of a freeform joint)."""

    def draw(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        z = rng.normal(size=3)
        z /= np.linalg.norm(z)
        x = rng.normal(size=3)
        x -= x.dot(z) * z
        return z[:, None], (x / np.linalg.norm(x))[:, None]

    return draw
