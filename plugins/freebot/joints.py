"""FreeBOT joint mode: the spherical rolling contact (SRC) joint (Zong et al. 2022).

One sphere (radius ``r_c``, the child) rolls without slipping and without spinning
over another (radius ``r_p``, the parent). Let ``u`` be the unit direction between
the two centres (the connection vector ``z``, in the parent's frame) and ``omega`` the
child's angular velocity relative to the parent. The child's centre is at
``p = (r_p + r_c) u``, the contact point at ``c = r_p u``; no slip at the contact and
no spin about the normal give

    p' + omega x (c - p) = 0   and   omega . u = 0
    =>  (r_p + r_c) u' = r_c omega x u   =>   omega = k (u x u'),   k = 1 + r_p / r_c.

Along the geodesic that takes ``u`` from ``z`` to ``z^joint`` (constant rotation axis
``n``, angle ``theta``) ``omega = k theta' n`` is constant in direction, so the child
turns by ``k theta`` about ``n`` while its centre turns by ``theta`` about the parent:
for equal radii (``k = 2``) the child rotates **twice** the angle its centre travels
(the coin-rotation paradox). For equal radii the rolling is even holonomic: a turn by
``2 theta`` about ``n`` is the product of two half-turns, ``portRot = H(z^joint) H(z)``
with ``H(u) = 2 u u^T - I``, so the orientation depends only on the end points (the
tests check this against integrated rolling); for unequal radii it depends on the path,
and the node follows the geodesic. The joint space is the geodesic-normal coordinates of
the new contact direction in the tangent plane at ``z``:

    e1 = normalise(x - (x . z) z),  e2 = z x e1        (tangent basis; x the forward vector)
    v  = sigma_1 e1 + sigma_2 e2,   w = z x v,   theta = |w| = |sigma|
    z^joint = exp(hat(w)) z = cos(theta) z + sin(theta) v / theta
    portRot = exp(k hat(w))                              (the child's rolling rotation)
    x^joint = exp(hat(w)) x                              (the drive heading, parallel transport)
    C       = theta                                      (angle the contact travels)

Derivatives use the left Jacobian of SO(3), ``J(phi) = I + (1 - cos a)/a^2 hat(phi) +
(a - sin a)/a^3 hat(phi)^2`` (``a = |phi|``), for which ``d exp(hat(phi)) =
hat(J(phi) dphi) exp(hat(phi))``: with ``dw/dsigma = [e2, -e1]``,

    omega_i        = k J(k w) dw/dsigma_i                (port angular velocity)
    dz^joint/dsigma_i = (J(w) dw/dsigma_i) x z^joint,  same for x^joint
    dC/dsigma      = sigma / theta  (0 at sigma = 0).

Rolling is symmetric in the two bodies, so the node is the same whichever end of the
connection the tree reaches first (the axis of ``w`` is unchanged by ``z -> -z``);
only ``k`` depends on which sphere is the parent (``radius_ratio = r_p / r_c``, 1 for
identical FreeBOTs).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from msrr.core.kinematics.node import ModuleJointNode, NodeBatch
from msrr.core.kinematics.rotations import canonical_perpendicular, cross, normalize, skew

__all__ = [
    "JOINT_MODES",
    "RollingContactJoint",
    "TangentMotion",
    "exp_so3",
    "left_jacobian",
]

_EYE = np.eye(3)
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


@dataclass
class TangentMotion:
    """A contact point moved along a geodesic of the parent sphere, batched over rows.

    Shared by the FreeBOT rolling contact and the SnailBot spherical joint: ``sigma``
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


class RollingContactJoint(ModuleJointNode):
    """FreeBOT's spherical rolling contact joint (module docstring for the equations).

    ``sigma`` (2,): geodesic-normal coordinates [rad] of the new contact direction,
    forward (along ``x``) and left. The child rolls: ``portRot = exp(k hat(w))`` with
    ``k = 1 + radius_ratio`` (twice the travel for equal spheres).

    Parameters: ``radius_ratio`` = parent radius / child radius (1), ``bound`` [rad]
    per coordinate (pi).
    """

    name = "rolling_contact"
    dim = 2
    controller = "freebot.rolling_contact"
    description = "the sphere rolls without slipping over its parent (SRC joint)"
    defaults = {"radius_ratio": 1.0, "bound": float(np.pi)}

    @classmethod
    def evaluate(cls, z, x, sigma, params, n_ports, derivatives, context=None):
        z1, x1 = z[:, 0], x[:, 0]
        k = 1.0 + params["radius_ratio"]
        motion = TangentMotion.of(z1, x1, sigma)
        xj = np.einsum("nab,nb->na", motion.rot, x1)
        port = exp_so3(k * motion.w)
        out = NodeBatch(motion.z[:, None], xj[:, None], motion.theta[:, None], port[:, None])
        if derivatives:
            travel = motion.omega()
            out.dz = moved(motion.z, travel)[:, None]
            out.dx = moved(xj, travel)[:, None]
            out.dcost = motion.travel_gradient(sigma)[:, None]
            out.omega = motion.omega(k)[:, None]
        return out


JOINT_MODES: tuple[type, ...] = (RollingContactJoint,)
"""FreeBOT node types in registration order; the first is the default joint mode."""
