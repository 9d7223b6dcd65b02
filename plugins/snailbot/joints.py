"""SnailBot joint modes: crawling over another module, and locked by the vacuum sucker.

A SnailBot's foot (tracks or a magnet-embedded rocker-bogie) lies flat on another
module's shell (the *substrate*), so relative to the substrate the SnailBot turns
about the substrate's centre: a spherical joint (FreeSN paper section 2.1). The
connection ``source -> target`` runs from the SnailBot to its substrate and ``z``, like
every connection vector, points from the source (the SnailBot) towards the target's
centre; the joint's motion does not depend on that sign.

* :class:`SphericalJoint` (``spherical``, the default): ``sigma = (s1, s2, psi)``; the
  foot travels along the geodesic with normal coordinates ``(s1, s2)`` (forward along
  ``x``, left) and the body turns by ``psi`` about the new normal:

      w = z x (s1 e1 + s2 e2),  theta = |(s1, s2)|      (e1, e2 as in the FreeBOT joint)
      R = exp(hat(w)) rodrigues(z, psi) = rodrigues(z^joint, psi) exp(hat(w))
      z^joint = exp(hat(w)) z,   x^joint = R x,   portRot = R
      C = theta + alpha |psi|

  with ``omega_{s_i} = J(w) dw/ds_i`` (left Jacobian, see
  :mod:`msrr.core.kinematics.surface`) and ``omega_psi = z^joint``.

  The joint sits at the substrate's centre. When the kinematic tree reaches the
  SnailBot first (the substrate is the node's child, parameter
  ``substrate_is_child = 1``), the SnailBot and its connection vector stay put and the
  substrate turns about its own centre by the inverse motion:
  ``z^joint = z``, ``x^joint = x``, ``portRot = R^T``, ``omega = -R^T omega``.
  :meth:`SphericalJoint.for_edge` sets the parameter from the edge's direction, so
  :func:`~msrr.core.kinematics.default_tree` builds the right joint for either end.

* :class:`SuckerRevoluteJoint` (``sucker_revolute``): the vacuum sucker locks the foot;
  the SnailBot only turns about the sucker axis, which is the contact normal ``z``
  (it passes through both centres, so the motion is the same from either end):
  ``portRot = rodrigues(z, sigma)``, ``z^joint = z``, ``x^joint = portRot x``,
  ``C = |sigma|`` -- the core revolute joint (FreeSN eq. 1) under the SnailBot's name.
"""

from __future__ import annotations

import numpy as np

from msrr.core.configuration import Edge
from msrr.core.kinematics.joints import RevoluteJoint
from msrr.core.kinematics.node import ModuleJointNode, NodeBatch
from msrr.core.kinematics.rotations import rodrigues
from msrr.core.kinematics.surface import TangentMotion, moved

__all__ = ["JOINT_MODES", "SphericalJoint", "SuckerRevoluteJoint"]


class SphericalJoint(ModuleJointNode):
    """SnailBot crawling on its substrate: a spherical joint (module docstring).

    ``sigma`` (3,): geodesic-normal coordinates of the foot's travel [rad] (forward,
    left) and the turn about the normal [rad]. Parameters: ``alpha`` weight of turning
    in the cost (0.5), ``bound`` [rad] per coordinate (pi), ``substrate_is_child``
    (0 or 1, see :meth:`for_edge`).
    """

    name = "spherical"
    dim = 3
    controller = "snailbot.spherical"
    description = "crawl over the substrate's shell and turn about the contact normal"
    defaults = {"alpha": 0.5, "bound": float(np.pi), "substrate_is_child": 0.0}

    @classmethod
    def for_edge(cls, edge: Edge, reached: str) -> SphericalJoint:
        """The joint about the substrate's centre: the substrate is the node's child
        when the tree reaches the connection's target (the substrate) through it."""
        return cls([edge.id], [reached], substrate_is_child=float(reached == edge.target))

    @classmethod
    def evaluate(cls, z, x, sigma, params, n_ports, derivatives, context=None):
        z1, x1 = z[:, 0], x[:, 0]
        motion = TangentMotion.of(z1, x1, sigma[:, :2])
        psi = sigma[:, 2]
        rot = motion.rot @ rodrigues(z1, psi)
        cost = motion.theta + params["alpha"] * np.abs(psi)
        reverse = params["substrate_is_child"] > 0.5
        if reverse:
            zj, xj, port = z1, x1, np.swapaxes(rot, -1, -2)
        else:
            zj, xj, port = motion.z, np.einsum("nab,nb->na", rot, x1), rot
        out = NodeBatch(zj[:, None], xj[:, None], cost[:, None], port[:, None])
        if derivatives:
            omega = np.concatenate([motion.omega(), motion.z[:, :, None]], axis=-1)
            if reverse:
                out.dz = np.zeros((len(z1), 1, 3, 3))
                out.dx = np.zeros((len(z1), 1, 3, 3))
                out.omega = -np.einsum("nba,nbd->nad", rot, omega)[:, None]
            else:
                out.dz = moved(zj, omega)[:, None]
                out.dx = moved(xj, omega)[:, None]
                out.omega = omega[:, None]
            dcost = np.concatenate([motion.travel_gradient(sigma[:, :2]),
                                    params["alpha"] * np.sign(psi)[:, None]], axis=1)
            out.dcost = dcost[:, None]
        return out


class SuckerRevoluteJoint(RevoluteJoint):
    """SnailBot locked by its vacuum sucker: rotation by ``sigma`` [rad] about ``z``.

    The sucker axis is the contact normal, so this is the core revolute joint (FreeSN
    eq. 1, ``C = |sigma|``) with the SnailBot's controller.
    """

    name = "sucker_revolute"
    controller = "snailbot.sucker_revolute"
    description = "locked by the vacuum sucker; turns only about the sucker axis"


JOINT_MODES: tuple[type, ...] = (SphericalJoint, SuckerRevoluteJoint)
"""SnailBot node types in registration order; the first is the default joint mode."""

