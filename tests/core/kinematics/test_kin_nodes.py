"""Node types: the tests' own joint modes against central differences (they back every
other kinematics test), and the node base class's checks."""

from __future__ import annotations

import numpy as np
import pytest
from kin_helpers import BraceNode, GimbalJoint, TwistJoint, central_difference, relative_error

from msrr.core.kinematics import FixedNode, KinematicNode, KinematicTreeError, skew

TYPES = [GimbalJoint, TwistJoint, BraceNode, FixedNode]


def make(cls: type[KinematicNode]) -> KinematicNode:
    if cls in (BraceNode, FixedNode):
        return cls(["R1", "R2"], ["H3"])
    return cls(["R1"], ["H2"])


@pytest.mark.parametrize("cls", [GimbalJoint, TwistJoint, BraceNode], ids=lambda c: c.name)
def test_node_jacobians_match_central_differences(cls):
    node = make(cls)
    for seed in range(3):
        rng = np.random.default_rng(seed)
        m = len(node.edges)
        z = rng.normal(size=(3, m))
        z /= np.linalg.norm(z, axis=0)
        x = rng.normal(size=(3, m))
        x /= np.linalg.norm(x, axis=0)
        sigma = rng.normal(size=node.dim) * 0.7
        jac = node.jacobian(z, x, sigma)
        for field in ("z", "x", "cost", "rotations"):
            numeric = central_difference(
                lambda s, f=field, z=z, x=x: getattr(node.forward(z, x, s), f), sigma)
            assert relative_error(getattr(jac, field), numeric) < 1e-7, field


@pytest.mark.parametrize("cls", TYPES, ids=lambda c: c.name)
def test_zero_joint_values_change_nothing(cls):
    node = make(cls)
    rng = np.random.default_rng(1)
    z, x = rng.normal(size=(3, len(node.edges))), rng.normal(size=(3, len(node.edges)))
    out = node.forward(z, x, np.zeros(node.dim))
    assert np.allclose(out.z, z) and np.allclose(out.x, x) and not out.cost.any()
    assert np.allclose(out.rotations, np.eye(3))


def test_port_rotations_are_rotations_and_omega_is_their_derivative():
    node = GimbalJoint(["R1"], ["H2"])
    z, x = np.array([[0.0], [0.0], [1.0]]), np.array([[1.0], [0.0], [0.0]])
    sigma = np.array([0.3, -0.4])
    rot = node.forward(z, x, sigma).rotations[0]
    assert np.allclose(rot @ rot.T, np.eye(3)) and np.isclose(np.linalg.det(rot), 1.0)
    out = node._one(z, x, sigma, derivatives=True)
    assert out.omega is not None
    first = skew(out.omega[0, 0, :, 0]) @ rot                     # d rot / d sigma_0
    assert np.allclose(first, node.jacobian(z, x, sigma).rotations[0][..., 0])


def test_a_module_joint_has_one_edge_and_one_vertex():
    with pytest.raises(KinematicTreeError, match="exactly one edge and one vertex"):
        GimbalJoint(["R1", "R2"], ["H2"])


def test_unknown_parameters_are_refused_listing_the_known_ones():
    with pytest.raises(KinematicTreeError, match=r"unknown parameter\(s\) wobble \(known: "
                                                 r"bound\)"):
        TwistJoint(["R1"], ["H2"], wobble=1.0)


def test_bounds_come_from_the_bound_parameter():
    lo, hi = GimbalJoint(["R1"], ["H2"], bound=0.5).bounds
    assert lo.tolist() == [-0.5, -0.5] and hi.tolist() == [0.5, 0.5]
    assert FixedNode([], ["H1"]).bounds[0].shape == (0,)
