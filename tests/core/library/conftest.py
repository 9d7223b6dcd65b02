"""Shared fixtures of the library tests: a library built from the S6N3 sources."""

from __future__ import annotations

import pytest

from msrr.core.library import Library, build_library, load_sources
from msrr.core.plugins import resolve

from library_helpers import source_files


@pytest.fixture(scope="session")
def s6n3() -> Library:
    return build_library(load_sources(source_files("S6N3"), resolve), resolve("freesn"),
                         cost="distance")
