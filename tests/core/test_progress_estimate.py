"""The run's progress line: its estimate of the wall time left."""

import re

import pytest

from msrr.core.app.commands.run import time_left


def _seconds(text: str) -> float:
    return float(re.fullmatch(r", about (\d+) s left", text).group(1))


def test_a_behavior_running_its_duration_counts_down():
    """The last action, a 60 s behavior at 2 s of wall per simulated second: the estimate
    falls as it runs (the old one, elapsed / done x actions left, grew with it)."""
    said = [time_left(done=2, total=3, finished=30.0, in_action=2.0 * t,
                      behavior_left=60.0 - t, wall_per_sim=2.0) for t in (0.0, 20.0, 40.0, 60.0)]
    assert [_seconds(s) for s in said] == [120.0, 80.0, 40.0, 0.0]


@pytest.mark.parametrize("per_action", [7.0, 30.0, 400.0])
def test_actions_of_equal_length_are_estimated_exactly(per_action):
    """Every action takes ``per_action`` of wall time: at any moment the estimate is the
    truth (an independent count of what is left), to the second it is said in."""
    total = 6
    for done in range(1, total):
        for into in (0.0, 0.25, 0.9):
            truth = (total - done) * per_action - into * per_action
            said = time_left(done=done, total=total, finished=done * per_action,
                             in_action=into * per_action, behavior_left=None,
                             wall_per_sim=None)
            assert _seconds(said) == pytest.approx(truth, abs=0.5)


def test_an_action_longer_than_the_mean_says_only_what_follows_it():
    """Past the mean, the running action's end is unknown: the line says so and gives the
    time of the actions after it (not a count that runs to zero while the run goes on)."""
    assert time_left(done=2, total=5, finished=20.0, in_action=35.0, behavior_left=None,
                     wall_per_sim=None) == \
        ", this action longer than the mean, about 20 s after it"
    assert time_left(done=4, total=5, finished=20.0, in_action=35.0, behavior_left=None,
                     wall_per_sim=None) == ", this action longer than the mean, the last"


def test_nothing_known_says_nothing():
    assert time_left(done=0, total=4, finished=0.0, in_action=3.0, behavior_left=None,
                     wall_per_sim=None) == ""
    assert time_left(done=0, total=4, finished=0.0, in_action=3.0, behavior_left=10.0,
                     wall_per_sim=1.5) == ""          # the actions after it are unknown
    assert _seconds(time_left(done=0, total=1, finished=0.0, in_action=3.0,
                              behavior_left=10.0, wall_per_sim=1.5)) == 15.0
