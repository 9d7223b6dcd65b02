"""Configuration matching and mapping (FreeSN paper, section 5).

* :func:`iso_search` -- isomorphism tree search, mappings in ascending distance (Alg. 2-3);
* :func:`brute_force_isomorphisms` -- the independent reference: all isomorphisms, sorted;
* :func:`match` -- the best (reference, kinematic tree, mapping) by motion cost (Alg. 4);
* :mod:`.cost` -- the one motion cost (IK eq. 6 or distance eq. 8), ``sigma`` and the tie rule.
"""

from .brute_force import brute_force_isomorphisms, enumerate_isomorphisms
from .cost import (
    CONFIDENCE,
    COST_DISTANCE,
    COST_IK,
    COST_KINDS,
    CostFn,
    MatchingError,
    check_cost,
    distance_cost,
    ik_cost,
    motion_cost,
    tied,
)
from .distance import PartialBound, vector_match
from .iso_search import iso_search
from .mapping import EdgeImage, Mapping
from .matcher import Candidate, MatchResult, RankedMatch, mapping_key, match
from .topology import Topology, signatures_match, vf2pp_order

__all__ = [
    "CONFIDENCE",
    "COST_DISTANCE",
    "COST_IK",
    "COST_KINDS",
    "Candidate",
    "CostFn",
    "EdgeImage",
    "Mapping",
    "MatchResult",
    "MatchingError",
    "PartialBound",
    "RankedMatch",
    "Topology",
    "brute_force_isomorphisms",
    "check_cost",
    "distance_cost",
    "enumerate_isomorphisms",
    "ik_cost",
    "iso_search",
    "mapping_key",
    "match",
    "motion_cost",
    "signatures_match",
    "tied",
    "vector_match",
    "vf2pp_order",
]
