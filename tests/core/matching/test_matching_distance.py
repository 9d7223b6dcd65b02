"""The distance bound of partial mappings is admissible and the distance monotone."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from msrr.core.alignment import rot_z
from msrr.core.matching import PartialBound, vector_match
from msrr.core.matching.distance import bound_terms, elevation

GRID = np.linspace(-np.pi, np.pi, 3601)


def _units(rng, n):
    v = rng.normal(size=(3, n))
    return v / np.linalg.norm(v, axis=0)


def _grid_min(z, y):
    """Eq. 8 cost minimised over a 0.1 degree yaw grid (an upper bound of the minimum)."""
    c, s = np.cos(GRID)[:, None], np.sin(GRID)[:, None]
    rotated_x, rotated_y = c * y[0] - s * y[1], s * y[0] + c * y[1]
    dots = z[0] * rotated_x + z[1] * rotated_y + z[2] * y[2]
    return float(np.min(np.sum(np.arccos(np.clip(dots, -1.0, 1.0)) ** 2, axis=1)))


def _bound(z, y):
    bound = PartialBound()
    for j in range(z.shape[1]):
        bound = bound.add(bound_terms(tuple(z[:, j]), tuple(y[:, j]), elevation(z[:, j]),
                                      elevation(y[:, j])))
    return bound.value()


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 10), st.floats(0.0, 2.0))
def test_bound_is_below_the_aligned_distance(seed, n, noise):
    rng = np.random.default_rng(seed)
    z = _units(rng, n)
    y = rot_z(rng.uniform(-3, 3)) @ z + noise * rng.normal(size=(3, n))
    y /= np.linalg.norm(y, axis=0)
    bound = _bound(z, y)
    assert bound <= vector_match(z, y).cost
    assert bound <= _grid_min(z, y) + 1e-12


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(2, 8))
def test_sub_configuration_distance_is_monotone(seed, n):
    rng = np.random.default_rng(seed)
    z, y = _units(rng, n), _units(rng, n)
    minima = [_grid_min(z[:, :k], y[:, :k]) for k in range(1, n + 1)]
    assert all(a <= b + 1e-12 for a, b in zip(minima, minima[1:], strict=False))


def test_bound_is_tight_for_identical_vectors():
    rng = np.random.default_rng(0)
    z = _units(rng, 6)
    assert _bound(z, rot_z(0.7) @ z) < 1e-9
