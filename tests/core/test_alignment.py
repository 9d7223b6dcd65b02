"""Yaw alignment (eq. 8) against a dense brute-force grid, and yaw recovery."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from msrr.core.alignment import align_yaw, rot_z


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
