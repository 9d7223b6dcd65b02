"""Non-finite numbers are refused by IK and FK (issue 11, deliverable 6)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from kin_helpers import random_stick, stick_tree

from msrr.core.errors import ConfigurationError
from msrr.core.kinematics import IKOptions, forward, solve_ik
from msrr.core.kinematics.ik import _better


def test_forward_refuses_non_finite_sigma() -> None:
    config = random_stick(3, 1)
    tree = stick_tree(config)
    sigma = np.zeros(tree.dim)
    sigma[2] = math.nan
    with pytest.raises(ConfigurationError, match=r"sigma\[2\]: joint value nan is not finite"):
        forward(tree, config, sigma)
    sigma[2] = math.inf
    with pytest.raises(ConfigurationError, match="joint value inf is not finite"):
        forward(tree, config, sigma)


def test_solve_ik_refuses_non_finite_starts() -> None:
    config = random_stick(3, 2)
    tree = stick_tree(config)
    target = forward(tree, config, np.full(tree.dim, 0.2)).configuration
    start = np.zeros(tree.dim)
    start[0] = math.nan
    with pytest.raises(ConfigurationError, match="initial_sigma: the IK start initial_sigma "
                                                 "has non-finite values"):
        solve_ik(tree, config, target, IKOptions(initial_sigma=start))
    with pytest.raises(ConfigurationError, match="initial_yaw: the IK start initial_yaw is nan"):
        solve_ik(tree, config, target, IKOptions(initial_yaw=math.nan))
    # the same problem from a finite start is solved
    assert solve_ik(tree, config, target, IKOptions(initial_sigma=np.zeros(tree.dim))).success


def test_a_finite_answer_always_beats_a_non_finite_one() -> None:
    nan_best = (math.nan, math.nan, math.nan, None)
    unsolved = (5.0, 5.0, 0.5, None)
    solved = (1.0, 1.0, 1e-6, None)
    assert _better(unsolved, nan_best, 1e-3) and _better(solved, nan_best, 1e-3)
    assert not _better(nan_best, unsolved, 1e-3) and _better(solved, unsolved, 1e-3)
