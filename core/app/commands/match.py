"""``platform match``: the best reference, cost and module mapping for a system (Alg. 4)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import click

from ...console import COSTS, FiniteFloat, console, plural, table
from ...errors import MsrrError
from ...plugins import load_configuration, resolve

if TYPE_CHECKING:
    from ...matching import MatchResult, RankedMatch

__all__ = ["CONFIDENCE", "command"]

CONFIDENCE = 4.0
"""``--confidence`` default: :data:`msrr.core.matching.CONFIDENCE` (a test keeps them equal;
the matching code is imported when the command runs, not at ``--help``)."""


def _mapping_table(system_name: str, ranked: RankedMatch, title: str):
    mapping = ranked.mapping
    rows = [["node", v, r, ""] for v, r in mapping.nodes.items()]
    rows += [["edge", e, f, "inv" if inv else ""] for e, (f, inv) in mapping.edges.items()]
    return table(title, ["", f"system ({system_name})", f"reference ({ranked.candidate.key})",
                         "direction"], rows)


def _summary(result: MatchResult, ranked: RankedMatch, rank: int) -> str:
    m = ranked.mapping
    return (f"#{rank} {ranked.candidate.key}: cost {ranked.cost:.6g} ({result.cost_kind}), "
            f"distance {m.distance:.6g} rad^2, RMS angle {math.degrees(m.rms_angle):.2f} deg, "
            f"yaw {math.degrees(m.yaw):.2f} deg")


@click.command("match")
@click.argument("system", type=click.Path(path_type=Path))
@click.argument("references", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("--top", type=click.IntRange(1, 1000), default=1, show_default=True,
              help="Print the K best mappings (1 to 1000).")
@click.option("--confidence", type=FiniteFloat(1.0, 1e6), default=CONFIDENCE, show_default=True,
              help="Stop a reference's search when distance > best cost * confidence (>= 1).")
@click.option("--time-budget", type=FiniteFloat(0.0, 86400.0, open_low=True), default=None,
              help="Stop the search after this long [s] and print the best so far.")
@click.option("--cost", type=click.Choice(COSTS), default=None,
              help="Motion cost: full-body IK (eq. 6; the default for robots with joint "
                   "modes) or aligned distance (eq. 8; the default otherwise).")
def command(system: Path, references: tuple[Path, ...], top: int, confidence: float,
            time_budget: float | None, cost: str | None) -> None:
    """Match SYSTEM.json against REFERENCE.json files: best reference, cost and mapping."""
    from ...matching import Candidate, MatchingError, match

    current = load_configuration(system)
    candidates = [Candidate(load_configuration(path), None, str(path)) for path in references]
    try:
        result = match(current, candidates, robot=resolve(current.robot), cost=cost,
                       confidence=confidence, time_budget=time_budget, top=top)
    except MsrrError as exc:  # a problem of the inputs found while matching: name them
        if str(system) in str(exc):
            raise
        raise MatchingError(f"{system}: {exc}") from None
    if result is None:
        raise MatchingError(f"{system}: no reference is isomorphic to this configuration "
                            f"(signature {current.signature().degrees})")
    if result.note:
        console.print(result.note)
    console.print(f"best match of {system}: {result.candidate.key}")
    for rank, ranked in enumerate(result.ranked, start=1):
        console.print(_summary(result, ranked, rank))
        console.print(_mapping_table(str(system), ranked, f"Module mapping #{rank}"))
    note = "" if result.complete else " (time budget reached: best so far)"
    console.print(f"{plural(result.evaluated, 'mapping')} evaluated{note}")
