"""The FreeSN library planner: behavior-library retrieval as a ``platform run`` planner.

``plan(start, goal)`` finds the shipped library of the system's sub-library (``S6N3``,
``S4N5``, ``S12N6``: ``plugins/freesn/libraries/<label>.json``, with the feasibility flags
of its check file applied), matches the goal into it (Alg. 4) to name the target
configuration, and retrieves the cheapest action path from the system to it (section
6.3, Fig. 15): an approach move to the matched start, then one action per edge, each
with its kinematic tree in the system's ids. The plan's goal is the last step's target
in the system's ids.
"""

from __future__ import annotations

import time
from pathlib import Path

from msrr.core.actions import topology_diff
from msrr.core.configuration import Configuration
from msrr.core.errors import PlanningError
from msrr.core.library import RetrievalError, load_library, retrieve
from msrr.core.library.check import apply_sidecar
from msrr.core.library.engine import best_match
from msrr.core.library.retrieve import library_cost
from msrr.core.plan import ActionType, Plan
from msrr.core.robot import Robot
from msrr.core.shape import skeletal_error

__all__ = ["LIBRARIES", "LibraryPlanner"]

LIBRARIES = Path(__file__).resolve().parent / "libraries"
"""The shipped FreeSN libraries."""


SAME_SHAPE = 1e-3
"""RMS strut angle [rad] under which the system counts as already at the matched start."""


class LibraryPlanner:
    """Plans by library retrieval (section 6.3).

    Args:
        robot: the FreeSN robot (spec, joint modes).
        folder: where ``<sub-library>.json`` files are.
    """

    name = "library"
    description = "behavior-library retrieval: match, cheapest action path, remap (Fig. 15)"

    def __init__(self, robot: Robot, folder: Path = LIBRARIES):
        self.robot = robot
        self.folder = folder

    def plan(self, start: Configuration, goal: Configuration, *, seed: int = 0) -> Plan:
        """The retrieved action sequence from ``start`` to the library configuration
        ``goal`` matches.

        Raises:
            PlanningError: no shipped library for the system's module counts.
            RetrievalError: the goal matches nothing or cannot be reached.
        """
        began = time.perf_counter()
        if start.modules() == goal.modules() and not topology_diff(start, goal) \
                and skeletal_error(start, goal) < SAME_SHAPE:
            return Plan(self.robot.name, self.name, start, goal, [],
                        notes=["the system is already at the goal"])
        label = start.signature().label(self.robot.spec)
        path = self.folder / f"{label}.json"
        if not path.exists():
            known = sorted(p.stem for p in self.folder.glob("*.json") if ".check" not in p.name)
            raise PlanningError(f"no FreeSN library for {label} (shipped: {', '.join(known)})")
        library = load_library(path)
        apply_sidecar(library, path)
        sub = library.sublibrary(label)
        candidates = [(c.id, c.configuration, next(iter(sub.groups[c.group].trees.values())))
                      for c in sub.configurations.values()
                      if sub.groups[c.group].reference.signature() == goal.signature()]
        found = best_match(goal, candidates, library_cost(library), self.robot.joint_modes) \
            if candidates else None
        if found is None:
            raise RetrievalError(f"the goal {goal.name or ''} matches no configuration of {label}")
        retrieval = retrieve(library, start, self.robot, to=found.key)
        actions = retrieval.actions(start)
        if actions and actions[0].type is ActionType.MOVING \
                and skeletal_error(start, actions[0].target) < SAME_SHAPE:
            actions = actions[1:]   # the system already is the matched start: no approach
        target = retrieval.steps[-1].target
        return Plan(self.robot.name, self.name, start, target, actions,
                    notes=[f"library {label}: {retrieval.start} -> {found.key} "
                           f"({len(actions)} actions, motion cost {retrieval.cost:.4g})"],
                    stats={"time_ms": (time.perf_counter() - began) * 1e3})
