"""Action targets derived from the previous action without copying (for large plans).

A plan of n modules and k actions holds k target configurations; copying one for
every action costs O(n k) (72 % of the planning time at 500 modules). A
:class:`DerivedConfiguration` only records its predecessor and the connections its
action makes or breaks; it builds itself, from the nearest predecessor already
built plus the recorded changes, the first time anything reads it. Executing a plan
in order therefore builds each target once, from the one before it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from msrr.core import Configuration

__all__ = ["Change", "DerivedConfiguration"]

Change = tuple[str, str, str, str, str, str]
"""``("connect", source, target, source_port, target_port, edge_id)`` or
``("disconnect", edge_id, "", "", "", "")``."""


class DerivedConfiguration(Configuration):
    """``parent`` plus ``changes``, built on first use (a :class:`Configuration` then).

    Args:
        parent: the configuration before this one (plain or derived).
        changes: connections made or broken, in order.
    """

    def __init__(self, parent: Configuration, changes: Sequence[Change] = ()):  # noqa: D107
        # no super().__init__(): every attribute of a Configuration appears on first use
        object.__setattr__(self, "_lazy", (parent, tuple(changes)))

    def __getattr__(self, name: str) -> Any:
        # only called for attributes not set yet, i.e. before the configuration is built
        lazy = self.__dict__.get("_lazy")
        if lazy is None or name.startswith("__"):
            raise AttributeError(name)
        self._build()
        return getattr(self, name)

    def _build(self) -> None:
        chain: list[DerivedConfiguration] = []
        node: Configuration = self
        while isinstance(node, DerivedConfiguration) and "_lazy" in node.__dict__:
            chain.append(node)
            node = node.__dict__["_lazy"][0]
        built = node.copy()
        for derived in reversed(chain):
            for op, a, b, pa, pb, edge_id in derived.__dict__["_lazy"][1]:
                if op == "connect":
                    built.connect(a, b, id=edge_id, ports=(pa, pb))
                else:
                    built.disconnect(a)
        del self.__dict__["_lazy"]
        for key, value in built.__dict__.items():  # a name set before the build wins
            self.__dict__.setdefault(key, value)

    def __reduce_ex__(self, protocol: int) -> Any:
        if "_lazy" in self.__dict__:
            self._build()
        return _plain, (Configuration.derive(self),)


def _plain(config: Configuration) -> Configuration:
    """Unpickle a derived configuration as the plain one it stands for."""
    return config
