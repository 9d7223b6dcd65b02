"""Rodrigues' formula (eq. 2) in both forms, with its singular cases, and the helpers."""

from __future__ import annotations

import numpy as np
import pytest
from kin_helpers import central_difference, random_units, relative_error

from msrr.core.kinematics import (
    canonical_perpendicular,
    rodrigues,
    rotation_between,
    rotation_between_omega,
    skew,
    vee,
)
from msrr.core.kinematics.rotations import cross, exp_so3, left_jacobian


def is_rotation(r: np.ndarray) -> bool:
    return np.allclose(r @ r.T, np.eye(3), atol=1e-12) and np.isclose(np.linalg.det(r), 1.0)


def test_skew_vee_and_cross_agree_with_numpy():
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(5, 3)), rng.normal(size=(5, 3))
    assert np.allclose(skew(a) @ b[:, :, None], np.cross(a, b)[:, :, None])
    assert np.allclose(cross(a, b), np.cross(a, b))
    assert np.allclose(vee(skew(a)), a)


def test_rodrigues_about_an_axis():
    rng = np.random.default_rng(1)
    k = random_units(rng, 4).T
    theta = rng.uniform(-np.pi, np.pi, 4)
    r = rodrigues(k, theta)
    for i in range(4):
        assert is_rotation(r[i])
        assert np.allclose(r[i] @ k[i], k[i])
        v = canonical_perpendicular(k[i])
        assert np.isclose(np.arccos(np.clip(v @ r[i] @ v, -1, 1)), abs(theta[i]))
    assert np.array_equal(rodrigues(k[0], 0.0), np.eye(3))  # exact at zero


def test_rotation_between_maps_one_vector_onto_the_other():
    rng = np.random.default_rng(2)
    v, w = random_units(rng, 6).T, random_units(rng, 6).T
    r = rotation_between(v, w)
    for i in range(6):
        assert is_rotation(r[i])
        assert np.allclose(r[i] @ v[i], w[i])
        axis = np.cross(v[i], w[i])
        assert np.allclose(r[i] @ axis, axis)  # minimal: about v x w


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_rotation_between_singular_cases(sign):
    rng = np.random.default_rng(3)
    v = random_units(rng, 1)[:, 0]
    r = rotation_between(v, sign * v)
    assert is_rotation(r)
    assert np.allclose(r @ v, sign * v)
    if sign > 0:
        assert np.allclose(r, np.eye(3))       # parallel: identity
    else:
        assert np.isclose(np.trace(r), -1.0)   # antiparallel: a half turn


def test_rotation_between_nearly_parallel_is_smooth():
    v = np.array([0.0, 0.0, 1.0])
    w = np.array([1e-9, 0.0, 1.0])
    w /= np.linalg.norm(w)
    r = rotation_between(v, w)
    assert is_rotation(r) and np.allclose(r @ v, w)


def test_rotation_between_omega_matches_finite_differences():
    rng = np.random.default_rng(4)
    for _ in range(10):
        v, w = random_units(rng, 2).T
        direction = rng.normal(size=(3, 2))  # two parameters moving w on the sphere

        def target(p: np.ndarray, w=w, direction=direction) -> np.ndarray:
            u = w + direction @ p
            return u / np.linalg.norm(u)

        def rot(p: np.ndarray, v=v, target=target) -> np.ndarray:
            return rotation_between(v, target(p))

        p0 = np.zeros(2)
        dw = central_difference(target, p0)
        omega = rotation_between_omega(v, w, dw)
        analytic = np.einsum("dab,bc->acd", skew(omega.T), rot(p0))
        assert relative_error(analytic, central_difference(rot, p0)) < 1e-6


def test_canonical_perpendicular_is_unit_and_perpendicular():
    rng = np.random.default_rng(5)
    v = random_units(rng, 20).T
    p = canonical_perpendicular(v)
    assert np.allclose(np.linalg.norm(p, axis=1), 1.0)
    assert np.allclose(np.einsum("ni,ni->n", p, v), 0.0)


def test_left_jacobian_is_the_derivative_of_the_exponential():
    rng = np.random.default_rng(3)
    for _ in range(10):
        phi, dphi, h = rng.normal(size=3), rng.normal(size=3), 1e-6
        numeric = (exp_so3(phi + h * dphi) - exp_so3(phi - h * dphi)) / (2 * h)
        analytic = skew(left_jacobian(phi) @ dphi) @ exp_so3(phi)
        assert np.allclose(numeric, analytic, atol=1e-8)


def test_exp_so3_is_rodrigues():
    rng = np.random.default_rng(4)
    for _ in range(10):
        phi = rng.normal(size=3)
        angle = np.linalg.norm(phi)
        assert np.allclose(exp_so3(phi), rodrigues(phi / angle, angle), atol=1e-12)
    assert np.array_equal(exp_so3(np.zeros(3)), np.eye(3))
