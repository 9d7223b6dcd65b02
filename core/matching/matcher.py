"""Configuration matching and mapping: the best reference, tree and mapping (Alg. 4).

Given the system configuration and candidate (reference configuration, kinematic
tree) pairs -- later the library -- :func:`match` keeps the candidates whose signature
equals the system's, walks each one's isomorphism tree search in ascending distance,
evaluates the motion cost of every mapping it sees (by default the full-body IK cost,
eq. 6) and stops a candidate's search as soon as the next distance exceeds
``cost_min * confidence`` (Alg. 4 line 5, ``sigma``). A time budget cuts the whole
search short and still returns the best found so far.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..configuration import Configuration
from ..errors import MsrrError
from .distance import vector_match
from .iso_search import iso_search
from .mapping import Mapping

__all__ = [
    "COST_DISTANCE",
    "COST_IK",
    "Candidate",
    "CostFn",
    "MatchResult",
    "MatchingError",
    "RankedMatch",
    "distance_cost",
    "ik_cost",
    "match",
]

CostFn = Callable[[Configuration, Any, Configuration], float]
"""``cost_fn(reference, tree, system_in_reference_ids) -> cost``."""

COST_IK = "ik"
COST_DISTANCE = "distance"

DEFAULT_CONFIDENCE = 2.0


class MatchingError(MsrrError):
    """Bad arguments to the matcher (a non-positive confidence, budget or top count)."""


@dataclass(frozen=True)
class Candidate:
    """A reference configuration with its kinematic tree (a library entry).

    Attributes:
        reference: the reference configuration.
        tree: its kinematic tree; None uses ``default_tree(reference)``.
        key: anything that identifies the candidate to the caller (a file, a library id).
    """

    reference: Configuration
    tree: Any = None
    key: Any = None


@dataclass(frozen=True)
class RankedMatch:
    """One evaluated mapping: the candidate, the mapping and its motion cost."""

    candidate: Candidate
    mapping: Mapping
    cost: float


@dataclass(frozen=True)
class MatchResult:
    """The outcome of :func:`match` (Alg. 4 output).

    Attributes:
        candidate: the best candidate (reference configuration and kinematic tree).
        mapping: the best system -> reference module mapping.
        cost: its motion cost.
        cost_kind: ``"ik"`` (eq. 6 objective of the full-body IK), ``"distance"`` (the
            eq. 8 aligned distance, used when the kinematics is unavailable) or
            ``"custom"`` (an injected ``cost_fn``).
        ranked: the best evaluated mappings, best first (as many as ``top``).
        evaluated: how many mappings had their cost evaluated.
        complete: False when the time budget cut the search short.
    """

    candidate: Candidate
    mapping: Mapping
    cost: float
    cost_kind: str
    ranked: tuple[RankedMatch, ...] = field(default=())
    evaluated: int = 0
    complete: bool = True

    @property
    def reference(self) -> Configuration:
        return self.candidate.reference

    @property
    def tree(self) -> Any:
        return self.candidate.tree


def distance_cost(reference: Configuration, tree: Any, system: Configuration) -> float:
    """Eq. 8 aligned distance of ``system`` (in reference ids) to ``reference``."""
    del tree
    ids = [e.id for e in reference.edges() if e.z is not None and system.edge(e.id).z is not None]
    if not ids:
        return 0.0
    return vector_match(system.vectors(ids), reference.vectors(ids)).cost


def ik_cost(reference: Configuration, tree: Any, system: Configuration) -> float:
    """Full-body IK cost (eq. 6) of moving ``system`` (in reference ids) to ``reference``."""
    from ..kinematics import IKOptions, default_tree, solve_ik

    if tree is None:  # transitional until matching receives its Robot (issue 10)
        from ..plugins import resolve

        tree = default_tree(reference, resolve(reference.robot).default_joint_mode())
    return float(solve_ik(tree, system, reference, options=IKOptions(seed=0)).cost)


def _default_cost() -> tuple[CostFn, str]:
    try:
        from ..kinematics import default_tree, solve_ik  # noqa: F401
    except ImportError:
        return distance_cost, COST_DISTANCE
    return ik_cost, COST_IK


def match(system: Configuration, candidates: Iterable[Candidate], *,
          confidence: float = DEFAULT_CONFIDENCE, time_budget: float | None = None,
          cost_fn: CostFn | None = None, top: int = 1,
          max_mappings: int | None = None) -> MatchResult | None:
    """Best candidate and module mapping for ``system`` (Alg. 4).

    Args:
        system: the current configuration.
        candidates: reference configurations with kinematic trees.
        confidence: ``sigma`` of Alg. 4: a candidate's search stops when a mapping's
            distance exceeds ``confidence`` times the ``top``-th best cost so far.
        time_budget: wall-clock limit [s]; the best found so far is returned.
        cost_fn: ``cost_fn(reference, tree, system_in_reference_ids) -> cost``; the
            full-body IK cost by default, or the aligned distance when the kinematics is
            not installed (the result says which in ``cost_kind``).
        top: how many best mappings to keep in :attr:`MatchResult.ranked`.
        max_mappings: optional cap on mappings evaluated per candidate.

    Returns:
        The best match, or None when no candidate is isomorphic to ``system``.

    Raises:
        MatchingError: a non-positive ``confidence``, ``time_budget`` or ``top``.
    """
    if not confidence > 0:
        raise MatchingError(f"confidence must be positive, got {confidence}")
    if time_budget is not None and not time_budget > 0:
        raise MatchingError(f"time budget must be positive, got {time_budget} s")
    if top < 1:
        raise MatchingError(f"top must be at least 1, got {top}")
    if cost_fn is None:
        cost_fn, cost_kind = _default_cost()
    else:
        cost_kind = "custom"
    deadline = None if time_budget is None else time.monotonic() + time_budget
    signature = system.signature()
    ranked: list[RankedMatch] = []
    evaluated, complete = 0, True

    def threshold() -> float:
        return ranked[top - 1].cost if len(ranked) >= top else np.inf

    for candidate in candidates:
        if candidate.reference.robot != system.robot \
                or candidate.reference.signature() != signature:
            continue
        for seen, mapping in enumerate(iso_search(system, candidate.reference,
                                                   deadline=deadline), start=1):
            if mapping.distance > threshold() * confidence:
                break
            cost = float(cost_fn(candidate.reference, candidate.tree,
                                 mapping.system_in_reference_ids(system)))
            evaluated += 1
            ranked.append(RankedMatch(candidate, mapping, cost))
            ranked.sort(key=lambda r: r.cost)
            del ranked[top:]
            if deadline is not None and time.monotonic() > deadline:
                break
            if max_mappings is not None and seen >= max_mappings:
                break
        if deadline is not None and time.monotonic() > deadline:
            complete = False
            break
    if not ranked:
        return None
    best = ranked[0]
    return MatchResult(best.candidate, best.mapping, best.cost, cost_kind, tuple(ranked),
                       evaluated, complete)
