"""Rotation helpers of the skeletal kinematics, batched over leading axes.

Rodrigues' rotation formula in its two forms (FreeSN paper, eq. 2): about an axis by
an angle, and the minimal rotation that takes one unit vector onto another. The
second form is written as ``I + W + W^2 / (1 + c)`` with ``W = hat(v x v')`` and
``c = v . v'``, which is smooth everywhere except at antiparallel vectors, so the
parallel case (``theta = 0``, identity) needs no special branch and has correct
derivatives; the antiparallel case is a rotation by pi about a canonical axis
perpendicular to ``v`` (its derivative does not exist and is returned as zero).

Every function takes arrays with any number of leading axes; vectors are the last
axis (size 3) and matrices the last two (3 x 3).
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "ANTIPARALLEL_TOLERANCE",
    "canonical_perpendicular",
    "cross",
    "einsum",
    "exp_so3",
    "left_jacobian",
    "normalize",
    "rodrigues",
    "rotation_between",
    "rotation_between_omega",
    "skew",
    "vee",
]

ANTIPARALLEL_TOLERANCE = 1e-12
"""``1 + v . v'`` below this counts as antiparallel in :func:`rotation_between`."""

_EYE = np.eye(3)
_NEXT = np.array([1, 2, 0])
_PREV = np.array([2, 0, 1])


_LEVI_CIVITA = np.zeros((3, 3, 3))
_LEVI_CIVITA[0, 1, 2] = _LEVI_CIVITA[1, 2, 0] = _LEVI_CIVITA[2, 0, 1] = 1.0
_LEVI_CIVITA[0, 2, 1] = _LEVI_CIVITA[2, 1, 0] = _LEVI_CIVITA[1, 0, 2] = -1.0
_HAT = -_LEVI_CIVITA  # hat(v)[i, j] = -eps[i, j, k] v[k]
# hat(v) row by row: the component of v in each entry and its sign (0 on the diagonal)
_HAT_INDEX = np.array([0, 2, 1, 2, 0, 0, 1, 0, 0])
_HAT_SIGN = np.array([0.0, -1.0, 1.0, 1.0, 0.0, -1.0, -1.0, 1.0, 0.0])

# einsum: numpy's C einsum, what np.einsum(..., optimize=False) calls behind its Python
# layers (dispatch, argument checks; half the time of a call on 3-12 rows), so the same
# products and sums in the same order. The IK's inner loop makes ~20 such calls.
try:
    from numpy._core.multiarray import c_einsum as einsum
