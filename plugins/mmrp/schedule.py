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

A leg stays whole however long: the controller says how long its drive takes
(:meth:`~.sim.controller.MmrpController.begin`) and the executor allows that on top of
its timeout. (Cutting long legs into pieces in the plan multiplied a 1,000-module plan's
moving legs by 8 and its file by 5.)
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from msrr.core.plan import Action, ActionType

from .motion import CHORD_SAG, CLEARANCE, Sweep, apart, leg_paths, sweep

__all__ = ["concurrent_moves", "leg_shift"]

Cell = tuple[int, int]


def leg_shift(action: Action, cells: Mapping[str, Cell], unit: float) -> Cell:
    """The translation [cells] of one group's leg: its first module's goal minus its cell."""
    m = action.modules[0]
    x, y, _ = action.goals[m]
    return round(x / unit) - cells[m][0], round(y / unit) - cells[m][1]


def _waves(legs: Sequence[Action], cells: dict[str, Cell], unit: float) -> list[list[int]]:
    """The wave of every leg (indices into ``legs``, in order), ``cells`` moved along.

    A leg's wave is one after the latest wave of any earlier leg it conflicts with: the
    earlier legs whose swept boxes come within reach are tested latest wave first, and
    the first conflict settles it."""
    reach = CLEARANCE + 2 * CHORD_SAG  # no two sweeps that come nearer are apart
    boxes = np.empty((len(legs), 4))  # each sweep's x/y min and max, widened by reach
    swept: list[Sweep] = []
    wave_of = np.empty(len(legs), dtype=int)
    last_wave: dict[str, int] = {}  # module -> the wave of its latest leg
    for k, leg in enumerate(legs):
        order = sorted(leg.modules)
        shift = leg_shift(leg, cells, unit)
        path = sweep(leg_paths([cells[m] for m in order], shift))
        ends = path.segments.reshape(-1, 2)
        lo, hi = ends.min(axis=0) - reach, ends.max(axis=0) + reach
        wave = max((last_wave.get(m, -1) for m in order), default=-1) + 1
        near = np.flatnonzero((wave_of[:k] >= wave) & (boxes[:k, 0] <= hi[0])
                              & (boxes[:k, 2] >= lo[0]) & (boxes[:k, 1] <= hi[1])
                              & (boxes[:k, 3] >= lo[1]))
        for other in near[np.lexsort((near, -wave_of[near]))]:
            if not apart(path, swept[other]):
                wave = int(wave_of[other]) + 1
                break
        boxes[k] = (*lo, *hi)
        swept.append(path)
        wave_of[k] = wave
        for m in order:
            last_wave[m] = wave
            cells[m] = (cells[m][0] + shift[0], cells[m][1] + shift[1])
    waves: list[list[int]] = [[] for _ in range(int(wave_of.max(initial=-1)) + 1)]
    for k, wave in enumerate(wave_of):
        waves[wave].append(k)
    return waves


def _merged(legs: Sequence[Action]) -> Action:
    if len(legs) == 1:
        return legs[0]
    modules = tuple(m for leg in legs for m in leg.modules)
    goals = {m: g for leg in legs for m, g in leg.goals.items()}
    return Action(ActionType.MOVING, legs[-1].target, modules=modules, goals=goals,
                  cost=round(sum(leg.cost for leg in legs), 9),
                  note=f"{len(legs)} groups at once: " + "; ".join(leg.note for leg in legs))


def concurrent_moves(actions: Sequence[Action], start_cells: Mapping[str, Cell], unit: float
                     ) -> list[Action]:
    """``actions`` with every run of consecutive single-group legs packed into waves.

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
            for wave in _waves(run, cells, unit):
                out.append(_merged([run[k] for k in wave]))
            run.clear()

    for action in actions:
        if action.type is ActionType.MOVING and action.goals:
            run.append(action)
        else:
            flush()
            out.append(action)
    flush()
    return out
