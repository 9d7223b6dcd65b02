"""The library's only door to the kinematics and the matcher.

Library creation and retrieval need four things from the rest of the core: a
kinematic tree for a designed topology, the motion cost between two configurations of
one topology (section 3.4), the configuration matcher (Alg. 4) and a tree expressed in
another set of ids. They are gathered here so the library code stays pure data
handling. The robot's joint modes come in as arguments; nothing here asks the plugin
host.

The motion cost and its tie rule are :mod:`msrr.core.matching.cost`'s: a fixed seed,
bounded restarts, no clock, and ties decided by a stated key, so building the same
sources twice -- on any machine -- gives the same library. A library records the cost
kind it was built with and retrieval matches with the same one.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from ..configuration import Configuration
from ..errors import MsrrError, UnknownNameError
from ..kinematics import KinematicTree, default_tree
from ..mapping import ModuleMap
from ..matching import Candidate, MatchingError, check_cost, match, motion_cost
from ..robot import Robot
from .model import LibraryError
from .sources import DesignedTree

__all__ = [
    "MatchOutcome",
    "best_match",
    "cost_kind",
    "design_tree",
    "edge_cost",
    "load_tree",
    "rename_tree",
    "tree_in_ids",
]

Modes = Mapping[str, type]
"""Joint modes by name (``Robot.joint_modes``)."""


@dataclass(frozen=True)
class MatchOutcome:
    """The best library candidate for a configuration.

    Attributes:
        key: the candidate's key (a library configuration id).
        mapping: system ids -> candidate ids (every vertex and edge).
        cost: motion cost from the system to the candidate.
        yaw: yaw [rad] that aligns the candidate with the system.
    """

    key: str
    mapping: ModuleMap
    cost: float
    yaw: float = 0.0


def design_tree(reference: Configuration, designed: DesignedTree, robot: Robot) -> dict:
    """The serialised kinematic tree of a designed group tree (Fig. 14(a)).

    A designed tree is a serialised tree (checked by loading it on ``reference``) or a
    joint mode of ``robot`` for the default tree of ``reference`` (the robot's default
    joint mode when it names none).
    """
    try:
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
    except MsrrError as exc:  # the kinematics' own errors name the problem
        raise LibraryError(f"kinematic tree {designed.name!r}: {exc}") from None


def load_tree(tree: dict, config: Configuration, modes: Modes) -> KinematicTree:
    """A :class:`~msrr.core.kinematics.KinematicTree` from its serialised form."""
    return KinematicTree.from_dict(tree, config, modes=modes)


def tree_in_ids(tree: dict, mapping: ModuleMap, config: Configuration, modes: Modes
                ) -> KinematicTree:
    """A serialised tree renamed by ``mapping`` and loaded on ``config`` (Fig. 15(c)).

    Vertex and edge ids of the stored topology and of every node are renamed; an edge
    mapped with ``inv`` has its ends swapped. Loading checks the renamed topology
    against ``config``.
    """
    return KinematicTree.from_dict(rename_tree(tree, mapping), config, modes=modes)


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


def cost_kind(kind: str) -> str:
    """``kind`` if it names a motion cost, else :class:`LibraryError`."""
    try:
        return check_cost(kind)
    except MatchingError as exc:
        raise LibraryError(str(exc)) from None


def edge_cost(kind: str, tree: dict, current: Configuration, target: Configuration,
              modes: Modes) -> float:
    """Motion cost (:func:`msrr.core.matching.motion_cost`) from ``current`` to ``target``
    (same ids and topology) with a serialised tree over those ids."""
    return motion_cost(kind, load_tree(tree, target, modes), current, target)


def best_match(system: Configuration, candidates: Sequence[tuple[str, Configuration, dict]],
               cost: str, modes: Modes) -> MatchOutcome | None:
    """The candidate the system matches best (Alg. 4), or ``None`` if none is isomorphic.

    Ties between candidates go to the one listed first (the matcher's tie rule).

    Args:
        system: the configuration to match, in its own ids.
        candidates: ``(key, configuration, serialised tree)`` triples.
        cost: the motion cost kind.
        modes: the robot's joint modes, to load the trees.
    """
    pool = [Candidate(config, load_tree(tree, config, modes), key)
            for key, config, tree in candidates]
    result = match(system, pool, cost=cost_kind(cost))
    if result is None:
        return None
    mapping = ModuleMap(dict(result.mapping.nodes), dict(result.mapping.edges))
    return MatchOutcome(str(result.candidate.key), mapping, float(result.cost),
                        float(result.mapping.yaw))
