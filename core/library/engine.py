"""The library's only door to the kinematics and the matcher.

Library creation and retrieval need four things from the rest of the core: a
kinematic tree for a designed topology, the inverse-kinematics motion cost between
two configurations of one topology (section 3.4), the configuration matcher
(Alg. 4) and a tree expressed in another set of ids. They are gathered here so the
library code stays pure data handling, and so a test can count or replace them.

Matching and inverse kinematics run with fixed seeds and restart-bounded options
(no clock decides a result), so building the same sources twice gives the same
library. The motion cost is the full-body IK cost, or the eq. 8 aligned distance
where the kinematics is not installed; a library records which one it was built
with and retrieval matches with the same one.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from ..configuration import Configuration
from ..errors import UnknownNameError
from ..mapping import ModuleMap
from .model import LibraryError
from .sources import DesignedTree

__all__ = [
    "MATCH_CONFIDENCE",
    "MatchOutcome",
    "best_match",
    "available_cost",
    "check_cost",
    "motion_cost",
    "design_tree",
    "load_tree",
    "rename_tree",
    "tree_in_ids",
]

MATCH_CONFIDENCE = 4.0
"""Confidence factor sigma of Alg. 4: stop a candidate's search past sigma * best cost."""

COST_IK = "ik"
COST_DISTANCE = "distance"
COST_KINDS = (COST_IK, COST_DISTANCE)

IK_SEED = 0
IK_RESTARTS = 2
IK_TIME_BUDGET = 120.0
"""IK solves end on tolerance or restarts, never on this generous clock, so they repeat."""


@dataclass(frozen=True)
class MatchOutcome:
    """The best library candidate for a configuration.

    Attributes:
        key: the candidate's key (a library configuration id).
        mapping: system ids -> candidate ids (every vertex and edge).
        cost: inverse-kinematics cost from the system to the candidate.
        yaw: yaw [rad] that aligns the candidate with the system.
    """

    key: str
    mapping: ModuleMap
    cost: float
    yaw: float = 0.0


def design_tree(reference: Configuration, designed: DesignedTree) -> dict:
    """The serialised kinematic tree of a designed group tree (Fig. 14(a)).

    A designed tree is a serialised tree (checked by loading it on ``reference``) or a
    joint mode for the default tree of ``reference``.
    """
    from ..kinematics import KinematicTree, default_tree

    try:
        robot = _robot(reference.robot)
        if designed.tree is not None:
            return KinematicTree.from_dict(designed.tree, reference,
                                           modes=robot.joint_modes).to_dict()
        if designed.joint_mode is None:
            joint_mode = robot.default_joint_mode()
        elif designed.joint_mode in robot.joint_modes:
            joint_mode = robot.joint_modes[designed.joint_mode]
        else:
            raise UnknownNameError(f"joint mode for robot {robot.name!r}", designed.joint_mode,
                                   robot.joint_modes)
        return default_tree(reference, joint_mode).to_dict()
    except LibraryError:
        raise
    except Exception as exc:  # the kinematics' own errors name the problem
        raise LibraryError(f"kinematic tree {designed.name!r}: {exc}") from None


def load_tree(tree: dict, config: Configuration) -> Any:
    """A :class:`~msrr.core.kinematics.KinematicTree` from its serialised form."""
    from ..kinematics.tree import KinematicTree

    return KinematicTree.from_dict(tree, config, modes=_robot(config.robot).joint_modes)


def tree_in_ids(tree: dict, mapping: ModuleMap, config: Configuration) -> Any:
    """A serialised tree renamed by ``mapping`` and loaded on ``config`` (Fig. 15(c)).

    Vertex and edge ids of the stored topology and of every node are renamed; an edge
    mapped with ``inv`` has its ends swapped. Loading checks the renamed topology
    against ``config``.
    """
    from ..kinematics.tree import KinematicTree

    return KinematicTree.from_dict(rename_tree(tree, mapping), config,
                                   modes=_robot(config.robot).joint_modes)


def _robot(name: str) -> Any:
    """Transitional: the robot's joint modes from the plugin host, until the library
    receives its ``Robot`` as an argument (issue 10)."""
    from ..plugins import resolve

    return resolve(name)


def rename_tree(tree: dict, mapping: ModuleMap) -> dict:
    """A serialised tree (``KinematicTree.to_dict()``) with its ids renamed by ``mapping``."""
    nodes, edges = mapping.nodes, mapping.edges
    out = dict(tree)
    out["modules"] = [{**m, "id": nodes[m["id"]]} for m in tree["modules"]]
    connections = []
    for c in tree["connections"]:
        image, inv = edges[c["id"]]
        source, target = nodes[c["source"]], nodes[c["target"]]
        renamed = {**c, "id": image, "source": target if inv else source,
                   "target": source if inv else target}
        if inv and c.get("ports"):
            renamed["ports"] = list(reversed(c["ports"]))
        connections.append(renamed)
    out["connections"] = connections
    out["nodes"] = [{**n, "edges": [edges[e][0] for e in n.get("edges", [])],
                     "vertices": [nodes[v] for v in n.get("vertices", [])]}
                    for n in tree["nodes"]]
    return out


def available_cost() -> str:
    """``"ik"`` when the full-body inverse kinematics is installed, else ``"distance"``."""
    try:
        from ..kinematics.ik import solve_ik  # noqa: F401
    except ImportError:
        return COST_DISTANCE
    return COST_IK


def check_cost(kind: str) -> str:
    if kind not in COST_KINDS:
        raise LibraryError(f"unknown motion cost {kind!r} (known: {', '.join(COST_KINDS)})")
    return kind


def motion_cost(kind: str, tree: Any, current: Configuration, target: Configuration) -> float:
    """Motion cost from ``current`` to ``target`` (same ids and topology).

    ``"ik"``: the full-body IK objective (eq. 6) with a fixed seed and a bounded number
    of restarts; ``"distance"``: the eq. 8 aligned distance, the matcher's stand-in
    when the kinematics is not installed.

    Args:
        tree: a :class:`KinematicTree` or its serialised form.
    """
    if check_cost(kind) == COST_DISTANCE:
        from ..matching import distance_cost

        return float(distance_cost(target, None, current))
    from ..kinematics.ik import IKOptions, solve_ik

    if isinstance(tree, dict):
        tree = load_tree(tree, target)
    options = IKOptions(seed=IK_SEED, max_restarts=IK_RESTARTS, time_budget=IK_TIME_BUDGET)
    return float(solve_ik(tree, current, target, options=options).cost)


def best_match(system: Configuration, candidates: Sequence[tuple[str, Configuration, dict]],
               cost: str) -> MatchOutcome | None:
    """The candidate the system matches best (Alg. 4), or ``None`` if none is isomorphic.

    Args:
        system: the configuration to match, in its own ids.
        candidates: ``(key, configuration, serialised tree)`` triples.
        cost: the motion cost kind (see :func:`motion_cost`).
    """
    from ..matching import Candidate, match

    pool = [Candidate(config, load_tree(tree, config), key=key)
            for key, config, tree in candidates]
    result = match(system, pool, confidence=MATCH_CONFIDENCE,
                   cost_fn=lambda ref, tree, sys: motion_cost(check_cost(cost), tree, sys, ref))
    if result is None:
        return None
    mapping = ModuleMap(dict(result.mapping.nodes), dict(result.mapping.edges))
    return MatchOutcome(str(result.candidate.key), mapping, float(result.cost),
                        float(getattr(result.mapping, "yaw", 0.0)))
