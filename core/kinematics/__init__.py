"""Skeletal kinematics of freeform modular robots (FreeSN paper, section 3).

Nouns, mink style: the *model* is a :class:`KinematicTree` of :class:`KinematicNode`
objects over a configuration's topology; :func:`forward` is the skeletal forward
kinematics (Alg. 1); :func:`solve_ik` is the full-body inverse kinematics (eqs. 6-8)
returning an :class:`IKSolution`; :class:`IKTracker` runs it tick by tick for the
executor. Robot plugins add joint modes through ``msrr_kinematic_nodes``.

Example::

    from msrr.core.kinematics import default_tree, forward, solve_ik, IKOptions

    tree = default_tree(config)            # fixed root at the centre, default joints
    moved = forward(tree, config, sigma).configuration
    sol = solve_ik(tree, config, target, IKOptions(time_budget=0.1))
    sol.sigma, sol.yaw, sol.rms_angle, sol.success
"""

from .build import default_tree, tree_centre
from .cycles import cyclic_groups, find_cycle_through
from .fk import Evaluator, FKResult, FKState, forward, tree_vectors
from .ground import GroundContact, GroundModel, GroundOp
from .ik import IKOptions, IKProblem, IKSolution, solve_ik
from .node import (
    FAMILIES,
    FixedNode,
    KinematicNode,
    KinematicTreeError,
    ModuleJointNode,
    NodeBatch,
    NodeForward,
    NodeJacobian,
    ParallelNode,
)
from .rotations import (
    canonical_perpendicular,
    rodrigues,
    rotation_between,
    rotation_between_omega,
    skew,
    vee,
)
from .tracker import IKTracker
from .tree import KinematicTree, check_same_topology, load_tree, save_tree
from .tree_file import TREE_SCHEMA_VERSION, KinematicTreeFile, NodeTypes

__all__ = [
    "FAMILIES",
    "TREE_SCHEMA_VERSION",
    "Evaluator",
    "FKResult",
    "FKState",
    "FixedNode",
    "GroundContact",
    "GroundModel",
    "GroundOp",
    "IKOptions",
    "IKProblem",
    "IKSolution",
    "IKTracker",
    "KinematicNode",
    "KinematicTree",
    "KinematicTreeError",
    "KinematicTreeFile",
    "ModuleJointNode",
    "NodeBatch",
    "NodeForward",
    "NodeJacobian",
    "NodeTypes",
    "ParallelNode",
    "canonical_perpendicular",
    "check_same_topology",
    "cyclic_groups",
    "default_tree",
    "find_cycle_through",
    "forward",
    "load_tree",
    "rodrigues",
    "rotation_between",
    "rotation_between_omega",
    "save_tree",
    "skew",
    "solve_ik",
    "tree_centre",
    "tree_vectors",
    "vee",
]
