"""The IK evaluation's fast paths compute what the general functions compute, to the bit
(issue 32, item 6: the FreeSN control tick made cheaper without changing a result).

Each written-out form is compared with the function it replaces in the inner loop, as
integers of the float64 bits (so a zero's sign counts too), on seeded random inputs.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from kin_helpers import SPEC, random_stick, stick_tree
from scipy.spatial import ConvexHull, QhullError

from msrr.core.kinematics import GroundModel, GroundOp, forward, rotations
from msrr.core.kinematics import ground as ground_module
from msrr.core.kinematics.ground import _cross3, hull_facets, turn_down, turn_down_omega

DOWN = np.array([0.0, 0.0, -1.0])


def bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64).view(np.int64)


def normals(count: int, seed: int) -> list[tuple[np.ndarray, float]]:
    """Unit normals (half of them pointing down, as support faces' do) and lengths."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(count):
        raw = rng.normal(size=3) * rng.uniform(0.01, 2.0)
        if i % 2:
            raw[2] = -abs(raw[2])
        norm = float(np.linalg.norm(raw))
        out.append((raw / norm, norm))
    return out


def test_turn_down_is_rotation_between_to_the_bit():
    for n, _ in normals(3000, 0):
        assert np.array_equal(bits(turn_down(n)), bits(rotations.rotation_between(n, DOWN)))


def test_turn_down_omega_is_rotation_between_omega_to_the_bit():
    for n, norm in normals(3000, 1):
        dn = (np.eye(3) - n[:, None] * n) / norm
        assert np.array_equal(bits(turn_down_omega(n, norm)),
                              bits(rotations.rotation_between_omega(DOWN, n, dn)))


def test_turn_down_keeps_the_signs_of_exact_zeros():
    """Exact runs (no noise) have axis-aligned normals: every zero's sign as the general path
    gives it (an arctan2 downstream turns -0 and +0 into -pi and pi)."""
    values = [0.0, -0.0, 0.6, -0.6, 0.8, -0.8, 1.0, -1.0]
    checked = 0
    for a, b, c in itertools.product(values, repeat=3):
        raw = np.array([a, b, c])
        norm = float(np.linalg.norm(raw))
        if norm == 0.0 or raw[2] / norm > 0.999:
            continue
        n = raw / norm
        dn = (np.eye(3) - n[:, None] * n) / norm
        assert np.array_equal(bits(turn_down(n)), bits(rotations.rotation_between(n, DOWN)))
        assert np.array_equal(bits(turn_down_omega(n, norm)),
                              bits(rotations.rotation_between_omega(DOWN, n, dn)))
        checked += 1
    assert checked > 300


def test_straight_up_takes_the_general_half_turn_and_has_no_derivative():
    up = np.array([0.0, 0.0, 1.0])
    assert np.array_equal(turn_down(up), rotations.rotation_between(up, DOWN))
    assert np.allclose(turn_down(up) @ up, DOWN)
    assert not turn_down_omega(up, 1.0).any()


def test_cross3_is_cross_to_the_bit():
    rng = np.random.default_rng(2)
    for _ in range(2000):
        a, b = rng.normal(size=3), rng.normal(size=3)
        assert np.array_equal(bits(_cross3(a, b)), bits(rotations.cross(a, b)))


def test_skew_is_the_levi_civita_contraction_to_the_bit():
    """The gathered components against the einsum it replaced, zeros of both signs included."""
    rng = np.random.default_rng(3)
    for shape in [(3,), (12, 3), (4, 2, 3)]:
        for _ in range(300):
            v = rng.normal(size=shape)
            v[rng.random(shape) < 0.2] = 0.0
            v[rng.random(shape) < 0.1] = -0.0
            want = np.einsum("ijk,...k->...ij", rotations._HAT, v)
            assert np.array_equal(bits(rotations.skew(v)), bits(want))


@pytest.mark.parametrize("signature, shapes", [
    ("ni,ni->n", [(12, 3), (12, 3)]),
    ("nab,nb->na", [(12, 3, 3), (12, 3)]),
    ("nba,nb->na", [(12, 3, 3), (12, 3)]),
    ("nmad,nma->nd", [(12, 1, 3, 3), (12, 1, 3)]),
    ("...i,...id->...d", [(3,), (3, 3)]),
])
def test_einsum_is_numpys(signature, shapes):
    rng = np.random.default_rng(4)
    operands = [rng.normal(size=s) for s in shapes]
    assert np.array_equal(bits(rotations.einsum(signature, *operands)),
                          bits(np.einsum(signature, *operands)))


def test_hull_facets_are_convex_hulls():
    rng = np.random.default_rng(5)
    for _ in range(200):
        points = rng.normal(size=(int(rng.integers(4, 24)), 3))
        simplices, equations = hull_facets(points)
        hull = ConvexHull(points)
        assert np.array_equal(simplices, hull.simplices)
        assert np.array_equal(bits(equations), bits(hull.equations))


def test_hull_facets_of_flat_points_raise_as_convex_hull_does():
    flat = np.random.default_rng(6).normal(size=(6, 3))
    flat[:, 2] = 0.0
    with pytest.raises(QhullError):
        ConvexHull(flat)
    with pytest.raises(QhullError):
        hull_facets(flat)


def test_hull_facets_without_the_qhull_wrapper_use_convex_hull(monkeypatch):
    points = np.random.default_rng(7).normal(size=(10, 3))
    want = hull_facets(points)
    monkeypatch.setattr(ground_module, "_QHULL", None)
    got = hull_facets(points)
    assert np.array_equal(got[0], want[0]) and np.array_equal(bits(got[1]), bits(want[1]))


def test_ground_backward_of_other_vectors_than_the_contacts_grounds_them_itself():
    """The grounded vectors kept by ``contact`` serve only the vectors it was given."""
    config = random_stick(8, 21, free=2)
    tree = stick_tree(config)
    z = forward(tree, config, np.random.default_rng(8).normal(size=tree.dim) * 0.3).Z.T.copy()
    op = GroundOp(tree, GroundModel.for_configuration(config, SPEC))
    contact, cache = op.contact(z)
    assert cache.source is z and np.array_equal(cache.grounded, z @ contact.rotation.T)
    grad = np.random.default_rng(9).normal(size=z.shape)
    kept = op.backward(cache, z, grad)[0]
    assert np.array_equal(bits(op.backward(cache, z.copy(), grad)[0]), bits(kept))
    other = z + 1e-3
    moved = op.backward(cache, other, grad)[0]
    cache.grounded = None   # only the identity of the vectors selects the kept ones
    assert np.array_equal(bits(op.backward(cache, other, grad)[0]), bits(moved))
