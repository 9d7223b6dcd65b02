"""Configuration matching and mapping: the best reference, tree and mapping (Alg. 4).

Given the system configuration and candidate (reference configuration, kinematic
tree) pairs -- later the library -- :func:`match` keeps the candidates whose signature
equals the system's, walks each one's isomorphism tree search in ascending distance,
evaluates the motion cost (:mod:`.cost`) of every mapping it sees and stops a
candidate's search once the next distance exceeds ``cost_min * sigma`` (Alg. 4 line 5).

Ties never go to round-off. Mappings whose distances are tied (:func:`~.cost.tied`)
form one batch: the stop test of line 5 is taken once per batch, so every member of a
batch is evaluated or none is, whatever order the search yields them in. The best
mapping is the one of least cost; among costs tied with the least, the least distance;
among those tied again, the candidate given first, then the mapping whose sorted
``(system id, reference id)`` node pairs and ``(system edge, reference edge, inv)``
triples compare smallest. A time budget may end the search early; the result then says
so (``complete`` is false) and is the best found so far.
"""

from __future__ import annotations

import bisect
import math
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field

from ..configuration import Configuration
from ..errors import UnknownNameError
from ..kinematics import KinematicTree, default_tree
from ..robot import Robot
from .cost import (
    CONFIDENCE,
    COST_DISTANCE,
    COST_FUNCTIONS,
    COST_IK,
    CostFn,
    MatchingError,
    check_cost,
    tied,
)
from .iso_search import iso_search
from .mapping import Mapping

__all__ = ["Candidate", "MatchResult", "RankedMatch", "mapping_key", "match"]


@dataclass(frozen=True)
class Candidate:
    """A reference configuration with its kinematic tree (a library entry).

    Attributes:
        reference: the reference configuration.
        tree: its kinematic tree; None uses the robot's default tree of ``reference``.
        key: anything that identifies the candidate to the caller (a file, a library id).
    """

    reference: Configuration
    tree: KinematicTree | None = None
    key: object = None


@dataclass(frozen=True)
class RankedMatch:
    """One evaluated mapping: the candidate, the mapping and its motion cost."""

    candidate: Candidate
    mapping: Mapping
    cost: float
    position: int = 0
    """Index of the candidate in the list given to :func:`match` (the tie rule's key)."""


@dataclass(frozen=True)
class MatchResult:
    """The outcome of :func:`match` (Alg. 4 output).

    Attributes:
        candidate: the best candidate (reference configuration and kinematic tree).
        mapping: the best system -> reference module mapping.
        cost: its motion cost.
        cost_kind: ``"ik"`` (eq. 6, full-body IK), ``"distance"`` (eq. 8) or
            ``"custom"`` (an injected cost function).
        note: why the cost kind is what it is when it was not asked for (a robot
            without joint modes is matched by distance); empty otherwise.
        ranked: the best evaluated mappings, best first (as many as ``top``).
        evaluated: how many mappings had their cost evaluated.
        complete: False when the time budget ended the search early.
    """

    candidate: Candidate
    mapping: Mapping
    cost: float
    cost_kind: str
    note: str = ""
    ranked: tuple[RankedMatch, ...] = field(default=())
    evaluated: int = 0
    complete: bool = True

    @property
    def reference(self) -> Configuration:
        return self.candidate.reference

    @property
    def tree(self) -> KinematicTree | None:
        return self.candidate.tree


def mapping_key(mapping: Mapping) -> tuple:
    """The last key of the tie rule: sorted node pairs, then sorted edge triples."""
    return (tuple(sorted(mapping.nodes.items())),
            tuple(sorted((e, f, inv) for e, (f, inv) in mapping.edges.items())))


def _best(ranked: Sequence[RankedMatch]) -> RankedMatch:
    """The best of ``ranked`` under the tie rule (module doc)."""
    least = min(r.cost for r in ranked)
    by_cost = [r for r in ranked if tied(r.cost, least)]
    nearest = min(r.mapping.distance for r in by_cost)
    by_distance = [r for r in by_cost if tied(r.mapping.distance, nearest)]
    return min(by_distance, key=lambda r: (r.position, mapping_key(r.mapping)))


def _module_joint(robot: Robot | None) -> type | None:
    if robot is None:
        return None
    try:
        return robot.default_joint_mode()
    except UnknownNameError:
        return None


def _cost(cost: str | CostFn | None, pool: list[Candidate], robot: Robot | None
          ) -> tuple[CostFn, str, str, list[Candidate]]:
    """The cost function, its kind, the note on it and the candidates with their trees."""
    if callable(cost):
        return cost, "custom", "", pool
    joint = _module_joint(robot)
    have_trees = all(c.tree is not None for c in pool) or joint is not None
    note = ""
    if cost is None:
        if have_trees:
            kind = COST_IK
        else:
            kind = COST_DISTANCE
            note = (f"robot {robot.name!r} has no joint modes" if robot is not None
                    else "no kinematic trees given") + ": eq. 8 distance as the motion cost"
    else:
        kind = check_cost(cost)
    if kind == COST_IK:
        if not have_trees:
            raise MatchingError("the IK motion cost needs a kinematic tree for every "
                                "candidate or a robot with a module joint mode")
        pool = [c if c.tree is not None else Candidate(c.reference,
                                                       default_tree(c.reference, joint), c.key)
                for c in pool]
    return COST_FUNCTIONS[kind], kind, note, pool


