"""The ``library`` planner: behavior-library retrieval as a planner (FreeSN paper, 6.3).

Any robot that ships behavior libraries (``msrr_libraries``) gets it: the plugin host
registers a :class:`LibraryPlanner` over the robot's library files after the robot's own
planners and before the generic runtime's. It shares :func:`~.retrieve.retrieve` with
``platform library retrieve``:

* :meth:`LibraryPlanner.plan` matches the goal into the system's sub-library (Alg. 4)
  to name the target configuration, then retrieves the cheapest action path from the
  system to it (Fig. 15): an approach move to the matched start (left out when the
  system already is it), then one action per action edge, each with its target and
  kinematic tree in the system's ids and one frame;
* :meth:`LibraryPlanner.plan_behavior` retrieves the path to a behavior's start, then
  appends the behavior: one ``BEHAVIOR`` action for a mapping behavior (its linear map
  in the system's ids, the commanded direction turned into the system's frame), or the
  sequence's steps for every loop.

A library file holds sub-libraries by module counts; the planner reads the file named
after the system's sub-library (``S6N3.json``) first, then any other, once each, with
the flags of its feasibility check file applied (:func:`~.check.apply_sidecar`).
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..actions import topology_diff
from ..alignment import rot_z
from ..configuration import Configuration
from ..console import plural
from ..errors import PlanningError
from ..plan import Action, ActionType, BehaviorCall, Plan
from ..robot import Robot
from ..shape import skeletal_error
from .check import apply_sidecar
from .model import Library, LibraryError, RetrievalError
from .retrieve import Retrieval, locate, retrieve
from .storage import load_library

__all__ = ["DEFAULT_DURATION", "MAX_LOOPS", "SAME_SHAPE", "LibraryPlanner"]

SAME_SHAPE = 1e-3
"""RMS strut angle [rad] under which the system counts as already at the matched start."""

DEFAULT_DURATION = 30.0
"""How long a mapping behavior runs when no duration is given [s]."""

MAX_LOOPS = 50
"""Loops of a sequence behavior planned when only a distance bounds it."""


class LibraryPlanner:
    """Plans by library retrieval (section 6.3, Fig. 15).

    Args:
        robot: the robot (spec, joint modes).
        libraries: the robot's library files (``msrr_libraries``).
    """

    name = "library"
    description = "behavior-library retrieval: match, cheapest action path, remap (Fig. 15)"
    generic = True   # the core's, offered to every robot with libraries

    def __init__(self, robot: Robot, libraries: Sequence[Path]):
        self.robot = robot
        self.libraries = [Path(p) for p in libraries]
        self._loaded: dict[Path, Library] = {}

    # -- libraries -----------------------------------------------------------------------

    def _load(self, path: Path) -> Library:
        if path not in self._loaded:
            library = load_library(path, self.robot)
            apply_sidecar(library, path)
            self._loaded[path] = library
        return self._loaded[path]

    def library_for(self, system: Configuration) -> Library:
        """The library holding the system's sub-library (``S6N3``).

        Raises:
            PlanningError: none of the robot's libraries has it (names the ones there are).
        """
        label = system.signature().label(self.robot.spec)
        ordered = sorted(self.libraries, key=lambda p: p.stem != label)
        for path in ordered:
            library = self._load(path)
            if label in library.sublibraries:
                return library
        known = sorted({s for p in self.libraries for s in self._load(p).sublibraries})
        raise PlanningError(f"no {self.robot.name} library for {label} (there are: "
                            f"{', '.join(known) or 'none'})")

    # -- planning ------------------------------------------------------------------------

    def plan(self, start: Configuration, goal: Configuration, *, seed: int = 0) -> Plan:
        """The retrieved action sequence from ``start`` to the library configuration
        ``goal`` matches (in any ids), ending at that configuration in the system's ids.

        Raises:
            PlanningError: no library for the system's module counts.
            RetrievalError: the goal matches nothing or cannot be reached.
        """
        began = time.perf_counter()
        if start.modules() == goal.modules() and not topology_diff(start, goal) \
                and skeletal_error(start, goal) < SAME_SHAPE:
            return Plan(self.robot.name, self.name, start, goal, [],
                        notes=["the system is already at the goal"])
        library = self.library_for(start)
        label = start.signature().label(self.robot.spec)
        if goal.signature().label(self.robot.spec) != label:
            raise RetrievalError(f"the goal {goal.name or ''} has other modules than the "
                                 f"system ({goal.signature().label(self.robot.spec)}, not {label})")
        try:
            located = locate(library, goal, self.robot)
        except RetrievalError:
            raise RetrievalError(f"the goal {goal.name or ''} matches no configuration of "
                                 f"{label}") from None
        retrieval = retrieve(library, start, self.robot, to=located.key)
        actions = self._path(retrieval, start)
        plan = self._plan(start, retrieval, actions, began, located.key)
        # the system's ids -> the goal file's: through the target's library ids
        assert retrieval.target_mapping is not None
        to_goal = retrieval.target_mapping.inverse().then(located.mapping.inverse())
        plan.mapping = {m: to_goal.nodes[m] for m in start.vertices()
                        if not start.is_virtual(m) and m in to_goal.nodes}
        return plan

    def plan_behavior(self, start: Configuration, behavior: str, *,
                      parameters: Mapping[str, float] | None = None,
                      duration: float | None = None, loops: int | None = None,
                      distance: float | None = None, seed: int = 0) -> Plan:
        """The path to ``behavior``'s start configuration, then the behavior (sections
        4.3, 6.3): one ``BEHAVIOR`` action for a mapping behavior (``duration``
        [s], default :data:`DEFAULT_DURATION`, or until ``distance`` [m]), or the steps
        of a sequence behavior ``loops`` times (default 1; :data:`MAX_LOOPS` when only
        ``distance`` bounds it).

        Raises:
            PlanningError: no library, no such behavior (the message lists the known
                ones), unknown parameters, or the start cannot be reached.
        """
        began = time.perf_counter()
        library = self.library_for(start)
        try:
            retrieval = retrieve(library, start, self.robot, behavior=behavior)
        except LibraryError as exc:
            raise PlanningError(str(exc)) from None
        chosen = retrieval.behavior
        assert chosen is not None
        values = dict(parameters or {})
        unknown = sorted(set(values) - set(chosen.parameters))
        if unknown:
            raise PlanningError(f"behavior {behavior} has no parameter {', '.join(unknown)} "
                                f"(its parameters: {', '.join(chosen.parameters) or 'none'})")
        if chosen.kind == "mapping" and loops is not None:
            raise PlanningError(f"behavior {chosen.name} is a mapping: it runs for a duration "
                                "or a distance, not loops")
        if chosen.kind == "sequence" and duration is not None:
            raise PlanningError(f"behavior {chosen.name} is a sequence: it runs loops or a "
                                "distance, not a duration")
        actions = self._path(retrieval, start)
        at = retrieval.steps[-1]
        # ``speed`` (a mapping) or the sequence's travel (its designed direction) is +x
        direction = rot_z(at.yaw) @ np.array([1.0, 0.0, 0.0])
        heading = (float(direction[0]), float(direction[1]), float(direction[2]))
        if chosen.kind == "mapping":
            call = BehaviorCall(
                chosen.name, "mapping", values, retrieval.commands,
                duration=duration if duration is not None or distance is not None
                else DEFAULT_DURATION, distance=distance, direction=heading,
                drive_root=retrieval.drive_root)
            actions.append(Action(ActionType.BEHAVIOR, at.target, kinematic_tree=at.tree,
                                  note=f"behavior {chosen.name}", behavior=call,
                                  retrieved=f"{retrieval.sublibrary} {at.library_id} "
                                            f"(behavior {chosen.name})"))
        else:
            count = loops if loops is not None else (MAX_LOOPS if distance is not None else 1)
            if count > 1 and not chosen.loop:
                raise PlanningError(f"behavior {chosen.name} does not loop; it runs once")
            steps = retrieval.actions(start)[len(retrieval.steps):]
            for loop in range(count):
                call = BehaviorCall(chosen.name, "sequence", values, loops=count, loop=loop,
                                    distance=distance, direction=heading,
                                    drive_root=retrieval.drive_root)
                actions += [replace(a, behavior=call) for a in steps]
        plan = self._plan(start, retrieval, actions, began, f"behavior {chosen.name}")
        plan.goal = actions[-1].target if actions else start
        return plan

    # -- helpers -------------------------------------------------------------------------

    @staticmethod
    def _path(retrieval: Retrieval, start: Configuration) -> list[Action]:
        """The actions to the retrieval's target; no approach move when the system already
        is the matched start."""
        actions = retrieval.actions(start)[:len(retrieval.steps)]
        if actions and actions[0].type is ActionType.MOVING \
                and skeletal_error(start, actions[0].target) < SAME_SHAPE:
            actions = actions[1:]
        if actions:
            actions[0].retrieved += f"; system -> {retrieval.start}: " + \
                retrieval.mapping_text(start)
        return actions

    def _plan(self, start: Configuration, retrieval: Retrieval, actions: list[Action],
              began: float, target: str) -> Plan:
        goal = retrieval.steps[-1].target
        assert retrieval.target_mapping is not None   # system ids -> the target's library ids
        back = retrieval.target_mapping.inverse()
        mapping = {m: back.nodes[m] for m in start.vertices()
                   if not start.is_virtual(m) and m in back.nodes}
        path = " -> ".join(s.library_id for s in retrieval.steps)
        return Plan(self.robot.name, self.name, start, goal, actions, mapping=mapping,
                    notes=[f"library {retrieval.sublibrary}: {path} to {target} "
                           f"({plural(len(actions), 'action')}, motion cost {retrieval.cost:.4g})"],
                    stats={"time_ms": (time.perf_counter() - began) * 1e3})
