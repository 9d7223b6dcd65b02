"""Matching and mapping between subconfigurations (paper section 4.2).

Starting from the highest current subconfiguration, each one searches an MCS only
with goal subconfigurations of adjacent height, ``|h(tau_c^i) - h(tau_g^a)| <= 1``
(the height-adjacent rule). A matched pair is decomposed again, its new
subconfigurations and free vertices join the sets, and the iteration goes on until
every subconfiguration was visited. What stays unmatched is disconnected into free
vertices, so both free sets end with the same number of modules.
"""

from __future__ import annotations

from dataclasses import dataclass

from .mcs import Subconfiguration, decompose, largest_common
from .representation import FaceLinks

__all__ = ["HEIGHT_WINDOW", "MatchedPair", "SubconfigurationMatching", "match_subconfigurations"]

HEIGHT_WINDOW = 1
"""The height-adjacent rule: subconfigurations whose heights differ by at most this."""


@dataclass(frozen=True)
class MatchedPair:
    """An isomorphic pair {bar-G_c^k, bar-G_g^gamma} and its mapping (current -> goal)."""

    current: Subconfiguration
    goal: Subconfiguration
    mapping: dict[str, str]


@dataclass(frozen=True)
class SubconfigurationMatching:
    """The outcome of section 4.2.

    Attributes:
        pairs: matched subconfigurations, in the order they were found.
        free_current: hat-V_c after the matching (free vertices and dissolved modules).
        free_goal: hat-V_g likewise.
        dissolved_current: current subconfigurations left unmatched and disconnected.
        dissolved_goal: goal subconfigurations left unmatched.
        attempts: MCS searches made (pairs that passed the height rule).
    """

    pairs: tuple[MatchedPair, ...]
    free_current: tuple[str, ...]
    free_goal: tuple[str, ...]
    dissolved_current: tuple[Subconfiguration, ...]
    dissolved_goal: tuple[Subconfiguration, ...]
    attempts: int


def match_subconfigurations(links_c: FaceLinks, links_g: FaceLinks,
                            current: tuple[Subconfiguration, ...],
                            goal: tuple[Subconfiguration, ...], free_current: tuple[str, ...],
                            free_goal: tuple[str, ...], *, window: int = HEIGHT_WINDOW
                            ) -> SubconfigurationMatching:
    """Match subconfigurations by the height-adjacent rule, decomposing each match again.

    Args:
        links_c: face adjacency of G_c.
        links_g: face adjacency of G_g.
        current: tilde-G_c from the first decomposition.
        goal: tilde-G_g from the first decomposition.
        free_current: hat-V_c from the first decomposition.
        free_goal: hat-V_g from the first decomposition.
        window: largest allowed height difference (1 in the paper).
    """
    pending_c = list(current)
    pending_g = list(goal)
    tried: list[Subconfiguration] = []
    free_c, free_g = list(free_current), list(free_goal)
    pairs: list[MatchedPair] = []
    attempts = 0
    while pending_c:
        pending_c.sort(key=lambda s: (-s.height, -len(s.vertices)))
        sub_c = pending_c.pop(0)
        best: tuple[dict[str, str], int] | None = None
        for index, sub_g in enumerate(pending_g):
            if abs(sub_c.height - sub_g.height) > window:
                continue
            attempts += 1
            found = largest_common(links_c, links_g, sub_c.vertices, sub_g.vertices,
                                   prefer=(sub_c.root, sub_g.root))
            if len(found) > 1 and (best is None or len(found) > len(best[0])):
                best = (found, index)
        if best is None:
            tried.append(sub_c)
            continue
        mapping, index = best
        sub_g = pending_g.pop(index)
        pairs.append(MatchedPair(sub_c, sub_g, mapping))
        again = decompose(links_c, links_g, sub_c.vertices, sub_g.vertices, mapping)
        pending_c.extend(again.current)
        free_c.extend(again.free_current)
        free_g.extend(again.free_goal)
        if again.goal:
            pending_g.extend(again.goal)
            pending_c.extend(tried)
            tried.clear()
    for sub in tried:
        free_c.extend(sub.vertices)
    for sub in pending_g:
        free_g.extend(sub.vertices)
    return SubconfigurationMatching(tuple(pairs), tuple(free_c), tuple(free_g), tuple(tried),
                                    tuple(pending_g), attempts)