except ImportError:  # pragma: no cover - another numpy layout
    einsum = np.einsum


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product along the last axis; like ``np.cross`` but faster for small arrays."""
    return a.take(_NEXT, -1) * b.take(_PREV, -1) - a.take(_PREV, -1) * b.take(_NEXT, -1)


def skew(v: np.ndarray) -> np.ndarray:
    """The hat operation: ``skew(v) @ u == cross(v, u)``; shape (..., 3) -> (..., 3, 3)."""
    v = np.asarray(v, dtype=np.float64)
    # each entry is +-v[k] or 0: what einsum("ijk,...k->...ij", _HAT, v) sums to, to the bit
    # (its sums start at +0, hence + 0.0: a zero entry is +0 there too)
    return (v[..., _HAT_INDEX] * _HAT_SIGN + 0.0).reshape(*v.shape[:-1], 3, 3)


def vee(m: np.ndarray) -> np.ndarray:
    """The vector of the skew-symmetric part of ``m``; shape (..., 3, 3) -> (..., 3)."""
    m = np.asarray(m, dtype=np.float64)
    return 0.5 * np.stack([m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0],
                           m[..., 1, 0] - m[..., 0, 1]], axis=-1)


def normalize(v: np.ndarray, tiny: float = 1e-300) -> tuple[np.ndarray, np.ndarray]:
    """``(v / |v|, |v|)`` along the last axis; a zero vector stays zero."""
    norm = np.linalg.norm(v, axis=-1)
    return v / np.maximum(norm, tiny)[..., None], norm


def canonical_perpendicular(v: np.ndarray) -> np.ndarray:
    """A unit vector perpendicular to each ``v`` (shape (..., 3)), chosen deterministically.

    ``v`` is crossed with the coordinate axis it is least aligned with.
    """
    v = np.asarray(v, dtype=np.float64)
    axes = _EYE[np.argmin(np.abs(v), axis=-1)]
    return normalize(np.cross(v, axes))[0]


def rodrigues(axis: np.ndarray, angle: np.ndarray | float) -> np.ndarray:
    """Rotation about unit ``axis`` (..., 3) by ``angle`` [rad] (...), eq. 2; (..., 3, 3).

    ``R = cos(theta) I + (1 - cos(theta)) k k^T + sin(theta) hat(k)``, written as
    ``I + sin(theta) K + (1 - cos(theta)) K^2`` so that ``angle == 0`` gives exactly I.
    """
    k = skew(axis)
    angle = np.asarray(angle, dtype=np.float64)[..., None, None]
    return _EYE + np.sin(angle) * k + (1.0 - np.cos(angle)) * (k @ k)


def rotation_between(v: np.ndarray, v2: np.ndarray) -> np.ndarray:
    """The minimal rotation taking unit ``v`` onto unit ``v2`` (eq. 2), shape (..., 3, 3).

    Parallel vectors give the identity; antiparallel ones a rotation by pi about
    :func:`canonical_perpendicular` of ``v``.
    """
    v = np.asarray(v, dtype=np.float64)
    v2 = np.asarray(v2, dtype=np.float64)
    w = cross(v, v2)
    c = einsum("...i,...i->...", v, v2)
    one_plus_c = 1.0 + c
    flip = one_plus_c < ANTIPARALLEL_TOLERANCE
    # I + W + W^2 / (1 + c) == c I + W + w w^T / (1 + c) for unit v, v2
    rot = (c[..., None, None] * _EYE + skew(w)
           + w[..., :, None] * w[..., None, :] / np.where(flip, 1.0, one_plus_c)[..., None, None])
    if np.any(flip):
        p = canonical_perpendicular(v)
        half_turn = 2.0 * p[..., :, None] * p[..., None, :] - _EYE
        rot = np.where(flip[..., None, None], half_turn, rot)
    return rot


def rotation_between_omega(v: np.ndarray, v2: np.ndarray, dv2: np.ndarray) -> np.ndarray:
    """Angular velocity of :func:`rotation_between` ``(v, v2)`` when ``v2`` moves by ``dv2``.

    With ``R(v2)`` the minimal rotation from fixed ``v`` onto ``v2`` and ``dv2`` a
    tangent of the unit sphere at ``v2``, ``dR = hat(omega) R`` with

        omega = v2 x dv2 - ((v x v2) . dv2) / (1 + v . v2) * v2.

    Args:
        v: fixed unit vectors, shape (..., 3).
        v2: unit vectors, shape (..., 3).
        dv2: derivatives of ``v2``, shape (..., 3, d) (one column per parameter).

    Returns:
        omega, shape (..., 3, d); zero where the vectors are antiparallel.
    """
    one_plus_c = 1.0 + einsum("...i,...i->...", v, v2)
    flip = one_plus_c < ANTIPARALLEL_TOLERANCE
    axis = cross(v, v2)
    twist = einsum("...i,...id->...d", axis, dv2) / np.where(flip, 1.0, one_plus_c)[..., None]
    omega = (cross(v2[..., None, :], np.swapaxes(dv2, -1, -2)).swapaxes(-1, -2)
             - twist[..., None, :] * v2[..., :, None])
    return np.where(flip[..., None, None], 0.0, omega)


_SMALL = 1e-4  # below this angle [rad] the series forms of the coefficients are used


def _coefficients(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``sin(a)/a``, ``(1 - cos a)/a^2`` and ``(a - sin a)/a^3``, exact series near 0."""
    a = np.asarray(theta, dtype=np.float64)
    small = a < _SMALL
    safe = np.where(small, 1.0, a)
    a2 = a * a
    s = np.where(small, 1.0 - a2 / 6.0, np.sin(safe) / safe)
    c = np.where(small, 0.5 - a2 / 24.0, (1.0 - np.cos(safe)) / (safe * safe))
    d = np.where(small, 1.0 / 6.0 - a2 / 120.0, (safe - np.sin(safe)) / safe ** 3)
    return s, c, d


def exp_so3(phi: np.ndarray) -> np.ndarray:
    """``exp(hat(phi))``: rotation by ``|phi|`` [rad] about ``phi``; (..., 3) -> (..., 3, 3).

    Smooth at ``phi = 0`` (exactly the identity there).
    """
    phi = np.asarray(phi, dtype=np.float64)
    s, c, _ = _coefficients(np.linalg.norm(phi, axis=-1))
    k = skew(phi)
    return _EYE + s[..., None, None] * k + c[..., None, None] * (k @ k)


def left_jacobian(phi: np.ndarray) -> np.ndarray:
    """Left Jacobian of SO(3): ``d exp(hat(phi)) = hat(J(phi) dphi) exp(hat(phi))``.

    ``J = I + (1 - cos a)/a^2 hat(phi) + (a - sin a)/a^3 hat(phi)^2``, ``a = |phi|``;
    shape (..., 3) -> (..., 3, 3).
    """
    phi = np.asarray(phi, dtype=np.float64)
    _, c, d = _coefficients(np.linalg.norm(phi, axis=-1))
    k = skew(phi)
    return _EYE + c[..., None, None] * k + d[..., None, None] * (k @ k)
