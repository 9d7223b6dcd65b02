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

import numpy as np

from msrr.core.kinematics.node import ModuleJointNode, NodeBatch
from msrr.core.kinematics.rotations import exp_so3
from msrr.core.kinematics.surface import TangentMotion, moved

__all__ = [
    "JOINT_MODES",
    "RollingContactJoint",
]

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
