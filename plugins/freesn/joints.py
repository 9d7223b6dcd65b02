"""FreeSN joint modes: kinematic node types of a strut (paper Figs. 6-7, eqs. 1-5).

A strut whose two connectors roll on node spheres is two spherical joints in series;
the modes below restrict it to useful motions. In every module-joint mode the node
has one edge (the strut, vector ``z`` from the parent node towards the child) and
owns the vertex the strut reaches.

* :class:`RevoluteJoint` (Fig. 6a, eq. 1): rotation by ``sigma`` about ``z``.
* :class:`DifferentialSphericalJoint` (Fig. 6b, eq. 3): steer, then move forward;
  ``z^joint = normalise(z + sigma)``, ``sigma`` in R^3.
* :class:`OppositeSteeringJoint` (Fig. 6c, eq. 4, the default): the same motion, the
  opposite connector cancels the steering, so subsequent nodes rotate only by the
  minimal rotation ``z -> z^joint``.
* :class:`FullOppositeJoint` (Fig. 6d): every opposite motion, subsequent nodes keep
  their orientation; twice the cost of the differential spherical mode.
* :class:`ParallelStrutNode` (Fig. 7, eq. 5): two struts from two nodes of the parent
  to one child node act as two parallel revolute joints about the parent nodes' axis;
  ``beta`` weighs the second one.

Steering costs (the ``alpha`` terms of eqs. 3-5) are undefined at zero motion (the
steering direction ``x^steer`` is ``0/0``); they are faded in by ``r^2 / (r^2 + eps^2)``
with ``r`` the size of the motion and ``eps = steer_epsilon`` [rad], which keeps
``C(0) = 0`` and the objective continuous. For the differential spherical mode the
steering rotation is faded the same way so that its forward kinematics is continuous.
"""

from __future__ import annotations

import numpy as np

from msrr.core.kinematics.joints import RevoluteJoint as CoreRevoluteJoint
from msrr.core.kinematics.node import (
    KinematicTreeError,
    ModuleJointNode,
    NodeBatch,
    ParallelNode,
    fade,
)
from msrr.core.kinematics.rotations import (
    ANTIPARALLEL_TOLERANCE,
    canonical_perpendicular,
    cross,
    normalize,
    rodrigues,
    rotation_between,
    skew,
)

__all__ = [
    "JOINT_MODES",
    "DifferentialSphericalJoint",
    "FullOppositeJoint",
    "OppositeSteeringJoint",
    "ParallelStrutNode",
    "PlantedJoint",
    "RevoluteJoint",
    "SwingJoint",
]

_EYE = np.eye(3)
_TINY = 1e-12


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ni,ni->n", a, b)


