"""The run's progress line: its estimate of the wall time left."""

import pytest

from msrr.core.app.commands.run import time_left


def test_a_behavior_running_its_duration_counts_down():
    """The last action, a 60 s behavior at 2 s of wall per simulated second: the estimate
    falls as it runs (the old one, elapsed / done x actions left, grew with it)."""
    said = [time_left(done=2, total=3, finished=30.0, in_action=2.0 * t,
                      behavior_left=60.0 - t, wall_per_sim=2.0) for t in (0.0, 20.0, 40.0, 60.0)]
    assert said == [120.0, 80.0, 40.0, 0.0]


@pytest.mark.parametrize("per_action", [0.5, 3.0, 40.0])
def test_actions_of_equal_length_are_estimated_exactly(per_action):
    """Every action takes ``per_action`` of wall time: at any moment the estimate is the
    truth (an independent count of what is left)."""
    total = 6
    for done in range(1, total):
        for into in (0.0, 0.25, 0.9):
            truth = (total - done) * per_action - into * per_action
            got = time_left(done=done, total=total, finished=done * per_action,
                            in_action=into * per_action, behavior_left=None,
                            wall_per_sim=None)
            assert got == pytest.approx(truth)


def test_an_action_over_the_mean_leaves_the_ones_after_it():
    assert time_left(done=2, total=5, finished=20.0, in_action=35.0, behavior_left=None,
                     wall_per_sim=None) == pytest.approx(20.0)


def test_nothing_known_says_nothing():
    assert time_left(done=0, total=4, finished=0.0, in_action=3.0, behavior_left=None,
                     wall_per_sim=None) is None
    assert time_left(done=0, total=4, finished=0.0, in_action=3.0, behavior_left=10.0,
                     wall_per_sim=1.5) is None          # the actions after it are unknown
    assert time_left(done=0, total=1, finished=0.0, in_action=3.0, behavior_left=10.0,
                     wall_per_sim=1.5) == pytest.approx(15.0)
