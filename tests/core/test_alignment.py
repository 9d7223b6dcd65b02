"""Yaw alignment (eq. 8) against a dense brute-force grid, and yaw recovery."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from msrr.core.alignment import align_yaw, median_yaw, rot_z, wrap_angle


def _units(rng: np.random.Generator, n: int) -> np.ndarray:
    v = rng.normal(size=(3, n))
    return v / np.linalg.norm(v, axis=0)


_ROTATIONS = np.stack([rot_z(t) for t in np.linspace(-np.pi, np.pi, 20001)])
"""Full rotation matrices of 20001 yaws, for the brute force."""


def _brute_force(z, zt, w, x=None, xt=None, gamma=0.0) -> float:
    """The smallest eq. 8 cost over 20001 yaws, with full rotation matrices."""

    def cost(a, b):
        dots = np.einsum("in,kin->kn", a, _ROTATIONS @ b)
        return (np.arccos(np.clip(dots, -1.0, 1.0)) ** 2) @ w

    total = cost(z, zt) + (gamma * cost(x, xt) if x is not None else 0.0)
    return float(total.min())


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 12), with_x=st.booleans())
def test_minimum_is_global(seed: int, n: int, with_x: bool) -> None:
    rng = np.random.default_rng(seed)
    z, zt, w = _units(rng, n), _units(rng, n), rng.uniform(0.1, 2.0, n)
    x, xt = (_units(rng, n), _units(rng, n)) if with_x else (None, None)
    gamma = 0.7 if with_x else 0.0
    found = align_yaw(z, zt, weights=w, x=x, x_target=xt, gamma=gamma)
    assert found.cost <= _brute_force(z, zt, w, x, xt, gamma) + 1e-6


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 12), yaw=st.floats(-3.1, 3.1))
def test_a_yaw_rotated_copy_is_aligned_with_the_right_yaw(seed: int, n: int, yaw: float) -> None:
    z = _units(np.random.default_rng(seed), n)
    if np.linalg.norm(z[:2], axis=0).max() < 1e-3:  # all vertical: any yaw fits
        return
    found = align_yaw(z, rot_z(-yaw) @ z)
    assert abs(np.angle(np.exp(1j * (found.theta - yaw)))) < 1e-6
    assert found.rms_angle < 1e-6



def test_near_keeps_the_local_minimum_it_starts_in() -> None:
    """Two minima (one rod each way, a third tilting the balance): ``near`` stays in the
    basin it is given, so a tracked yaw never jumps to the other, slightly lower one."""
    def level(*degrees: float) -> np.ndarray:
        a = np.radians(degrees)
        return np.stack([np.cos(a), np.sin(a), np.zeros_like(a)])

    z, zt, w = level(0.0, 180.0, 80.0), level(0.0, 0.0, 90.0), np.array([1.0, 1.1, 0.1])

    def cost(theta: float) -> float:
        dots = np.einsum("in,in->n", z, rot_z(theta) @ zt)
        return float((np.arccos(np.clip(dots, -1.0, 1.0)) ** 2) @ w)

    best = align_yaw(z, zt, weights=w)
    kept = align_yaw(z, zt, weights=w, near=1.5)
    assert best.theta < 0 < kept.theta and kept.cost > best.cost + 0.01
    assert kept.cost == pytest.approx(cost(kept.theta))
    assert kept.cost < min(cost(kept.theta - 1e-3), cost(kept.theta + 1e-3))  # refined
    assert align_yaw(z, zt, weights=w, near=-1.5).theta == pytest.approx(best.theta)


@pytest.mark.parametrize("seed", range(20))
@pytest.mark.parametrize("n", [1, 2, 5, 8])
def test_the_median_yaw_with_equal_weights_is_numpys_median_of_the_turns(seed: int,
                                                                          n: int) -> None:
    """With equal weights the weighted median is ``np.median`` of the wrapped turns, to
    the bit (an even count: the midpoint of the two middle ones); a weight that outweighs
    the rest decides alone."""
    rng = np.random.default_rng(seed)
    z, z_target = rng.normal(size=(3, n)), rng.normal(size=(3, n))
    z /= np.linalg.norm(z, axis=0)
    z_target /= np.linalg.norm(z_target, axis=0)
    flat = (np.hypot(z[0], z[1]) >= 0.2) & (np.hypot(z_target[0], z_target[1]) >= 0.2)
    turns = wrap_angle(np.arctan2(z[1], z[0]) - np.arctan2(z_target[1], z_target[0]))[flat]
    got = median_yaw(z, z_target)
    if not flat.any():
        assert got is None
        return
    assert got == float(np.median(turns))
    heavy = np.ones(n)
    heavy[int(np.flatnonzero(flat)[0])] = 10.0 * n
    assert median_yaw(z, z_target, weights=heavy) == pytest.approx(float(turns[0]))
