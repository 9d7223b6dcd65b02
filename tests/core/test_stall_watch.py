"""A phase that makes no progress ends early; one that converges slowly is never cut
(:class:`~msrr.core.executor.StallWatch`, issue 31)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from msrr.core.errors import ExecutionError
from msrr.core.executor import ExecutorOptions, StallWatch

DT = 0.1
OPTIONS = ExecutorOptions()


def _watch() -> StallWatch:
    return StallWatch(OPTIONS.stall_window, OPTIONS.stall_gain, OPTIONS.stall_time)


def _first_stall(errors_deg: np.ndarray) -> tuple[float, str]:
    """When (driver time [s]) and why the watch first says stalled; ``(inf, "")``: never."""
    watch = _watch()
    for i, e in enumerate(errors_deg):
        reason = watch.stalled(math.radians(float(e)), (i + 1) * DT, DT)
        if reason:
            return (i + 1) * DT, reason
    return math.inf, ""


@pytest.mark.parametrize("seed", range(5))
def test_a_noisy_plateau_ends_after_the_window(seed) -> None:
    # a collapsed body: the tracker's (already smoothed) error sits at 23 deg with the
    # jitter 2 deg of report noise leaves in it
    rng = np.random.default_rng(seed)
    errors = 23.0 + rng.normal(0.0, 1.5, 900)   # 90 s, the phase timeout
    when, reason = _first_stall(errors)
    assert OPTIONS.stall_window <= when <= 2 * OPTIONS.stall_window + 2.0
    assert reason.startswith("shape error 2") and "deg for 1" in reason


@pytest.mark.parametrize("seed", range(5))
def test_a_slowly_converging_phase_is_never_cut(seed) -> None:
    # 30 -> 3 deg at 0.1 deg/s (the slowest progress the watch keeps is 0.033 deg/s), with a
    # jitter twice what 2 deg of report noise leaves in the tracker's smoothed error
    rng = np.random.default_rng(seed)
    t = np.arange(2700) * DT
    errors = 30.0 - 0.1 * t + rng.normal(0.0, 1.0, t.size)
    assert _first_stall(errors) == (math.inf, "")


def test_a_detour_shorter_than_the_window_is_not_cut() -> None:
    # 30 -> 15 deg in 5 s, back up to 18 over 4 s (a fold around an obstacle), then down
    # to 4 deg by t = 23 s; where it then stays is cut a window after its last progress
    t = np.arange(600) * DT
    errors = np.interp(t, [0.0, 5.0, 9.0, 23.0], [30.0, 15.0, 18.0, 4.0])
    assert _first_stall(errors[:230]) == (math.inf, "")
    when, reason = _first_stall(errors)
    assert 23.0 + OPTIONS.stall_window - 1.0 <= when <= 23.0 + OPTIONS.stall_window + 2.0
    assert reason.startswith("shape error 4.0 deg")


def test_before_the_tracker_stepped_nothing_is_judged() -> None:
    watch = _watch()
    assert watch.stalled(math.inf, DT, DT) == ""
    assert all(watch.stalled(0.2, (i + 2) * DT, DT) == "" for i in range(50))


def test_stall_options_are_checked() -> None:
    with pytest.raises(ExecutionError, match="stall"):
        ExecutorOptions(stall_window=-1.0)
    with pytest.raises(ExecutionError, match="stall"):
        ExecutorOptions(stall_time=0.0)
    with pytest.raises(ExecutionError, match="settle tolerance"):
        ExecutorOptions(settle_tolerance=-0.1)
