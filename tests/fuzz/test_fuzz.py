"""The fuzz suite of issues 11 and 30: mutated files of every kind fed to every reader
and to the file-reading commands (``platform run --plan`` too) end in one clean error or
are valid (see fuzz_inputs); driver options and fault specs are refused in one line
without a run folder, or accepted exactly when valid (fuzz_options); the link decoder
never raises anything but its own refusals (fuzz_link).

Plans are fuzzed in both file versions (version 2 stores each target as its changes:
its own mutations empty them, remove what is not there or insert past the end).

Each extension of the suite takes fresh seeds (the campaign of issue 30 used 20261122
for files; these were never used before), so what it covers was not tuned to pass."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import fuzz_link
import fuzz_options
from fuzz_inputs import MUTATORS, campaign, cases, cases_of, read, write

SEED = 29261134  # the rare mutations are drawn on purpose (test below): a campaign of
# 2,000 drew none of some of them whenever the seed plans changed (issues 29, 32, 28)
CASES = 2000
OPTION_SEED = 30261127
OPTION_CASES = 1500
LINK_SEED = 30261128
LINK_CASES = 10000


def test_every_mutated_file_ends_in_one_clean_error_or_is_valid(tmp_path: Path) -> None:
    outcomes = campaign(CASES, SEED, tmp_path, command_every=3)
    problems = [f"{o.case.label} -> {o.target}: {o.problem}" for o in outcomes if o.problem]
    assert not problems, f"{len(problems)} problems (seed {SEED}):\n" + "\n".join(problems[:20])
    readers = Counter(o.target for o in outcomes if o.target.startswith("read "))
    assert sum(readers.values()) == CASES
    assert set(readers) == {f"read {k}" for k in
                            ("configuration", "library", "sources", "plan", "tree")}
    commands = {o.target for o in outcomes} - set(readers)
    assert commands == {"validate", "show", "match", "plan", "library show",
                        "library retrieve", "run"}
    assert sum(not o.ok for o in outcomes) > 0.7 * len(outcomes)  # most mutations break


RARE = ("not_object", "plan_copy", "plan_drop", "plan_swap", "plan_start", "plan_modules",
        "plan_unknown", "plan_emptied", "plan_index", "library_mapping", "library_tree",
        "library_command")


def test_every_rare_mutation_is_refused_in_one_clean_error(tmp_path: Path) -> None:
    """The mutations a campaign of 2,000 draws only a few times (those of plans and
    libraries), three of each, whatever the seed files are."""
    for kind in RARE:
        made = cases_of(kind, 3, SEED)
        assert len(made) == 3, kind
        for index, case in enumerate(made):
            outcome = read(case, write(case, tmp_path, index))
            assert outcome.problem is None, f"{case.label}: {outcome.problem}"


def test_the_generator_is_seeded_and_uses_every_mutation() -> None:
    first = [(c.label, c.data) for c in cases(300, 5)]
    assert first == [(c.label, c.data) for c in cases(300, 5)]
    assert first != [(c.label, c.data) for c in cases(300, 6)]
    made = {c.mutation for c in cases(1000, 5)}
    names = {m.__name__[2:] for m in MUTATORS}
    # some mutators report a free-form variant (rename_free...) under another name
    assert len(made) >= len(names), sorted(names - made)


def test_driver_options_and_fault_specs_are_refused_in_one_line_or_valid(
        tmp_path: Path) -> None:
    outcomes = fuzz_options.campaign(OPTION_CASES, OPTION_SEED, tmp_path, command_every=4)
    problems = [f"{o.case.label} -> {o.target}: {o.problem}" for o in outcomes if o.problem]
    assert not problems, f"{len(problems)} problems (seed {OPTION_SEED}):\n" + \
        "\n".join(problems[:20])
    seen = Counter((o.case.kind, o.target, o.ok) for o in outcomes)
    for kind in ("driver-option", "faults"):
        assert seen[(kind, "check", True)] > 50 and seen[(kind, "check", False)] > 50, seen
        assert seen[(kind, "run", False)] > 10, seen
    assert seen[("faults", "sweep", False)] > 10, seen
    assert {o.case.driver for o in outcomes if o.case.kind == "driver-option"} == \
        {d for _, d in fuzz_options.DRIVERS}


def test_the_options_generator_is_seeded() -> None:
    first = [c.label for c in fuzz_options.cases(200, 3)]
    assert first == [c.label for c in fuzz_options.cases(200, 3)]
    assert first != [c.label for c in fuzz_options.cases(200, 4)]


def test_the_link_decoder_refuses_or_accepts_every_mutated_payload() -> None:
    outcomes = fuzz_link.campaign(LINK_CASES, LINK_SEED)
    problems = [f"{o.case.label}: {o.problem}" for o in outcomes if o.problem]
    assert not problems, f"{len(problems)} problems (seed {LINK_SEED}):\n" + \
        "\n".join(problems[:10])
    kinds = Counter((o.case.seed.kind, o.ok) for o in outcomes)
    for kind in ("header", "command", "report"):
        assert kinds[(kind, True)] > 10 and kinds[(kind, False)] > 100, kinds
    assert any(o.case.seed.records and o.ok for o in outcomes)  # FreeSN records decoded
