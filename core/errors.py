"""The error hierarchy: one root, :class:`MsrrError`, with specific subclasses.

Every error a user can cause (a bad file, an unknown robot, an impossible target)
is an ``MsrrError`` whose ``str()`` is one line that says what and where; the CLI
prints that line and exits non-zero instead of showing a traceback.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Final

__all__ = [
    "MAX_MESSAGE",
    "ConfigurationError",
    "DockingRuleError",
    "ExecutionError",
    "MsrrError",
    "OutputError",
    "PlanningError",
    "PluginError",
    "UnknownNameError",
    "UnknownRobotError",
    "one_line",
    "short_source",
]

MAX_MESSAGE: Final = 300
"""Longest error line [characters]; longer ones are shortened in the middle."""


def one_line(text: str, limit: int = MAX_MESSAGE) -> str:
    """``text`` on one line of at most ``limit`` characters.

    Line breaks and tabs become spaces; a longer text keeps its head and tail around
    ``" … "`` (the head says what, the tail usually where or why). Characters that
    are not printable (control characters, lone surrogates) are shown as escapes.
    """
    flat = " ".join(text.split())
    if not flat.isprintable():  # control characters, lone surrogates: escaped
        flat = "".join(c if c.isprintable() else repr(c)[1:-1] for c in flat)
    if len(flat) <= limit:
        return flat
    head = (limit - 3) * 2 // 3
    tail = limit - 3 - head
    return f"{flat[:head]} … {flat[len(flat) - tail:]}"


def short_source(path: str, limit: int = 120) -> str:
    """A file path on one line of at most ``limit`` characters, shortened in the
    folders, never in the file's own name (that is what a reader looks for)."""
    flat = one_line(path, 10 * limit)
    if len(flat) <= limit:
        return flat
    name = flat.rsplit("/", 1)[-1]
    if len(name) + 4 >= limit:
        return one_line(name, limit)
    return f"{flat[:limit - 4 - len(name)]} …/{name}"


class MsrrError(Exception):
    """Root of every error msrr raises on purpose; ``str()`` is :func:`one_line`."""

    def __str__(self) -> str:
        return one_line(super().__str__())


class ConfigurationError(MsrrError):
    """A configuration (file or in-memory) is malformed.

    Args:
        message: what is wrong.
        source: where it came from (a file path), if anywhere.
        field: the offending field, as a dotted path such as ``connections[3].z``.
        problems: every problem found, ``(field, message)`` each, the first being the
            one the message names (``platform validate --all`` prints them all).
    """

    def __init__(self, message: str, *, source: str | None = None, field: str | None = None,
                 problems: tuple[tuple[str | None, str], ...] = ()):
        self.message = message
        self.source = source
        self.field = field
        self.problems = problems or ((field, message),)
        super().__init__(str(self))

    def __str__(self) -> str:
        # file and field stay readable: each gets a share, the message the rest
        source = short_source(self.source) if self.source else ""
        field = one_line(self.field, 80) if self.field else ""
        where = ": ".join(p for p in (source, field) if p)
        room = MAX_MESSAGE - len(where) - (2 if where else 0)
        return ": ".join(p for p in (where, one_line(self.message, room)) if p)

    def at(self, source: str) -> ConfigurationError:
        """The same error, attributed to ``source`` (keeps an existing source)."""
        return type(self)(self.message, source=self.source or source, field=self.field,
                          problems=self.problems)


class OutputError(ConfigurationError):
    """A file or folder could not be written (a full disk, no permission, a place that
    is not a folder); ``source`` names it. Nothing is left under its final name."""


class DockingRuleError(ConfigurationError):
    """A configuration breaks its robot's docking rules (illegal port pair, topology)."""


class UnknownNameError(MsrrError, KeyError):
    """A name (robot, joint mode, planner, scenario, ...) that nothing registered.

    The message lists the valid choices.
    """

    def __init__(self, what: str, name: str, choices: Iterable[str], *,
                 source: str | None = None, field: str | None = None):
        self.what = what
        self.name = name
        self.choices = sorted(choices)
        self.source = source
        self.field = field
        super().__init__(str(self))

    def __str__(self) -> str:
        known = ", ".join(self.choices) if self.choices else "none"
        where = "".join(f"{text}: " for text in (
            short_source(self.source) if self.source else "",
            one_line(self.field, 120) if self.field else "") if text)
        return one_line(f"{where}unknown {self.what} {self.name!r} (known: {known})")


class UnknownRobotError(UnknownNameError):
    """No installed plugin describes a robot of this name."""

    def __init__(self, name: str, choices: Iterable[str], *, source: str | None = None,
                 field: str | None = None):
        super().__init__("robot", name, choices, source=source, field=field)


class PluginError(MsrrError):
    """A plugin could not be loaded or broke the plugin contract."""


class PlanningError(MsrrError):
    """No plan exists (different module counts, an illegal goal) or the planner gave up."""


class ExecutionError(MsrrError):
    """A plan could not be carried out: an action timed out or a module stopped answering."""
