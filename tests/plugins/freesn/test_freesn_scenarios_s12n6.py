"""The S12N6 figure scenario fig21 (issue 13, paper Fig. 21): planned at prepare time
through the parallel connections and disconnections of the library (no simulation
here; the runs are in docs/freesn.md)."""

from __future__ import annotations

from pathlib import Path

from msrr.core import plugins
from msrr.core.plan import ActionType
from msrr.core.run import RunRequest, prepare_run
from msrr.core.shape import skeletal_error

FREESN = Path(__file__).resolve().parents[3] / "plugins" / "freesn"
PARALLEL = (ActionType.PARALLEL_CONNECTION, ActionType.PARALLEL_DISCONNECTION)


def test_fig21_reaches_the_tree_and_the_star_by_parallel_actions(tmp_path):
    prepared = prepare_run(RunRequest(robot="freesn", scenario="fig21", out=tmp_path / "run",
                                      log=False))
    plan = prepared.run.plan
    assert [a.reaches for a in plan.actions if a.reaches] == ["S12N6-7.1", "S12N6-2.1"]
    parallel = [a for a in plan.actions if a.type in PARALLEL]
    # out: dock R6 and C1 together, undock R1 and R4 together; back: the reverse
    assert [a.type for a in parallel] == list(PARALLEL) * 2
    assert all(len(a.changes) == 2 for a in parallel)
    tree = next(i for i, a in enumerate(plan.actions) if a.reaches == "S12N6-7.1")
    assert plan.actions[tree].type is ActionType.PARALLEL_DISCONNECTION
    reached = plan.actions[tree].target
    assert reached.is_connected() and len(reached.edges()) == 12
    assert sum(not reached.is_virtual(e.target) for e in reached.edges()) == 5   # a tree
    star = plugins.load_configuration(FREESN / "configs" / "library" / "S12N6-2.1.json")
    assert skeletal_error(plan.goal, star) < 1e-9                    # back where it began
    assert (plan.docks, plan.undocks) == (5, 5)
