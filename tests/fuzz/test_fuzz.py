"""The fuzz suite of issue 11: mutated files of every kind, fed to every reader and to
the file-reading commands, end in one clean error or are valid (see fuzz_inputs)."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

from fuzz_inputs import MUTATORS, campaign, cases

SEED = 20261122
CASES = 2000


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
                        "library retrieve"}
    assert sum(not o.ok for o in outcomes) > 0.7 * len(outcomes)  # most mutations break


def test_the_generator_is_seeded_and_uses_every_mutation() -> None:
    first = [(c.label, c.data) for c in cases(300, 5)]
    assert first == [(c.label, c.data) for c in cases(300, 5)]
    assert first != [(c.label, c.data) for c in cases(300, 6)]
    made = {c.mutation for c in cases(1000, 5)}
    names = {m.__name__[2:] for m in MUTATORS}
    # some mutators report a free-form variant (rename_free...) under another name
    assert len(made) >= len(names), sorted(names - made)
