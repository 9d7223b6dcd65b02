"""Action targets derived from the previous action without copying (for large plans).

A plan of n modules and k actions holds k target configurations; copying one for
every action costs O(n k) (72 % of the planning time at 500 modules). A
:class:`DerivedConfiguration` (:mod:`msrr.core.delta`) only records its predecessor and
the connections its action makes or breaks; it builds itself, from the nearest
predecessor already built plus the recorded changes, the first time anything reads it.
Executing a plan in order therefore builds each target once, from the one before it,
and a plan file stores just those changes.
"""

from __future__ import annotations

from collections.abc import Sequence

from msrr.core import Configuration
from msrr.core.configuration import Edge
from msrr.core.delta import ConfigurationDelta
from msrr.core.delta import DerivedConfiguration as _Derived

__all__ = ["Change", "DerivedConfiguration"]

Change = tuple[str, str, str, str, str, str]
"""``("connect", source, target, source_port, target_port, edge_id)`` or
``("disconnect", edge_id, "", "", "", "")``."""


class DerivedConfiguration(_Derived):
    """``parent`` plus ``changes`` (connections made or broken, in order), built on
    first use (a :class:`Configuration` then)."""

    def __init__(self, parent: Configuration, changes: Sequence[Change] = ()):  # noqa: D107
        removed = tuple(a for op, a, *_ in changes if op != "connect")
        made = tuple((Edge(edge_id, a, b, None, None, None, (pa, pb)), None)
                     for op, a, b, pa, pb, edge_id in changes if op == "connect")
        super().__init__(parent, ConfigurationDelta(removed_edges=removed, edges=made))
