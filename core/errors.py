"""The error hierarchy: one root, :class:`MsrrError`, with specific subclasses.

Every error a user can cause (a bad file, an unknown robot, an impossible target)
is an ``MsrrError`` whose ``str()`` is one line that says what and where; the CLI
prints that line and exits non-zero instead of showing a traceback.
"""

from __future__ import annotations

from collections.abc import Iterable

__all__ = [
    "ConfigurationError",
    "DockingRuleError",
    "ExecutionError",
    "MsrrError",
    "PlanningError",
    "PluginError",
    "UnknownNameError",
    "UnknownRobotError",
]


class MsrrError(Exception):
    """Root of every error msrr raises on purpose."""


class ConfigurationError(MsrrError):
    """A configuration (file or in-memory) is malformed.

    Args:
        message: what is wrong.
        source: where it came from (a file path), if anywhere.
        field: the offending field, as a dotted path such as ``connections[3].z``.
    """

    def __init__(self, message: str, *, source: str | None = None, field: str | None = None):
        self.message = message
        self.source = source
        self.field = field
        super().__init__(str(self))

    def __str__(self) -> str:
        parts = [p for p in (self.source, self.field) if p]
        return ": ".join([*parts, self.message])

    def at(self, source: str) -> ConfigurationError:
        """The same error, attributed to ``source`` (keeps an existing source)."""
        return type(self)(self.message, source=self.source or source, field=self.field)


class DockingRuleError(ConfigurationError):
    """A configuration breaks its robot's docking rules (illegal port pair, topology)."""


class UnknownNameError(MsrrError, KeyError):
    """A name (robot, joint mode, planner, scenario, ...) that nothing registered.

    The message lists the valid choices.
    """

    def __init__(self, what: str, name: str, choices: Iterable[str]):
        self.what = what
        self.name = name
        self.choices = sorted(choices)
        super().__init__(str(self))

    def __str__(self) -> str:
        known = ", ".join(self.choices) if self.choices else "none"
        return f"unknown {self.what} {self.name!r} (known: {known})"


class UnknownRobotError(UnknownNameError):
    """No installed plugin describes a robot of this name."""

    def __init__(self, name: str, choices: Iterable[str]):
        super().__init__("robot", name, choices)


class PluginError(MsrrError):
    """A plugin could not be loaded or broke the plugin contract."""


class PlanningError(MsrrError):
    """No plan exists (different module counts, an illegal goal) or the planner gave up."""


class ExecutionError(MsrrError):
    """A plan could not be carried out: an action timed out or a module stopped answering."""
