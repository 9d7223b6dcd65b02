"""Section 4.3: the forces of eqs. 2-5 and the free-vertex mapping with its fallback."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment

from msrr.plugins.mmrp.potential_field import (
    FieldParameters,
    map_free_vertices,
    resultant_forces,
)

PARAMS = FieldParameters()
NONE = np.zeros((0, 2))


def test_attraction_is_k_a_over_d_squared_toward_the_target():
    force = resultant_forces(np.array([[0.0, 0.0]]), np.array([[2.0, 0.0]]), NONE, PARAMS)
    assert force[0] == pytest.approx([PARAMS.k_a / 4, 0.0])


def test_repulsion_acts_only_inside_d_r():
    near = resultant_forces(np.array([[0.0, 0.0], [0.5, 0.0]]), NONE, NONE, PARAMS)
    assert near[0] == pytest.approx([-PARAMS.k_r / 0.5, 0.0])
    far = resultant_forces(np.array([[0.0, 0.0], [PARAMS.d_r + 0.1, 0.0]]), NONE, NONE, PARAMS)
    assert far == pytest.approx(np.zeros((2, 2)))


@pytest.mark.parametrize(("distance", "expected"), [
    (0.5, -PARAMS.k_r / 0.5),            # inside d_safe-: pushed away
    (2.0, 0.0),                          # inside the ring: no force
    (8.0, PARAMS.k_r * 8.0),             # beyond d_safe+: pulled back
])
def test_obstacle_force_follows_equation_4(distance, expected):
    force = resultant_forces(np.array([[0.0, 0.0]]), NONE, np.array([[distance, 0.0]]), PARAMS)
    assert force[0] == pytest.approx([expected, 0.0])


def test_each_free_module_takes_its_nearest_target():
    result = map_free_vertices({"a": (0.0, 0.0), "b": (3.0, 0.0)},
                               {"x": (3.0, 1.0), "y": (0.0, 1.0)}, [(1.5, 2.0)], seed=1)
    assert result.mapping == {"a": "y", "b": "x"}
    assert not result.stalled and set(result.arrival) == {"a", "b"}
    assert result.travelled["a"] == pytest.approx(1.0, abs=0.1)


def test_a_stalled_field_falls_back_to_minimum_total_distance():
    rng = np.random.default_rng(0)
    free = {f"m{i}": tuple(rng.uniform(-5, 5, 2)) for i in range(6)}
    targets = {f"t{i}": tuple(rng.uniform(-5, 5, 2)) for i in range(6)}
    result = map_free_vertices(free, targets, [], params=FieldParameters(patience=1, step=1e-6))
    assert result.stalled and set(result.fallback) == set(free)
    cost = np.array([[np.hypot(*np.subtract(free[m], targets[t])) for t in targets]
                     for m in free])
    rows, cols = linear_sum_assignment(cost)
    assert sum(cost[list(free).index(m), list(targets).index(t)]
               for m, t in result.mapping.items()) == pytest.approx(cost[rows, cols].sum(),
                                                                     abs=1e-3)
