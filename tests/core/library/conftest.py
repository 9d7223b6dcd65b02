"""Shared fixtures of the core library tests: a library of the ``stick`` test robot."""

from __future__ import annotations

import pytest
from stick_library import STICK, stick_sources

from msrr.core.library import Library, build_library


@pytest.fixture(scope="session")
def stick_lib() -> Library:
    return build_library(stick_sources(), STICK, cost="distance")
