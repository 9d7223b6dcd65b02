"""Joint modes general enough for any robot, which plugins register or subclass.

A robot plugin may register these directly or subclass them to name its own
controller (FreeSN's ``revolute``, SnailBot's ``sucker_revolute``).
"""

from __future__ import annotations

import numpy as np

from .node import ModuleJointNode, NodeBatch
from .rotations import cross, rodrigues

__all__ = ["RevoluteJoint"]


class RevoluteJoint(ModuleJointNode):
    """Revolute mode (FreeSN paper Fig. 6a, eq. 1): rotate by ``sigma`` [rad] about
    ``z``; ``C = |sigma|``. Robots subclass it to name their own controller."""

    name = "revolute"
    dim = 1
    controller = "revolute"
    description = "turns about the connection axis"
    defaults = {"bound": float(np.pi)}

    @classmethod
    def evaluate(cls, z, x, sigma, params, n_ports, derivatives, context=None):
        z1, x1, s = z[:, 0], x[:, 0], sigma[:, 0]
        rot = rodrigues(z1, s)
        xj = np.einsum("nab,nb->na", rot, x1)
        out = NodeBatch(z.copy(), xj[:, None], np.abs(s)[:, None], rot[:, None])
        if derivatives:
            out.dz = np.zeros(z.shape + (1,))
            out.dx = cross(z1, xj)[:, None, :, None]
            out.dcost = np.sign(s)[:, None, None]
            out.omega = z1[:, None, :, None].copy()
        return out
