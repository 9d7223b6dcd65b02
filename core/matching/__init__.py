"""Configuration matching and mapping (FreeSN paper, section 5).

* :func:`iso_search` -- isomorphism tree search, mappings in ascending distance (Alg. 2-3);
* :func:`brute_force_isomorphisms` -- the independent reference: all isomorphisms, sorted;
* :func:`match` -- the best (reference, kinematic tree, mapping) by motion cost (Alg. 4).
"""

from .brute_force import brute_force_isomorphisms, enumerate_isomorphisms
from .distance import PartialBound, vector_match
from .iso_search import iso_search
from .mapping import EdgeImage, Mapping
from .matcher import (
    COST_DISTANCE,
    COST_IK,
    Candidate,
    CostFn,
    MatchingError,
    MatchResult,
    RankedMatch,
    distance_cost,
    ik_cost,
    match,
)
from .topology import Topology, signatures_match, vf2pp_order

__all__ = [
    "COST_DISTANCE",
    "COST_IK",
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
    "distance_cost",
    "enumerate_isomorphisms",
    "ik_cost",
    "iso_search",
    "match",
    "signatures_match",
    "vector_match",
    "vf2pp_order",
]
