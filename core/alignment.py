"""Yaw alignment of two sets of unit vectors about the vertical axis (FreeSN paper, eq. 8).

Two skeletal configurations measured in different horizontal frames differ by a yaw
angle ``theta``. :func:`align_yaw` finds the ``theta`` that minimises

    sum_j w_j [ gamma * arccos(x_j . Rz(theta) x*_j)^2 + arccos(z_j . Rz(theta) z*_j)^2 ]

(eq. 8) and reports the aligned distance. It is shared by the inverse kinematics (yaw
initialisation) and the isomorphism tree search (``vectorMatch``, Alg. 3).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

__all__ = ["YawAlignment", "align_yaw", "angles_between", "rot_z"]


def rot_z(theta: float) -> np.ndarray:
    """Rotation matrix about z by ``theta`` [rad], shape (3, 3)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def angles_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angles [rad] between corresponding unit column vectors of ``a`` and ``b``, shape (n,)."""
    return np.arccos(np.clip(np.einsum("ij,ij->j", a, b), -1.0, 1.0))


@dataclass(frozen=True)
class YawAlignment:
    """Result of :func:`align_yaw`.

    Attributes:
        theta: yaw [rad] that rotates the target onto the current vectors.
        cost: the eq. 8 objective at ``theta``.
        rms_angle: root-mean-square angle [rad] over every aligned vector (z and x).
    """

    theta: float
    cost: float
    rms_angle: float


def _objective(theta: float, z: np.ndarray, zt: np.ndarray, w: np.ndarray,
               x: np.ndarray | None, xt: np.ndarray | None, gamma: float) -> float:
    r = rot_z(theta)
    cost = float(np.sum(w * angles_between(z, r @ zt) ** 2))
    if x is not None and xt is not None and gamma:
        cost += gamma * float(np.sum(w * angles_between(x, r @ xt) ** 2))
    return cost


def align_yaw(z: np.ndarray, z_target: np.ndarray, *, weights: np.ndarray | None = None,
              x: np.ndarray | None = None, x_target: np.ndarray | None = None,
              gamma: float = 0.0) -> YawAlignment:
    """Yaw that best aligns ``z_target`` (and ``x_target``) with ``z`` (and ``x``), eq. 8.

    A closed-form start (the yaw that maximises the weighted sum of horizontal dot
    products, a 2-D Procrustes problem) is refined by bounded Brent search on the
    arccos-squared objective within +-pi of it.

    Args:
        z: current unit vectors, shape (3, n).
        z_target: target unit vectors in their own horizontal frame, shape (3, n).
        weights: per-column weights, shape (n,); ones by default.
        x: current forward vectors, shape (3, n), optional.
        x_target: target forward vectors, shape (3, n), optional.
        gamma: weight of the forward-vector term.

    Returns:
        The yaw ``theta`` such that ``rot_z(theta) @ z_target`` matches ``z``.
    """
    z = np.asarray(z, dtype=np.float64).reshape(3, -1)
    zt = np.asarray(z_target, dtype=np.float64).reshape(3, -1)
    n = z.shape[1]
    w = np.ones(n) if weights is None else np.asarray(weights, dtype=np.float64)
    if n == 0:
        return YawAlignment(0.0, 0.0, 0.0)
    use_x = x is not None and x_target is not None and gamma > 0.0
    a, b = (np.hstack([z, x]), np.hstack([zt, x_target])) if use_x else (z, zt)
    wa = np.concatenate([w, gamma * w]) if use_x else w
    # maximise sum w (a . Rz b) over the horizontal components: atan2 of cross and dot sums
    sin_sum = float(np.sum(wa * (b[0] * a[1] - b[1] * a[0])))
    cos_sum = float(np.sum(wa * (b[0] * a[0] + b[1] * a[1])))
    start = float(np.arctan2(sin_sum, cos_sum))
    args = (z, zt, w, x if use_x else None, x_target if use_x else None, gamma)
    best = minimize_scalar(_objective, bounds=(start - np.pi, start + np.pi), args=args,
                           method="bounded", options={"xatol": 1e-9})
    theta, cost = float(best.x), float(best.fun)
    start_cost = _objective(start, *args)
    if start_cost <= cost:
        theta, cost = start, start_cost
    theta = float(np.arctan2(np.sin(theta), np.cos(theta)))
    r = rot_z(theta)
    angles = angles_between(z, r @ zt)
    if use_x:
        angles = np.concatenate([angles, angles_between(x, r @ x_target)])
    return YawAlignment(theta, cost, float(np.sqrt(np.mean(angles ** 2))))
