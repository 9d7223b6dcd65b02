"""Yaw alignment of two sets of unit vectors about the vertical axis (FreeSN paper, eq. 8).

Two skeletal configurations measured in different horizontal frames differ by a yaw
angle ``theta``. :func:`align_yaw` finds the ``theta`` that minimises

    sum_j w_j [ gamma * arccos(x_j . Rz(theta) x*_j)^2 + arccos(z_j . Rz(theta) z*_j)^2 ]

(eq. 8) and reports the aligned distance. It is shared by the inverse kinematics (yaw
initialisation) and the isomorphism tree search (``vectorMatch``, Alg. 3).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import overload

import numpy as np
from scipy.optimize import minimize_scalar

__all__ = ["YawAlignment", "align_yaw", "angles_between", "best_turn", "median_yaw", "rot_z",
           "rot_zs", "wrap_angle"]


def rot_z(theta: float) -> np.ndarray:
    """Rotation matrix about z by ``theta`` [rad], shape (3, 3)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rot_zs(theta: np.ndarray) -> np.ndarray:
    """Rotation matrices about z by each of ``theta`` (n,) [rad], shape (n, 3, 3): each
    :func:`rot_z`'s, to the bit."""
    c, s = np.cos(theta), np.sin(theta)
    out = np.zeros((len(c), 3, 3))
    out[:, 0, 0], out[:, 0, 1], out[:, 1, 0], out[:, 1, 1] = c, -s, s, c
    out[:, 2, 2] = 1.0
    return out


@overload
def wrap_angle(angle: float) -> float: ...
@overload
def wrap_angle(angle: np.ndarray) -> np.ndarray: ...
def wrap_angle(angle: float | np.ndarray) -> float | np.ndarray:
    """``angle`` [rad] wrapped into [-pi, pi): a float for a float, an array for an array."""
    wrapped = (np.asarray(angle, dtype=np.float64) + np.pi) % (2.0 * np.pi) - np.pi
    return float(wrapped) if wrapped.ndim == 0 else wrapped


def best_turn(a: np.ndarray, b: np.ndarray) -> float:
    """The yaw [rad] that best turns the points ``a`` (n, 2) onto ``b`` (n, 2), each set
    about its own mean (least squares, weighted alike: the 2-D Kabsch rotation)."""
    a, b = a - a.mean(axis=0), b - b.mean(axis=0)
    return float(np.arctan2(np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]),
                            np.sum(a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1])))


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


