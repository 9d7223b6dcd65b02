"""Concurrent legs: independent moves of a plan driven at the same time (pure).

Every MMRP module drives itself (section 2), and the paper's hybrid planning lets the
free modules move at once under their potential field (section 4.3), so moves of
different groups need not wait for each other. The planner routes legs one after
another (:mod:`.routing`); this pass packs each run of consecutive moving actions into
*waves*: a leg joins the earliest wave after every earlier leg it conflicts with, and
each wave is one moving action whose goals cover all its groups.

Two legs conflict when they move a common module or when their swept paths
(:func:`~.motion.leg_paths`, turns included) come within ``CLEARANCE`` of each other
(:func:`~.motion.apart`, a test that is never optimistic). Legs that do not conflict
commute, so the waves are a reordering of the checked sequence: each leg still sees
every other module either standing where the sequence had it or moving along a path
that stays clear of its own. The plan checker replays the waves itself
(:func:`~.check.check_plan`: concurrent groups against each other and the still ones).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np

from msrr.core.plan import Action, ActionType

from .motion import CLEARANCE, SAMPLE_STEP, apart, leg_paths, sweep_points

__all__ = ["concurrent_moves", "leg_shift"]

Cell = tuple[int, int]

BUCKET = 4
"""Side of the spatial hash of the legs' swept boxes [cells]."""

LONGEST_LEG = 20
"""Longest drive of one moving action [cells]: 6 m, 50 s at the controller's cruise
speed, well inside the executor's default phase timeout (90 s). A longer straight leg
is driven in pieces (stopping in between), so that a parking leg across the field
does not time out and restart."""


def leg_shift(action: Action, cells: Mapping[str, Cell], unit: float) -> Cell:
    """The translation [cells] of one group's leg: its first module's goal minus its cell."""
    m = action.modules[0]
    x, y, _ = action.goals[m]
    return round(x / unit) - cells[m][0], round(y / unit) - cells[m][1]


def _buckets(points: np.ndarray) -> list[Cell]:
    reach = CLEARANCE + SAMPLE_STEP
    lo = np.floor((points.min(axis=0) - reach) / BUCKET).astype(int)
    hi = np.floor((points.max(axis=0) + reach) / BUCKET).astype(int)
    return [(i, j) for i in range(lo[0], hi[0] + 1) for j in range(lo[1], hi[1] + 1)]


def _waves(legs: Sequence[Action], cells: dict[str, Cell], unit: float) -> list[list[int]]:
    """The wave of every leg (indices into ``legs``, in order), ``cells`` moved along."""
    swept: list[np.ndarray] = []
    wave_of: list[int] = []
    last_wave: dict[str, int] = {}  # module -> the wave of its latest leg
    index: dict[Cell, list[int]] = {}
    for k, leg in enumerate(legs):
        order = sorted(leg.modules)
        shift = leg_shift(leg, cells, unit)
        points = sweep_points(leg_paths([cells[m] for m in order], shift))
        swept.append(points)
        buckets = _buckets(points)
        wave = max((last_wave.get(m, -1) for m in order), default=-1) + 1
        seen: set[int] = set()
        for b in buckets:
            for other in index.get(b, ()):
                if other not in seen and wave_of[other] >= wave:
                    seen.add(other)
                    if not apart(points, swept[other]):
                        wave = wave_of[other] + 1
        wave_of.append(wave)
        for b in buckets:
            index.setdefault(b, []).append(k)
        for m in order:
            last_wave[m] = wave
            cells[m] = (cells[m][0] + shift[0], cells[m][1] + shift[1])
    waves: list[list[int]] = [[] for _ in range(max(wave_of, default=-1) + 1)]
    for k, wave in enumerate(wave_of):
        waves[wave].append(k)
    return waves


def _pieces(legs: Sequence[Action], cells: Mapping[str, Cell], unit: float) -> list[Action]:
    """``legs`` with every drive longer than ``LONGEST_LEG`` split into equal pieces.

    Only legs whose pieces sweep nothing the whole leg does not: drives along x, and
    drives along y of a single module (it turns in place; a group's turn halfway along
    a y leg would sweep a new disc, so a group's y leg stays whole).
    """
    cells = dict(cells)
    out = []
    for leg in legs:
        dx, dy = leg_shift(leg, cells, unit)
        count = 1 if dy and len(leg.modules) > 1 else -(-max(abs(dx), abs(dy)) // LONGEST_LEG)
        for i in range(1, count + 1):
            if count == 1:
                out.append(leg)
                break
            step = (round(dx * i / count), round(dy * i / count))
            goals = {m: [(cells[m][0] + step[0]) * unit, (cells[m][1] + step[1]) * unit, 0.0]
                     for m in leg.modules}
            out.append(replace(leg, goals=goals, cost=leg.cost / count,
                               note=f"{leg.note}, piece {i}/{count}"))
        for m in leg.modules:
            cells[m] = (cells[m][0] + dx, cells[m][1] + dy)
    return out


def _merged(legs: Sequence[Action]) -> Action:
    if len(legs) == 1:
        return legs[0]
    modules = tuple(m for leg in legs for m in leg.modules)
    goals = {m: g for leg in legs for m, g in leg.goals.items()}
    return Action(ActionType.MOVING, legs[-1].target, modules=modules, goals=goals,
                  cost=sum(leg.cost for leg in legs),
                  note=f"{len(legs)} groups at once: " + "; ".join(leg.note for leg in legs))


def concurrent_moves(actions: Sequence[Action], start_cells: Mapping[str, Cell], unit: float
                     ) -> list[Action]:
    """``actions`` with every run of consecutive single-group legs packed into waves
    (legs longer than ``LONGEST_LEG`` first split into pieces).

    Args:
        actions: a plan's actions; each moving action is one leg of one rigid group
            (goals ``{id: [x, y, 0]}`` [m] in the frame of ``start_cells``).
        start_cells: every module's grid cell at the start.
        unit: the grid pitch [m].

    Returns:
        The same undocks and docks in the same order; between them, one moving action
        per wave (a wave of one leg is that leg unchanged).
    """
    cells = dict(start_cells)
    out: list[Action] = []
    run: list[Action] = []

    def flush() -> None:
        if run:
            legs = _pieces(run, cells, unit)
            for wave in _waves(legs, cells, unit):
                out.append(_merged([legs[k] for k in wave]))
            run.clear()

    for action in actions:
        if action.type is ActionType.MOVING and action.goals:
            run.append(action)
        else:
            flush()
            out.append(action)
    flush()
    return out
