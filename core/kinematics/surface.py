"""Motion of a contact over a sphere's surface, shared by rolling and crawling joints.

A module whose connector travels over another module's spherical shell (FreeBOT's
rolling contact, SnailBot's crawling) moves its contact direction ``z`` along a
geodesic; :class:`TangentMotion` parametrises that travel by geodesic-normal
coordinates in the tangent plane at ``z`` and gives the rotation and its derivatives.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .rotations import canonical_perpendicular, cross, exp_so3, left_jacobian, normalize, skew

__all__ = ["TangentMotion", "moved"]


@dataclass
class TangentMotion:
    """A contact point moved along a geodesic of the parent sphere, batched over rows.

    ``sigma``
    are the geodesic-normal coordinates of the new contact direction in the tangent
    plane at ``z`` (``e1`` along the forward vector, ``e2 = z x e1``).

    Attributes:
        e1, e2: tangent basis, shape (N, 3).
        w: rotation vector ``z x v`` of the contact's travel, shape (N, 3).
        theta: ``|w|`` [rad], shape (N,).
        dw: ``dw/dsigma = [e2, -e1]``, shape (N, 3, 2).
        rot: ``exp(hat(w))``, shape (N, 3, 3).
        z: ``z^joint = rot z``, shape (N, 3).
    """

    e1: np.ndarray
    e2: np.ndarray
    w: np.ndarray
    theta: np.ndarray
    dw: np.ndarray
    rot: np.ndarray
    z: np.ndarray

    @classmethod
    def of(cls, z: np.ndarray, x: np.ndarray, sigma: np.ndarray) -> TangentMotion:
        """The motion of contacts ``z`` (N, 3) with forward vectors ``x`` (N, 3) by
        ``sigma`` (N, 2)."""
        xp = x - np.einsum("ni,ni->n", x, z)[:, None] * z
        e1, norm = normalize(xp)
        bad = norm < 1e-9
        if bad.any():
            e1[bad] = canonical_perpendicular(z[bad])
        e2 = cross(z, e1)
        w = sigma[:, :1] * e2 - sigma[:, 1:2] * e1
        rot = exp_so3(w)
        return cls(e1, e2, w, np.linalg.norm(sigma, axis=1), np.stack([e2, -e1], axis=-1),
                   rot, np.einsum("nab,nb->na", rot, z))

    def travel_gradient(self, sigma: np.ndarray) -> np.ndarray:
        """``d theta / d sigma = sigma / theta``, zero at ``sigma = 0``; shape (N, 2)."""
        return sigma / np.maximum(self.theta, 1e-300)[:, None] * (self.theta > 0)[:, None]

    def omega(self, scale: float = 1.0) -> np.ndarray:
        """Angular velocity of ``exp(scale hat(w))`` per sigma, ``scale J(scale w) dw``;
        shape (N, 3, 2)."""
        return scale * left_jacobian(scale * self.w) @ self.dw


def moved(vectors: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """``d v / d sigma = omega x v`` for vectors ``v`` (N, 3) and ``omega`` (N, 3, d);
    shape (N, 3, d)."""
    return -np.einsum("nab,nbd->nad", skew(vectors), omega)