def _dot_terms(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Coefficients with ``a_j . rot_z(theta) b_j = p_j cos(theta) + q_j sin(theta) + r_j``."""
    p = a[0] * b[0] + a[1] * b[1]
    q = a[1] * b[0] - a[0] * b[1]
    return p, q, a[2] * b[2]


def _downhill(grid_costs: np.ndarray, near: float) -> int:
    """The grid cell of the local minimum reached downhill from the cell nearest ``near``."""
    k = len(grid_costs)
    i = int(round((wrap_angle(float(near)) - GRID[0]) / (GRID[1] - GRID[0]))) % k
    while True:
        left, right = grid_costs[(i - 1) % k], grid_costs[(i + 1) % k]
        if min(left, right) >= grid_costs[i]:
            return i
        i = (i - 1) % k if left < right else (i + 1) % k


def _costs(thetas: np.ndarray, p: np.ndarray, q: np.ndarray, r: np.ndarray, w: np.ndarray
           ) -> np.ndarray:
    """The eq. 8 objective at each yaw of ``thetas``, shape (k,)."""
    dots = np.cos(thetas)[:, None] * p + np.sin(thetas)[:, None] * q + r
    # np.clip's value without its Python layers: the bounded search calls this ~20 times
    return (np.arccos(np.minimum(np.maximum(dots, -1.0), 1.0)) ** 2) @ w


GRID = np.linspace(-np.pi, np.pi, 72, endpoint=False)
"""Coarse yaw grid (5 degree steps) that brackets the global minimum before refinement."""


def align_yaw(z: np.ndarray, z_target: np.ndarray, *, weights: np.ndarray | None = None,
              x: np.ndarray | None = None, x_target: np.ndarray | None = None,
              gamma: float = 0.0, near: float | None = None) -> YawAlignment:
    """Yaw that best aligns ``z_target`` (and ``x_target``) with ``z`` (and ``x``), eq. 8.

    The objective is a sum of squared arc lengths, each a function of
    ``p cos(theta) + q sin(theta) + r``; it is evaluated on a 5-degree grid (vectorised),
    and the two best grid cells are refined by bounded Brent search, so the global
    minimum is found unless two minima lie within one cell of each other.

    Args:
        z: current unit vectors, shape (3, n).
        z_target: target unit vectors in their own horizontal frame, shape (3, n).
        weights: per-column weights, shape (n,); ones by default.
        x: current forward vectors, shape (3, n), optional.
        x_target: target forward vectors, shape (3, n), optional.
        gamma: weight of the forward-vector term.
        near: if given [rad], the local minimum whose basin holds this yaw (downhill on
            the grid from it, then refined) instead of the global one: a yaw that
            follows a moving configuration continuously, never jumping to another
            minimum that has become slightly lower.

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
    p, q, r = _dot_terms(a, b)
    grid_costs = _costs(GRID, p, q, r, wa)
    step = GRID[1] - GRID[0]
    best_theta, best_cost = 0.0, np.inf
    cells = np.argsort(grid_costs)[:2] if near is None else [_downhill(grid_costs, near)]
    for i in cells:
        result = minimize_scalar(lambda t: float(_costs(np.array([t]), p, q, r, wa)[0]),
                                 bounds=(GRID[i] - step, GRID[i] + step), method="bounded",
                                 options={"xatol": 1e-10})
        theta, cost = (float(result.x), float(result.fun))
        if grid_costs[i] < cost:
            theta, cost = float(GRID[i]), float(grid_costs[i])
        if cost < best_cost:
            best_theta, best_cost = theta, cost
    theta = float(np.arctan2(np.sin(best_theta), np.cos(best_theta)))
    angles = np.arccos(np.clip(p * np.cos(theta) + q * np.sin(theta) + r, -1.0, 1.0))
    return YawAlignment(theta, best_cost, float(np.sqrt(np.mean(angles ** 2))))


FLAT = 0.2
"""Horizontal length under which a unit vector has no yaw of its own (:func:`median_yaw`)."""


def median_yaw(z: np.ndarray, z_target: np.ndarray, *, weights: np.ndarray | None = None,
               near: float = 0.0) -> float | None:
    """The weighted median of the yaws [rad] that turn each column of ``z_target`` onto
    the same column of ``z`` about the vertical (shapes (3, n)), wrapped about ``near``;
    ``None`` when no column has a horizontal part of at least :data:`FLAT` in both. Where
    the weights split exactly in half, the midpoint of the two middle yaws (with equal
    weights, ``np.median``'s).

    Robust where eq. 8's least squares (:func:`align_yaw`) is not: while part of the
    vectors is far from its target, eq. 8's yaw turns the whole target part of the way
    towards it, and the rest is told to turn; the median stays with the majority.
    """
    z = np.asarray(z, dtype=np.float64).reshape(3, -1)
    zt = np.asarray(z_target, dtype=np.float64).reshape(3, -1)
    w = np.ones(z.shape[1]) if weights is None else np.asarray(weights, dtype=np.float64)
    flat = (np.hypot(z[0], z[1]) >= FLAT) & (np.hypot(zt[0], zt[1]) >= FLAT) & (w > 0)
    if not np.any(flat):
        return None
    turns = wrap_angle(np.arctan2(z[1, flat], z[0, flat]) - np.arctan2(zt[1, flat], zt[0, flat])
                       - near) + near
    order = np.argsort(turns, kind="stable")
    cumulative = np.cumsum(w[flat][order])
    half = 0.5 * cumulative[-1]
    i = int(np.searchsorted(cumulative, half))
    ordered = turns[order]
    middle = 0.5 * (ordered[i] + ordered[i + 1]) if cumulative[i] == half \
        and i + 1 < len(ordered) else ordered[i]
    return float(middle) if -np.pi <= middle < np.pi else float(wrap_angle(float(middle)))