class _Spherical:
    """Shared pieces of the spherical modes: move ``z -> normalise(z + sigma)``, steer.

    Closed forms (rows are nodes; ``nu = |z + sigma|``, ``c = z . z^joint``,
    ``w = z x z^joint``, ``P = I - z^joint z^joint^T``):

    * ``R = c I + hat(w) + w w^T / (1 + c)`` (eq. 2, minimal rotation ``z -> z^joint``);
    * ``d z^joint / d sigma = P / nu``;
    * port angular velocity ``omega = (hat(z^joint) - z^joint w^T / (1 + c)) / nu``
      (:func:`~msrr.core.kinematics.rotations.rotation_between_omega` with
      ``dv2 = P / nu``);
    * ``d angle(z, z^joint) / d sigma = -(z - c z^joint) / (nu |w|)``;
    * steering angle ``phi = atan2((z x x) . x^steer, x . x^steer)`` with
      ``x^steer = P_z sigma / |P_z sigma|`` and ``d x^steer = (I - xs xs^T) P_z / r``.
    """

    def __init__(self, z: np.ndarray, x: np.ndarray, s: np.ndarray, eps: float,
                 derivatives: bool, context: tuple[np.ndarray, np.ndarray] | None = None):
        zx, xp = context if context is not None else self.prepare(z, x)
        self.z = z
        still = ~s.any(axis=1)
        any_still = bool(still.any())
        u = z + s
        nu = np.sqrt(_dot(u, u))
        if any_still:
            nu[still] = 1.0
        inv_nu = 1.0 / nu
        zj = u * inv_nu[:, None]
        if any_still:
            zj[still] = z[still]
        c = _dot(z, zj)
        w = cross(z, zj)
        sw = np.sqrt(_dot(w, w))
        one_plus_c = 1.0 + c
        flip = one_plus_c.min() < ANTIPARALLEL_TOLERANCE
        if flip:  # antiparallel: a half turn (rotation_between), no derivative
            bad = one_plus_c < ANTIPARALLEL_TOLERANCE
            one_plus_c[bad] = np.inf
        wk = w / one_plus_c[:, None]
        rot = skew(w) + w[:, :, None] * wk[:, None, :]
        rot += c[:, None, None] * _EYE
        if flip:
            rot[bad] = rotation_between(z[bad], zj[bad])
        if any_still:
            rot[still] = _EYE
        self.still, self.zj, self.rot = still, zj, rot
        self.angle = np.arctan2(sw, c)
        # steering: the motion's component perpendicular to z gives x^steer
        sp = s - _dot(s, z)[:, None] * z
        r2 = _dot(sp, sp)
        moving = r2 > _TINY * _TINY
        inv_r = moving / np.sqrt(np.maximum(r2, _TINY * _TINY))
        xs = sp * inv_r[:, None]
        a_ = _dot(zx, xs)
        b_ = _dot(x, xs)
        self.phi = np.arctan2(a_, b_)  # signed steering angle about z, from x to x^steer
        e2 = eps * eps
        inv_den = 1.0 / (r2 + e2) if e2 > 0 else moving / np.maximum(r2, _TINY)
        self.fade = r2 * inv_den
        if not derivatives:
            return
        self.dzj = (_EYE - zj[:, :, None] * zj[:, None, :]) * inv_nu[:, None, None]
        self.omega = (skew(zj) - zj[:, :, None] * wk[:, None, :]) * inv_nu[:, None, None]
        ok = sw > _TINY
        self.dangle = (c[:, None] * zj - z) * (ok * inv_nu / np.maximum(sw, _TINY))[:, None]
        da_ = (zx - a_[:, None] * xs) * inv_r[:, None]
        db_ = (xp - b_[:, None] * xs) * inv_r[:, None]
        h2 = a_ * a_ + b_ * b_
        ih2 = (h2 > _TINY) / np.maximum(h2, _TINY)
        self.dphi = (b_[:, None] * da_ - a_[:, None] * db_) * ih2[:, None]
        self.dfade = (2.0 * e2 * inv_den * inv_den)[:, None] * sp  # zero at sigma = 0

    @staticmethod
    def prepare(z: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``z x x`` and ``x`` projected off ``z``: constants of the steering angle."""
        return cross(z, x), x - _dot(x, z)[:, None] * z

    def steer_cost(self) -> tuple[np.ndarray, np.ndarray | None]:
        """``|phi| * fade`` and, when derivatives were computed, its gradient (N, 3)."""
        b = np.abs(self.phi)
        value = b * self.fade
        if not hasattr(self, "dphi"):
            return value, None
        grad = (np.sign(self.phi) * self.fade)[:, None] * self.dphi + b[:, None] * self.dfade
        return value, grad


class _SphericalJoint(ModuleJointNode):
    """A strut connector mode with ``sigma`` in R^3 (eqs. 3-4): base of three modes."""

    dim = 3
    defaults = {"alpha": 0.1, "steer_epsilon": 0.05, "bound": 2.0}
    steer_factor = 1.0   # multiple of alpha on the steering cost
    cost_factor = 1.0    # multiple of the whole cost

    @classmethod
    def prepare(cls, z, x, params):
        return _Spherical.prepare(z[:, 0], x[:, 0])

    @classmethod
    def evaluate(cls, z, x, sigma, params, n_ports, derivatives, context=None):
        z1, x1 = z[:, 0], x[:, 0]
        sph = _Spherical(z1, x1, sigma, params["steer_epsilon"], derivatives, context)
        steer, dsteer = sph.steer_cost()
        alpha = params["alpha"] * cls.steer_factor
        cost = cls.cost_factor * (sph.angle + alpha * steer)
        rot, omega = cls._port(sph, derivatives)
        xj = np.einsum("nab,nb->na", cls._vector_rotation(sph), x1)
        out = NodeBatch(sph.zj[:, None], xj[:, None], cost[:, None], rot[:, None])
        if derivatives:
            assert dsteer is not None
            out.dz = sph.dzj[:, None]
            # d x^joint = omega x x^joint = -hat(x^joint) omega
            out.dx = -(skew(xj) @ cls._vector_omega(sph))[:, None]
            out.dcost = (cls.cost_factor * (sph.dangle + alpha * dsteer))[:, None]
            out.omega = omega[:, None]
        return out

    @classmethod
    def _vector_rotation(cls, sph: _Spherical) -> np.ndarray:
        return sph.rot

    @classmethod
    def _vector_omega(cls, sph: _Spherical) -> np.ndarray:
        return sph.omega

    @classmethod
    def _port(cls, sph: _Spherical, derivatives: bool) -> tuple[np.ndarray, np.ndarray]:
        return sph.rot, (sph.omega if derivatives else None)


class OppositeSteeringJoint(_SphericalJoint):
    """Opposite steering mode (Fig. 6c, eq. 4), FreeSN's default joint.

    ``z^joint = normalise(z + sigma)``, ``R = rodrigues(z, z^joint)`` rotates the
    subsequent nodes and ``x``; ``C = angle(z, z^joint) + 2 alpha angle(x, x^steer)``.
    """

    name = "opposite_steering"
    controller = "freesn.opposite_steering"
    description = "move the connector on the node, steering cancelled by the opposite one"
    steer_factor = 2.0


class DifferentialSphericalJoint(_SphericalJoint):
    """Differential spherical mode (Fig. 6b, eq. 3): steer about ``z``, then move.

    ``R = rodrigues(z, z^joint) rodrigues(x, x^steer)``; the steering rotates the
    subsequent nodes too. ``C = angle(z, z^joint) + alpha angle(x, x^steer)``.
    """

    name = "differential_spherical"
    controller = "freesn.differential_spherical"
    description = "one differential drive: steer towards the target, then drive"

    @classmethod
    def _steer(cls, sph: _Spherical) -> np.ndarray:
        """Steering rotation about z by the faded steering angle, shape (N, 3, 3)."""
        return rodrigues(sph.z, sph.phi * sph.fade)

    @classmethod
    def _vector_rotation(cls, sph: _Spherical) -> np.ndarray:
        return sph.rot @ cls._steer(sph)

    @classmethod
    def _vector_omega(cls, sph: _Spherical) -> np.ndarray:
        # omega = omega1 + R1 (z d(phi f)) = omega1 + z^joint d(phi f)
        dturn = sph.dphi * sph.fade[:, None] + sph.phi[:, None] * sph.dfade
        return sph.omega + sph.zj[:, :, None] * dturn[:, None, :]

    @classmethod
    def _port(cls, sph, derivatives):
        return cls._vector_rotation(sph), (cls._vector_omega(sph) if derivatives else None)


class FullOppositeJoint(_SphericalJoint):
    """Full opposite mode (Fig. 6d): subsequent nodes keep their orientation.

    The strut moves as in the differential spherical mode (``x`` follows the minimal
    rotation) but every motion is mirrored by the opposite connector: the port
    rotation is the identity and the cost twice that of eq. 3.
    """

    name = "full_opposite"
    controller = "freesn.full_opposite"
    description = "every motion mirrored by the opposite connector; the child keeps its attitude"
    cost_factor = 2.0

    @classmethod
    def _port(cls, sph, derivatives):
        n = len(sph.zj)
        return (np.broadcast_to(_EYE, (n, 3, 3)).copy(),
                np.zeros((n, 3, 3)) if derivatives else None)


class RevoluteJoint(CoreRevoluteJoint):
    """Revolute mode (Fig. 6a, eq. 1): both connectors turn about the strut axis."""

    controller = "freesn.revolute"
    description = "both connectors turn about the strut axis"


class ParallelStrutNode(ParallelNode):
    """Parallel strut node (Fig. 7, eq. 5): two struts from two parent nodes to one node.

    Edges ``(M1, M2)`` run from two nodes of the parent (the axis) to the node this
    kinematic node owns. With ``x^joint = normalise(z1 - z2)`` the hinge axis,
    ``sigma_1`` turns both struts about it and ``sigma_2`` turns the owned node (and
    its subtree) further; ``C_i = 2 alpha angle(x_i, x^steer) + |sigma_1| + beta |sigma_2|``
    with ``x^steer = normalise(z1 x z2)``.
    """

    name = "parallel_strut"
    dim = 2
    controller = "freesn.parallel_strut"
    description = "two struts sharing a node turn together about their parent nodes' axis"
    defaults = {"alpha": 0.1, "beta": 1.0, "steer_epsilon": 0.05, "bound": float(np.pi)}

    def validate(self) -> None:
        if len(self.edges) != 2 or len(self.vertices) != 1:
            raise KinematicTreeError(
                f"{self.name} node: needs two edges and one vertex, got edges "
                f"{list(self.edges)} and vertices {list(self.vertices)}")

    @classmethod
    def evaluate(cls, z, x, sigma, params, n_ports, derivatives, context=None):
        n = len(z)
        z1, z2 = z[:, 0], z[:, 1]
        axis, norm = normalize(z1 - z2)
        degenerate = norm < _TINY
        axis[degenerate] = canonical_perpendicular(z1[degenerate])
        steer, snorm = normalize(cross(z1, z2))
        flat = snorm < _TINY
        steer[flat] = canonical_perpendicular(z1[flat])
        s1, s2 = sigma[:, 0], sigma[:, 1]
        r1 = rodrigues(axis, s1)
        rot = rodrigues(axis, s1 + s2)
        zj = np.einsum("nab,nmb->nma", r1, z)
        xj = np.einsum("nab,nmb->nma", r1, x)
        turn = np.arccos(np.clip(np.einsum("nmi,ni->nm", x, steer), -1.0, 1.0))
        f, dfade = fade(s1 * s1 + s2 * s2, params["steer_epsilon"])
        alpha, beta = params["alpha"], params["beta"]
        cost = 2.0 * alpha * turn * f[:, None] + (np.abs(s1) + beta * np.abs(s2))[:, None]
        out = NodeBatch(zj, xj, cost, np.broadcast_to(rot[:, None], (n, n_ports, 3, 3)).copy())
        if derivatives:
            d1 = cross(axis[:, None, :], zj)
            out.dz = np.stack([d1, np.zeros_like(d1)], axis=-1)
            dx1 = cross(axis[:, None, :], xj)
            out.dx = np.stack([dx1, np.zeros_like(dx1)], axis=-1)
            df = 2.0 * dfade[:, None] * sigma  # (N, 2)
            dabs = np.stack([np.sign(s1), beta * np.sign(s2)], axis=-1)
            out.dcost = 2.0 * alpha * turn[:, :, None] * df[:, None, :] + dabs[:, None, :]
            om = np.stack([axis, axis], axis=-1)  # (N, 3, 2)
            out.omega = np.broadcast_to(om[:, None], (n, n_ports, 3, 2)).copy()
        return out


class PlantedJoint(OppositeSteeringJoint):
    """A leg planted on its foot: the opposite steering joint (eq. 4) whose strut ends on
    a leaf node (the foot) with that connector braked.

    The kinematics are the opposite steering mode's; only the controller differs: the
    connector on the foot holds where it is on the node, so the foot sphere turns with
    the leg and grips (it can only rock as the leg pitches), while a foot under an
    ``opposite_steering`` leg is re-aimed every tick and rolls freely. Choosing which
    legs are planted in each step of a sequence gives a crawl its friction asymmetry
    (FreeSN paper, Fig. 19(f)-(o)).
    """

    name = "planted"
    controller = "freesn.planted"
    description = "opposite steering with the foot's connector braked (the foot grips)"
    planted = True


class SwingJoint(OppositeSteeringJoint):
    """A swing leg: the opposite steering joint (eq. 4) whose foot connector (on a leaf
    node) coasts, its motors off, so the foot sphere rolls freely under the leg.

    The counterpart of :class:`PlantedJoint`: a connector that is driven, even softly,
    brakes the node by its motors' back-EMF, and a foot dragged at the legs' speed slides
    as much as a planted one; only a coasting foot gives way.
    """

    name = "swing"
    controller = "freesn.swing"
    description = "opposite steering with the foot's connector coasting (the foot rolls)"


JOINT_MODES: tuple[type, ...] = (
    OppositeSteeringJoint,
    DifferentialSphericalJoint,
    FullOppositeJoint,
    RevoluteJoint,
    ParallelStrutNode,
    PlantedJoint,
    SwingJoint,
)
"""FreeSN node types in registration order; the first is the default joint mode."""
