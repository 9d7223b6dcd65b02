"""SnailBot's named runs (``platform run --robot snailbot [--scenario NAME]``).

Five SnailBots in a row on the ground (``chain5``: each crawls on the next, B5's foot
free). One stage per flow (FreeSN paper, section 4.1): B1 crawls over B2 onto B3, then
B2 over B3 onto B4 -- a branching tree (``tree5-flat``: B1 on B3, B2 and B3 on B4) --
and the same two flows in reverse bring the row back. Each intermediate configuration
is a goal the run is judged on (ground truth).
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


def _stages(*names: str) -> tuple[Stage, ...]:
    return tuple(Stage(goal=CONFIGS / f"{name}.json") for name in names)


SCENARIOS = (
    Scenario(name="chain-tree", start=CONFIGS / "chain5.json", goal=CONFIGS / "chain5-a.json",
             stages=_stages("tree5-flat", "chain5-a", "chain5"),
             description="five SnailBots: a row becomes a tree and a row again, by four flows",
             default=True),
    Scenario(name="chain-to-tree", start=CONFIGS / "chain5.json",
             goal=CONFIGS / "chain5-a.json", stages=_stages("tree5-flat"),
             description="five SnailBots: a row becomes a tree by two flows"),
    Scenario(name="tree-to-chain", start=CONFIGS / "tree5-flat.json",
             goal=CONFIGS / "chain5-a.json", stages=_stages("chain5"),
             description="five SnailBots: a tree becomes a row by two flows"),
    Scenario(name="sucker-turn", start=CONFIGS / "stand5.json",
             stages=(Stage(goal=CONFIGS / "stand5-laid.json", joint_mode="sucker_revolute"),),
             description="five SnailBots: B2 anchors on B3 with its sucker and turns about "
                         "it, laying B1 (anchored on B2) down on the floor"),
    Scenario(name="crawl-to-dock", start=CONFIGS / "row4.json", goal=CONFIGS / "row4-turned.json",
             description="four SnailBots: B1 lets go of the row, crawls round it over the floor "
                         "and docks on B4 at the other end"),
    _let_go_then_tree("forest-to-tree", "comb20",
                      "twenty SnailBots: six let go of a row of fourteen (a forest of "
                      "seven pieces), then each crawls one module along and docks (a tree)"),
    _let_go_then_tree("pieces-to-tree", "forest20",
                      "twenty SnailBots: a row of twelve and two rows of four let go of "
                      "each other (a forest of three pieces); each row of four is taken "
                      "apart and its modules crawl one by one to build it again across "
                      "the row (a tree)"),
)
"""The default first."""