@dataclass(frozen=True)
class _Search:
    """What Alg. 4's inner loop needs besides the candidate (see :func:`match`'s arguments)."""

    system: Configuration
    cost_fn: CostFn
    confidence: float
    top: int
    max_mappings: int | None
    deadline: float | None
    clock: Callable[[], float]

    def expired(self) -> bool:
        return self.deadline is not None and self.clock() > self.deadline


def _walk(search: _Search, candidate: Candidate, position: int, ranked: list[RankedMatch],
          costs: list[float]) -> None:
    """Alg. 4 lines 4-12 for one candidate: its mappings in ascending distance, each batch
    of tied distances evaluated unless it is past ``confidence`` times the ``top``-th best
    cost so far (line 5); adds to ``ranked`` and to the sorted ``costs``."""
    top = search.top
    batch: float | None = None
    for seen, mapping in enumerate(iso_search(search.system, candidate.reference,
                                              deadline=search.deadline, clock=search.clock)):
        if batch is None or not tied(mapping.distance, batch):
            if search.max_mappings is not None and seen >= search.max_mappings:
                break
            limit = search.confidence * (costs[top - 1] if len(costs) >= top else math.inf)
            if mapping.distance > limit and not tied(mapping.distance, limit):
                break                                   # Alg. 4 line 5
            batch = mapping.distance
        value = float(search.cost_fn(candidate.reference, candidate.tree,
                                     mapping.system_in_reference_ids(search.system)))
        ranked.append(RankedMatch(candidate, mapping, value, position))
        bisect.insort(costs, value)
        if search.expired():
            break


def _best_ones(ranked: Sequence[RankedMatch], top: int) -> list[RankedMatch]:
    """The ``top`` best of ``ranked``, best first, under the tie rule (module doc)."""
    best: list[RankedMatch] = []
    left = list(ranked)
    while left and len(best) < top:
        best.append(_best(left))
        left = [r for r in left if r is not best[-1]]
    return best


def match(system: Configuration, candidates: Iterable[Candidate], *,
          robot: Robot | None = None, cost: str | CostFn | None = None,
          confidence: float = CONFIDENCE, top: int = 1, max_mappings: int | None = None,
          time_budget: float | None = None,
          clock: Callable[[], float] = time.monotonic) -> MatchResult | None:
    """Best candidate and module mapping for ``system`` (Alg. 4).

    Args:
        system: the current configuration.
        candidates: reference configurations with kinematic trees, in order of
            preference for ties.
        robot: the robot; its default joint mode builds the tree of a candidate without
            one. A robot without module joint modes is matched by distance.
        cost: ``"ik"`` (eq. 6), ``"distance"`` (eq. 8) or a function
            ``cost(reference, tree, system_in_reference_ids)``; by default the IK cost
            when trees are available, else the distance (the result's ``note`` says why).
        confidence: ``sigma`` of Alg. 4: a candidate's search stops when a mapping's
            distance exceeds ``confidence`` times the ``top``-th best cost so far.
        top: how many best mappings to keep in :attr:`MatchResult.ranked`.
        max_mappings: a cap on the mappings evaluated per candidate, checked between
            batches of tied distances.
        time_budget: stop the search after this long [s] (of ``clock``) and return the
            best so far with ``complete=False``.
        clock: the time source of ``time_budget`` (injected by tests).

    Returns:
        The best match, or None when no candidate is isomorphic to ``system``.

    Raises:
        MatchingError: a non-positive ``confidence``, ``time_budget`` or ``top``, an
            unknown cost kind, or the IK cost without trees.
    """
    if not confidence > 0:
        raise MatchingError(f"confidence must be positive, got {confidence}")
    if time_budget is not None and not time_budget > 0:
        raise MatchingError(f"time budget must be positive, got {time_budget} s")
    if top < 1:
        raise MatchingError(f"top must be at least 1, got {top}")
    signature = system.signature()
    cost_fn, cost_kind, note, pool = _cost(cost, list(candidates), robot)
    search = _Search(system, cost_fn, confidence, top, max_mappings,
                     None if time_budget is None else clock() + time_budget, clock)
    ranked: list[RankedMatch] = []
    costs: list[float] = []          # sorted, for the top-th best cost of line 5
    complete = True
    for position, candidate in enumerate(pool):     # Alg. 4 line 3
        if candidate.reference.robot != system.robot \
                or candidate.reference.signature() != signature:
            continue
        _walk(search, candidate, position, ranked, costs)
        if search.expired():
            complete = False
            break
    if not ranked:
        return None
    best = _best_ones(ranked, top)
    first = best[0]
    return MatchResult(first.candidate, first.mapping, first.cost, cost_kind, note,
                       tuple(best), len(ranked), complete)
