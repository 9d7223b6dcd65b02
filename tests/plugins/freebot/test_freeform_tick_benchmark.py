"""The tick benchmark (``benchmarks/freeform_tick.py``): its parts' CPU adds up without
counting a nested part twice, and its fingerprint of a run is the same run after run."""

from __future__ import annotations

import time

from msrr_test_support import ROOT, load_script


def _benchmark():
    return load_script(ROOT / "benchmarks" / "freeform_tick.py", "freeform_tick_benchmark")


def _spin(seconds: float) -> None:
    end = time.process_time() + seconds
    while time.process_time() < end:
        pass


def test_a_part_counts_without_the_parts_timed_inside_it():
    timer = _benchmark().Timer()
    inner = timer.wrap("inner", lambda: _spin(0.02))
    outer = timer.wrap("outer", lambda: (_spin(0.01), inner(), inner()))
    outer()
    assert timer.calls == {"inner": 2, "outer": 1}
    assert 0.035 < timer.own["inner"] < 0.08
    assert 0.005 < timer.own["outer"] < 0.03


def test_the_fingerprint_of_a_run_is_the_same_again_and_the_world_is_left_as_it_was():
    from msrr.core.freeform.world import FreeformWorld

    bench = _benchmark()
    step, reports = FreeformWorld.step, FreeformWorld.reports
    first = bench.measure("roll-to-dock", 2.0, 0, 0.0)
    second = bench.measure("roll-to-dock", 2.0, 0, 0.0)
    assert first[2].final() == second[2].final()
    assert first[0]["ticks"] == second[0]["ticks"] > 0
    assert sum(first[1].own.values()) <= first[0]["cpu"] + 1e-6
    assert (FreeformWorld.step, FreeformWorld.reports) == (step, reports)
