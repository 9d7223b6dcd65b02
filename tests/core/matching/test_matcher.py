"""Configuration matching and mapping (Alg. 4) and the ``platform match`` command."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from matching_helpers import BARS, assert_isomorphism, random_freesn, scrambled, stick

from msrr.core.app.cli import get_cli
from msrr.core.io import save_configuration
from msrr.core.matching import (
    Candidate,
    MatchingError,
    brute_force_isomorphisms,
    distance_cost,
    ik_cost,
    iso_search,
    mapping_key,
    match,
    tied,
)
from msrr.core.plugins import load_configuration

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
    result = match(system, candidates, cost="distance")
    assert result is not None and result.candidate.key == "target"
    assert result.cost_kind == "distance" and result.complete and not result.note
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

    result = match(system, candidates, cost=cost)
    assert result is not None and result.cost_kind == "custom"
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

    tight = match(system, [Candidate(reference)], cost=cost, confidence=1.0)
    assert tight is not None and len(calls) < total
    loose = match(system, [Candidate(reference)], cost="distance", confidence=1e9, top=3)
    assert loose.evaluated == total and len(loose.ranked) == 3
    assert [r.cost for r in loose.ranked] == sorted(r.cost for r in loose.ranked)
    assert loose.cost == pytest.approx(tight.cost)


class Ticks:
    """A clock that advances one second per reading (no wall-clock in the test)."""

    def __init__(self):
        self.now = 0.0

    def __call__(self) -> float:
        self.now += 1.0
        return self.now


def test_time_budget_stops_early_and_says_so():
    rng = np.random.default_rng(2)
    system = random_freesn(rng, 4, 4, 3)
    reference = scrambled(system, rng, noise=1.0)
    total = 3 * sum(1 for _ in iso_search(system, reference))
    full = match(system, [Candidate(reference)] * 3, cost="distance", confidence=1e9,
                 clock=Ticks())
    assert full.complete and full.evaluated == total
    cut = match(system, [Candidate(reference)] * 3, cost="distance", confidence=1e9,
                time_budget=20.0, clock=Ticks())
    assert cut is not None and not cut.complete and 1 <= cut.evaluated < total
    assert cut.cost >= full.cost


def _symmetric(seed: int):
    """A configuration with many automorphisms: a triangle of nodes, two struts per side."""
    rng = np.random.default_rng(seed)
    config = random_freesn(rng, 3, 0, 0)
    for a, b in (("N0", "N1"), ("N1", "N2"), ("N2", "N0")):
        for k in range(2):
            config.connect(a, b, id=f"{a}{b}{k}", kind="strut", z=np.array([0.0, 0.0, 1.0]))
    return config


def _noisy(config, rng, scale=1e-7):
    """``config`` with every vector turned by ~1e-7 rad: distances ~1e-14, inside the tie rule."""
    z = {}
    for e in config.edges():
        v = e.z + rng.normal(scale=scale, size=3)
        z[e.id] = v / np.linalg.norm(v)
    return config.with_vectors(z=z, x={})


def test_ties_go_to_the_stated_key_never_to_round_off():
    """Equal-cost mappings (automorphisms) are chosen by the tie rule, whatever the noise."""
    reference = _symmetric(0)
    maps = brute_force_isomorphisms(reference, reference)
    least = min(m.distance for m in maps)
    assert sum(tied(m.distance, least) for m in maps) > 1       # the test needs real ties
    expected = min((m for m in maps if tied(m.distance, least)), key=mapping_key)
    rng = np.random.default_rng(1)
    chosen = set()
    for _ in range(4):
        system = _noisy(reference, rng)
        result = match(system, [Candidate(_noisy(reference, rng), None, "ref")],
                       cost="distance")
        chosen.add(mapping_key(result.mapping))
    assert chosen == {mapping_key(expected)}


def test_tied_candidates_go_to_the_first_listed():
    reference = _symmetric(3)
    exact = Candidate(reference.copy(), None, "exact")
    close = Candidate(_noisy(reference, np.random.default_rng(4)), None, "close")
    for pool in itertools.permutations([exact, close]):
        result = match(reference, list(pool), cost="distance")
        assert result.candidate is pool[0]


def test_robot_without_joint_modes_is_matched_by_distance_and_told():
    system, candidates = _library(6)
    result = match(system, candidates, robot=BARS)
    assert result.cost_kind == "distance" and "no joint modes" in result.note
    assert result.candidate.key == "target"
    with pytest.raises(MatchingError, match="needs a kinematic tree"):
        match(system, candidates, robot=BARS, cost="ik")


def test_no_isomorphic_candidate_and_bad_arguments():
    system, candidates = _library(3)
    others = [c for c in candidates if c.key == "decoy2"]
    assert match(system, others, cost="distance") is None
    with pytest.raises(MatchingError, match="confidence"):
        match(system, candidates, confidence=0)
    with pytest.raises(MatchingError, match="top"):
        match(system, candidates, top=0)
    with pytest.raises(MatchingError, match="unknown motion cost"):
        match(system, candidates, cost="speed")


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


def test_default_cost_is_the_ik_cost_for_a_robot_with_joint_modes():
    config = stick.triangle_leg()
    reference = scrambled(config, np.random.default_rng(0), noise=0.1)
    result = match(config, [Candidate(reference, None, "ref")], robot=stick.STICK)
    assert result is not None and result.cost_kind == "ik" and not result.note
    assert_isomorphism(config, reference, result.mapping)
    assert result.mapping.distance < 0.1
    assert result.tree is not None and result.tree.dim > 0      # the robot's default tree
    assert result.cost == pytest.approx(ik_cost(reference, result.tree,
                                                result.mapping.system_in_reference_ids(config)))


def test_cli_matches_a_robot_without_joint_modes(tmp_path):
    """Issue 11: ``platform match`` works for every robot (MMRP: by distance, and says so)."""
    cross = ROOT / "plugins" / "mmrp" / "configs" / "cross.json"
    out = CliRunner().invoke(get_cli(), ["match", str(cross), str(cross)])
    assert out.exit_code == 0, out.output
    assert "(distance)" in out.output and "no joint modes" in out.output
