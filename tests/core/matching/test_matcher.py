"""Configuration matching and mapping (Alg. 4) and the ``platform match`` command."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from matching_helpers import assert_isomorphism, random_freesn, scrambled

from msrr.core.cli import get_cli
from msrr.core.io import load_configuration, save_configuration
from msrr.core.matching import (
    Candidate,
    MatchingError,
    distance_cost,
    iso_search,
    match,
)

ROOT = Path(__file__).resolve().parents[3]


def _library(seed: int):
    rng = np.random.default_rng(seed)
    system = random_freesn(rng, 4, 3, 2)
    target = scrambled(system, rng, noise=0.05)
    decoys = [scrambled(random_freesn(np.random.default_rng(seed + 100), 4, 3, 2), rng),
              scrambled(system.with_vectors(z={e.id: -e.z for e in system.edges()}), rng),
              scrambled(random_freesn(rng, 3, 2, 1), rng)]
    candidates = [Candidate(d, None, f"decoy{i}") for i, d in enumerate(decoys)]
    candidates.insert(int(rng.integers(len(candidates) + 1)), Candidate(target, None, "target"))
    return system, candidates


@pytest.mark.parametrize("seed", range(5))
def test_picks_the_right_reference_among_decoys(seed):
    system, candidates = _library(seed)
    result = match(system, candidates, cost_fn=distance_cost)
    assert result is not None and result.candidate.key == "target"
    assert result.cost_kind == "custom" and result.complete
    assert_isomorphism(system, result.reference, result.mapping)
    assert result.cost == pytest.approx(result.mapping.distance, abs=1e-9)


def test_cost_function_gets_the_system_in_reference_ids():
    system, candidates = _library(11)
    seen = []

    def cost(reference, tree, moved):
        assert tree is None
        assert sorted(moved.edge_ids()) == sorted(reference.edge_ids())
        assert sorted(moved.vertices()) == sorted(reference.vertices())
        seen.append(1)
        return distance_cost(reference, tree, moved)

    assert match(system, candidates, cost_fn=cost) is not None
    assert seen


def test_confidence_stops_a_candidate_early():
    rng = np.random.default_rng(5)
    system = random_freesn(rng, 3, 4, 3)
    reference = scrambled(system, rng, noise=0.2)
    total = sum(1 for _ in iso_search(system, reference))
    calls = []

    def cost(reference, tree, moved):
        calls.append(1)
        return distance_cost(reference, tree, moved)

    tight = match(system, [Candidate(reference)], cost_fn=cost, confidence=1.0)
    assert tight is not None and len(calls) < total
    loose = match(system, [Candidate(reference)], cost_fn=distance_cost, confidence=1e9, top=3)
    assert loose.evaluated == total and len(loose.ranked) == 3
    assert [r.cost for r in loose.ranked] == sorted(r.cost for r in loose.ranked)
    assert loose.cost == pytest.approx(tight.cost)


def test_time_budget_returns_best_so_far():
    rng = np.random.default_rng(2)
    system = random_freesn(rng, 4, 6, 4)
    reference = scrambled(system, rng, noise=1.0)

    def slow(reference, tree, moved):
        import time

        time.sleep(0.3)
        return distance_cost(reference, tree, moved)

    total = 3 * sum(1 for _ in iso_search(system, reference))
    result = match(system, [Candidate(reference)] * 3, cost_fn=slow, time_budget=0.5,
                   confidence=1e9)
    assert result is not None and not result.complete and 1 <= result.evaluated < total


def test_no_isomorphic_candidate_and_bad_arguments():
    system, candidates = _library(3)
    others = [c for c in candidates if c.key == "decoy2"]
    assert match(system, others, cost_fn=distance_cost) is None
    with pytest.raises(MatchingError, match="confidence"):
        match(system, candidates, confidence=0)
    with pytest.raises(MatchingError, match="top"):
        match(system, candidates, top=0)


def test_cli_match_prints_best_and_top(tmp_path):
    system, candidates = _library(4)
    save_configuration(system, tmp_path / "system.json")
    paths = []
    for c in candidates:
        paths.append(str(tmp_path / f"{c.key}.json"))
        save_configuration(c.reference, paths[-1])
    runner = CliRunner()
    out = runner.invoke(get_cli(), ["match", str(tmp_path / "system.json"), *paths,
                                    "--top", "2", "--cost", "distance"])
    assert out.exit_code == 0, out.output
    assert "best match" in out.output and "target.json" in out.output.splitlines()[0]
    assert "#2" in out.output and "Module mapping" in out.output


def test_cli_match_without_isomorphic_reference_is_one_line(tmp_path):
    leg = ROOT / "plugins" / "freesn" / "configs" / "triangle-leg.json"
    cross = load_configuration(ROOT / "plugins" / "mmrp" / "configs" / "cross.json")
    save_configuration(cross, tmp_path / "cross.json")
    out = CliRunner().invoke(get_cli(), ["match", str(leg), str(tmp_path / "cross.json"),
                                         "--cost", "distance"])
    assert out.exit_code == 1
    assert "no reference is isomorphic" in out.output and "Traceback" not in out.output


def test_default_cost_is_the_ik_cost_when_kinematics_is_installed():
    try:
        from msrr.core.kinematics import default_tree, solve_ik  # noqa: F401
    except ImportError:
        pytest.skip("msrr.core.kinematics does not export the IK yet")
    config = load_configuration(ROOT / "plugins" / "freesn" / "configs" / "triangle-leg.json")
    reference = scrambled(config, np.random.default_rng(0), noise=0.1)
    result = match(config, [Candidate(reference, None, "ref")], time_budget=60)
    assert result is not None and result.cost_kind == "ik"
    assert_isomorphism(config, reference, result.mapping)
    assert result.mapping.distance < 0.1
