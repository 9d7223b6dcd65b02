"""No ground truth in any decision (issue 32, item 1), read from the source.

The witness channel (:mod:`msrr.core.witness`: ``Driver.witness``, ``ground_truth``,
the simulator's counts; a world's ``poses()`` and ``groups()``) is read only by the
judge, the recording, the application wing, the fault wrappers that pass it through,
the link emulator (the modules' side of the link) and the drivers and worlds that
provide it. Every other source file -- executor, IK tracking, controllers,
recognizers, planners, estimators -- names none of it. The import layers say the same
for the core (``tests/core/test_layers.py``); this covers the plugins too.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SOURCES = sorted(p for top in ("core", "plugins", "examples") for p in (ROOT / top).rglob("*.py")
                 if ".venv" not in p.parts)

CHANNEL = re.compile(r"\.witness\(|\bground_truth\(|\.constraint_events\(|\.saturation\(\)"
                     r"|\.faults\(\)|\bworld\.poses\(|\bworld\.groups\(|from \.+witness import"
                     r"|(from|import) msrr\.core\.witness\b|\.observation\.poses"
                     r"|observation\.groups")
"""A read of the witness channel (or of the fields it replaced)."""

ALLOWED = re.compile(r"^core/(app/|timeline/|judge\.py|faults\.py|witness\.py|link/emulator\.py)"
                     r"|^core/(driver|events)\.py"
                     r"|^core/freeform/(mujoco|mujoco_driver|world|driver)\.py"
                     r"|^core/generic/(driver|physics)\.py|^plugins/[^/]+/sim/(driver|world)\.py"
                     r"|^plugins/freesn/sim/(connectors|collision|docking)\.py")
"""The judge, the recording, the application wing, pass-through wrappers, the link's
module side, the drivers and worlds themselves, and the interface modules that name the
witness's type in annotations only (under ``TYPE_CHECKING``)."""


def _relative(path: Path) -> str:
    return path.relative_to(ROOT).as_posix()


def test_the_sources_are_found():
    names = {_relative(p) for p in SOURCES}
    assert {"core/executor.py", "core/judge.py", "plugins/freesn/sim/controller.py"} <= names


@pytest.mark.parametrize("path", [p for p in SOURCES if not ALLOWED.search(_relative(p))],
                         ids=_relative)
def test_the_control_path_reads_no_ground_truth(path):
    hits = [f"{n}: {line.strip()}" for n, line in enumerate(path.read_text().splitlines(), 1)
            if CHANNEL.search(line) and not line.lstrip().startswith("#")]
    assert not hits, f"{_relative(path)} reads the witness channel:\n" + "\n".join(hits)


def test_the_pattern_catches_what_it_is_for():
    for line in ("poses = self.driver.witness().poses", "truth = driver.ground_truth()",
                 "from msrr.core.witness import Witness", "from ..witness import Witness",
                 "groups = self.world.groups()", "x = tick.observation.poses"):
        assert CHANNEL.search(line), line
    for line in ("observation.tracked", "self.recognizer.recognize(observation.sensors)"):
        assert not CHANNEL.search(line), line
