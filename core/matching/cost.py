"""The motion cost of matching and of the library, its constants and its tie rule.

One definition, used by the matcher (Alg. 4), library creation (merge and action-edge
costs, FreeSN paper section 6.2) and retrieval (section 6.3):

* ``"ik"`` -- the full-body IK objective (eq. 6) of moving the system onto the reference
  with the reference's kinematic tree: a fixed seed, the first start that reaches the
  IK tolerance ends the solve, at most :data:`IK_RESTARTS` sampled restarts of at most
  ``max_iterations`` L-BFGS-B iterations each. No clock bounds it, so the answer does not
  depend on machine load.
* ``"distance"`` -- the eq. 8 aligned distance (``vectorMatch``), for robots without
  joint modes (no kinematic tree to solve) or when asked for.

Ties. Costs from an iterative solver carry round-off that depends on the BLAS kernel, so
two mappings that a symmetry makes equally good come out a few ulps apart. Whatever
compares two costs or two distances to *choose* goes through :func:`tied`: values
within :data:`TIE_RELATIVE` (relative) or :data:`TIE_ABSOLUTE` of each other are equal,
and a stated key decides (see :func:`msrr.core.matching.matcher.match`).
"""

from __future__ import annotations

from collections.abc import Callable

from ..configuration import Configuration
from ..errors import MsrrError
from ..kinematics import IKOptions, KinematicTree, solve_ik
from .distance import vector_match

__all__ = [
    "CONFIDENCE",
    "COST_DISTANCE",
    "COST_IK",
    "COST_KINDS",
    "IK_OPTIONS",
    "IK_RESTARTS",
    "TIE_ABSOLUTE",
    "TIE_RELATIVE",
    "CostFn",
    "MatchingError",
    "check_cost",
    "distance_cost",
    "ik_cost",
    "motion_cost",
    "tied",
]

COST_IK = "ik"
COST_DISTANCE = "distance"
COST_KINDS = (COST_IK, COST_DISTANCE)

CONFIDENCE = 4.0
"""``sigma`` of Alg. 4: a candidate's search stops once a mapping's distance exceeds
``sigma`` times the best cost so far. The paper gives no value, only that the search may
stop when the distance is "much larger" than the minimum IK cost (section 5.2); 4 is that
reading, and the library builds of the shipped files use it."""

TIE_RELATIVE = 1e-6
"""Two costs (or distances) within this fraction of the larger one are tied."""

TIE_ABSOLUTE = 1e-12
"""Two costs (or distances) within this much [rad^2] are tied (exact matches cost ~0)."""

IK_RESTARTS = 2
"""Sampled IK restarts after the first start (the motion cost is bounded by restarts)."""

IK_OPTIONS = IKOptions(seed=0, max_restarts=IK_RESTARTS, time_budget=None, polish=0)
"""The IK settings of the motion cost: fixed seed, bounded restarts and iterations, no
clock (``time_budget=None``), stop at the first start under the IK tolerance."""

CostFn = Callable[[Configuration, KinematicTree | None, Configuration], float]
"""``cost_fn(reference, tree, system_in_reference_ids) -> cost``."""


class MatchingError(MsrrError):
    """Bad arguments to the matcher or the motion cost (a bad confidence, cost kind...)."""


def tied(a: float, b: float) -> bool:
    """Whether ``a`` and ``b`` count as equal under the tie rule (see the module doc)."""
    return abs(a - b) <= TIE_ABSOLUTE + TIE_RELATIVE * max(abs(a), abs(b))


def check_cost(kind: str) -> str:
    """``kind`` if it names a motion cost, else :class:`MatchingError`."""
    if kind not in COST_KINDS:
        raise MatchingError(f"unknown motion cost {kind!r} (known: {', '.join(COST_KINDS)})")
    return kind


def distance_cost(reference: Configuration, tree: KinematicTree | None,
                  system: Configuration) -> float:
    """Eq. 8 aligned distance [rad^2] of ``system`` (in reference ids) to ``reference``."""
    del tree
    ids = [e.id for e in reference.edges() if e.z is not None and system.edge(e.id).z is not None]
    if not ids:
        return 0.0
    return float(vector_match(system.vectors(ids), reference.vectors(ids)).cost)


def ik_cost(reference: Configuration, tree: KinematicTree | None,
            system: Configuration) -> float:
    """Full-body IK objective (eq. 6) of moving ``system`` (in reference ids) to ``reference``.

    Args:
        tree: the reference's kinematic tree (over the reference's ids).

    Raises:
        MatchingError: no tree.
    """
    if tree is None:
        raise MatchingError(f"the IK motion cost needs a kinematic tree for {reference.name!r}")
    return float(solve_ik(tree, system, reference, options=IK_OPTIONS).cost)


COST_FUNCTIONS: dict[str, CostFn] = {COST_IK: ik_cost, COST_DISTANCE: distance_cost}


def motion_cost(kind: str, tree: KinematicTree | None, current: Configuration,
                target: Configuration) -> float:
    """Motion cost of ``kind`` from ``current`` to ``target`` (same ids and topology)."""
    return COST_FUNCTIONS[check_cost(kind)](target, tree, current)
