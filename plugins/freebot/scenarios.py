"""FreeBOT's named runs (``platform run --robot freebot [--scenario NAME]``).

Six FreeBOTs lie in a row on the ground (``line6``: every magnet holds on towards F3,
whose magnet is free). One stage per flow (FreeSN paper, section 4.1): F1 rolls over F2
onto F3, F6 over F5 onto F4 and then onto F3, F5 over F4 onto F3 -- a five-armed star
around F3 (``star6-flat``) -- and the same four flows in reverse bring the row back.
Each intermediate configuration is a goal the run is judged on (ground truth).

``roll-to-dock``: four FreeBOTs in a row (``row4``, every magnet towards F4); F1 lets go
of F2, rolls round the row over the floor, found again from its own reports (dead
reckoning, :mod:`msrr.core.freeform.travel`), and docks on F4 at the other end
(``row4-turned``): one break-and-make step of the MISO plan.

``chains-to-tree``: three chains of four (``chains12``), let go of each other; two of them
travel over the floor, each as one rigid piece whose every shell rolls, turn a right angle
and dock across the third (``chains12-tree``): MISO steps that move a module together with
the modules docked on it.
"""

from __future__ import annotations

from pathlib import Path

from msrr.core.scenario import Scenario, Stage

__all__ = ["CONFIGS", "SCENARIOS"]

CONFIGS = Path(__file__).resolve().parent / "configs"


def _let_go_then_tree(name: str, folder: str, description: str) -> Scenario:
    """From ``folder/folder.json`` its pieces let go (``-forest``), then a tree (``-tree``)."""
    return Scenario.through(name, description, *(CONFIGS / folder / f"{folder}{stage}.json"
                                                 for stage in ("", "-forest", "-tree")))


_TO_STAR = ("line6-a", "line6-b", "line6-c", "star6-flat")
_BACK = ("line6-c", "line6-b", "line6-a", "line6")


def _stages(names: tuple[str, ...]) -> tuple[Stage, ...]:
    return tuple(Stage(goal=CONFIGS / f"{name}.json") for name in names)


SCENARIOS = (
    Scenario(name="chain-star", start=CONFIGS / "line6.json",
             goal=CONFIGS / f"{_TO_STAR[0]}.json", stages=_stages(_TO_STAR[1:] + _BACK),
             description="six FreeBOTs: a row becomes a star and a row again, by eight flows",
             default=True),
    Scenario(name="chain-to-star", start=CONFIGS / "line6.json",
             goal=CONFIGS / f"{_TO_STAR[0]}.json", stages=_stages(_TO_STAR[1:]),
             description="six FreeBOTs: a row becomes a star by four flows"),
    Scenario(name="star-to-chain", start=CONFIGS / "star6-flat.json",
             goal=CONFIGS / f"{_BACK[0]}.json", stages=_stages(_BACK[1:]),
             description="six FreeBOTs: a star becomes a row by four flows"),
    Scenario(name="roll-to-dock", start=CONFIGS / "row4.json", goal=CONFIGS / "row4-turned.json",
             description="four FreeBOTs: F1 lets go of the row, rolls round it over the floor "
                         "and docks on F4 at the other end"),
    _let_go_then_tree("chains-to-tree", "chains12",
                      "twelve FreeBOTs: three chains of four let go of each other, then "
                      "two of them each travel as one piece, turn and dock across the "
                      "third (a tree)"),
    _let_go_then_tree("forest-to-tree", "comb20",
                      "twenty FreeBOTs: six let go of a row of fourteen (a forest of "
                      "seven pieces), then each rolls one module along and docks (a tree)"),
    _let_go_then_tree("pieces-to-tree", "forest20",
                      "twenty FreeBOTs: a row of twelve and two rows of four let go of "
                      "each other (a forest of three pieces), then the two rows of four "
                      "each travel as one piece, turn and dock across the row (a tree)"),
)
"""The default first."""
