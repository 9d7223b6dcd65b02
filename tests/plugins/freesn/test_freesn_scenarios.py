"""The FreeSN figure scenarios (issue 13): registered, their start files reproducible,
planned stage by stage at prepare time (no simulation here; the runs are in
docs/freesn.md)."""

from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path

import numpy as np

from msrr.core import plugins
from msrr.core.app.run import RunRequest, prepare_run, resolve_scenario
from msrr.core.io import save_configuration
from msrr.core.plan import ActionType
from msrr.core.random_configurations import newly_built
from msrr.core.shape import skeletal_error

FREESN = Path(__file__).resolve().parents[3] / "plugins" / "freesn"
GENERATE = FREESN / "configs" / "scenarios" / "generate.py"


def generator():
    spec = importlib.util.spec_from_file_location("freesn_scenario_starts", GENERATE)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_fig20_is_the_default_and_starts_from_the_systems_own_ids():
    scenario = resolve_scenario("freesn", None)
    assert scenario.name == "fig20"
    start = plugins.load_configuration(scenario.start)
    library = plugins.load_configuration(FREESN / "configs" / "library" / "S6N3-1.1.json")
    assert not set(start.modules()) & set(library.modules())        # relabelled
    tilts = [abs(e.z[2]) for e in start.edges()]                     # the triangle's struts
    assert sorted(tilts)[0] > 1e-3 and start.signature() == library.signature()
    assert [s.goal.stem for s in scenario.all_stages()] == ["S6N3-4.1", "S6N3-1.1"]


def same_document(a: object, b: object, tol: float = 1e-9) -> bool:
    """JSON values equal, numbers within ``tol`` (the script's floats differ in their last
    bits between processors: numpy's instruction paths)."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same_document(a[k], b[k], tol) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(same_document(x, y, tol) for x, y in zip(a, b, strict=True))
    if isinstance(a, float | int) and isinstance(b, float | int) \
            and not isinstance(a, bool) and not isinstance(b, bool):
        return abs(a - b) <= tol
    return a == b


def test_the_start_files_are_what_the_seeded_script_writes():
    module = generator()
    for name in module.STARTS:
        written = json.loads((GENERATE.parent / f"{name}.json").read_text())
        assert same_document(written, json.loads(module.start_document(name))), name


def test_same_document_tells_a_moved_module_from_a_last_bit():
    doc = {"modules": [{"id": "n0", "position": [0.1, 0.2, 0.0]}]}
    bit = {"modules": [{"id": "n0", "position": [0.1 + 1e-16, 0.2, 0.0]}]}
    moved = {"modules": [{"id": "n0", "position": [0.1 + 1e-6, 0.2, 0.0]}]}
    assert same_document(doc, bit) and not same_document(doc, moved)
    assert not same_document(doc, {"modules": [{"id": "n1", "position": [0.1, 0.2, 0.0]}]})


def test_fig20_plans_both_stages_at_prepare_time(tmp_path):
    prepared = prepare_run(RunRequest(robot="freesn", out=tmp_path / "run", log=False))
    plan = prepared.run.plan
    assert prepared.run.scenario == "fig20" and plan.planner == "library"
    assert [a.reaches for a in plan.actions if a.reaches] == ["S6N3-4.1", "S6N3-1.1"]
    assert (plan.docks, plan.undocks) == (3, 3)
    home = plugins.load_configuration(FREESN / "configs" / "library" / "S6N3-1.1.json")
    assert skeletal_error(plan.goal, home) < 1e-9                    # back where it began


def test_an_unseen_start_given_with_from_reaches_the_scenarios_target(tmp_path):
    library = FREESN / "configs" / "library"
    unseen = newly_built(plugins.load_configuration(library / "S6N3-1.1.json"),
                         np.random.default_rng(2026), noise=math.radians(6.0), name="mine")
    save_configuration(unseen, tmp_path / "mine.json")
    prepared = prepare_run(RunRequest(robot="freesn", start=tmp_path / "mine.json",
                                      goal=library / "S6N3-4.1.json",
                                      out=tmp_path / "run", log=False))
    plan = prepared.run.plan
    first = plan.actions[0]
    assert first.type is ActionType.MOVING                           # approach the match
    assert skeletal_error(unseen, first.target) < math.radians(12.0)
    target = plugins.load_configuration(library / "S6N3-4.1.json")
    assert skeletal_error(plan.goal, target) < 1e-9 and (plan.docks, plan.undocks) == (1, 2)
    assert plan.actions[-1].reaches == "S6N3-4.1"
