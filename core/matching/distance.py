"""Distances between mapped configurations: ``vectorMatch`` and its admissible bounds.

The distance of a (partial) mapping is the eq. 8 cost of the mapped connection
vectors at the best yaw, ``d(E) = min_theta sum_{j in E} arccos(z_j . Rz(theta) y_j)^2``,
where ``y_j`` is the mapped reference vector, negated for an inverted edge.
:func:`vector_match` evaluates it with :func:`msrr.core.alignment.align_yaw`
(``vectorMatch`` of Alg. 3).

Monotonicity: for ``E' subset of E`` and every ``theta`` the sum over ``E`` is at least
the sum over ``E'`` (the extra terms are squares), so ``d(E') <= d(E)``; a partial
mapping's distance never exceeds that of any completion. The search keys partial
mappings with a cheap lower bound of ``d`` (:class:`PartialBound`), which keeps that
property and therefore best-first order (Alg. 2): an arc is at least its chord,
``alpha^2 >= |z - R y|^2``, whose minimum over ``theta`` is closed form (2-D
Procrustes), and the angle between two vectors is at least the difference of their
elevations, whatever the yaw.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..alignment import YawAlignment, align_yaw

__all__ = ["PartialBound", "bound_terms", "elevation", "vector_match"]

BOUND_SLACK = 1e-9
"""Relative slack taken off the bound so rounding never lifts it above ``d``."""


def vector_match(z_sys: np.ndarray, z_ref: np.ndarray, *, x_sys: np.ndarray | None = None,
                 x_ref: np.ndarray | None = None, gamma: float = 0.0) -> YawAlignment:
    """Aligned distance of two mapped vector sets (``vectorMatch``, Alg. 3 line 23; eq. 8).

    Args:
        z_sys: system connection vectors, shape (3, n).
        z_ref: mapped reference vectors (negated where inverted), shape (3, n).
        x_sys: system forward vectors, shape (3, n), optional.
        x_ref: mapped reference forward vectors, shape (3, n), optional.
        gamma: weight of the forward-vector term (0 for skeletal configurations).
    """
    return align_yaw(z_sys, z_ref, x=x_sys, x_target=x_ref, gamma=gamma)


def elevation(z: np.ndarray | tuple[float, float, float]) -> float:
    """Elevation [rad] of a unit vector above the horizontal plane."""
    return math.asin(max(-1.0, min(1.0, float(z[2]))))


def bound_terms(z_sys: tuple[float, float, float], z_ref: tuple[float, float, float],
                elevation_sys: float, elevation_ref: float
                ) -> tuple[float, float, float, float]:
    """Terms one mapped edge adds to a :class:`PartialBound`.

    Args:
        z_sys: system vector.
        z_ref: mapped reference vector (negated when inverted).
        elevation_sys: :func:`elevation` of ``z_sys``.
        elevation_ref: :func:`elevation` of ``z_ref``.

    Returns:
        ``(cos, sin, vertical, elevation)``: the horizontal dot and cross products, the
        product of vertical components and the squared elevation difference [rad^2].
    """
    return (z_sys[0] * z_ref[0] + z_sys[1] * z_ref[1],
            z_sys[1] * z_ref[0] - z_sys[0] * z_ref[1],
            z_sys[2] * z_ref[2],
            (elevation_sys - elevation_ref) ** 2)


@dataclass(frozen=True)
class PartialBound:
    """Running sums of a lower bound of the distance of a partial mapping.

    Attributes:
        n: number of mapped edges with vectors.
        cos: sum of horizontal dot products.
        sin: sum of horizontal cross products (z component).
        vertical: sum of products of vertical components.
        elevation: sum of squared elevation differences [rad^2].
    """

    n: int = 0
    cos: float = 0.0
    sin: float = 0.0
    vertical: float = 0.0
    elevation: float = 0.0

    def add(self, terms: tuple[float, float, float, float]) -> PartialBound:
        """The bound with one more mapped edge, ``terms`` from :func:`bound_terms`."""
        c, s, v, e = terms
        return PartialBound(self.n + 1, self.cos + c, self.sin + s, self.vertical + v,
                            self.elevation + e)

    def value(self) -> float:
        """Lower bound [rad^2] of the eq. 8 distance of the mapped edges."""
        chord = 2.0 * (self.n - self.vertical - math.hypot(self.cos, self.sin))
        best = max(chord, self.elevation)
        return max(0.0, best * (1.0 - BOUND_SLACK) - BOUND_SLACK)
