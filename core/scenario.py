"""Named runs that ``platform run --robot ROBOT --scenario NAME`` starts."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

__all__ = ["Scenario"]


@dataclass(frozen=True)
class Scenario:
    """A start configuration, a goal configuration and the words to describe them.

    Attributes:
        name: identifier on the command line (``"cross-probe"``).
        description: one line for tables and progress output.
        start: path to the start configuration file.
        goal: path to the goal configuration file.
        default: whether ``platform run --robot ROBOT`` runs this one.
    """

    name: str
    description: str
    start: Path
    goal: Path
    default: bool = False
