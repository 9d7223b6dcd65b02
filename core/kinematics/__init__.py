"""Skeletal kinematics of freeform modular robots (FreeSN paper, section 3).

Nouns, mink style: the *model* is a :class:`KinematicTree` of :class:`KinematicNode`
objects over a configuration's topology (:mod:`.tree`; files in :mod:`.tree_file`,
the default tree in :mod:`.build`, cycles in :mod:`.cycles`); :func:`forward` is the
skeletal forward kinematics (Alg. 1, :mod:`.fk`); :func:`solve_ik` is the full-body
inverse kinematics (eqs. 6-8, :mod:`.ik`), whose objective is a sum of
:class:`IKTerm` objects, returning an :class:`IKSolution`; :class:`IKTracker` runs it
tick by tick. Nothing here asks the plugin host: joint modes and the robot spec come
in as arguments (``Robot.joint_modes``, ``Robot.default_joint_mode()``,
``Robot.spec``, see :func:`msrr.core.plugins.resolve`).

Example::

    from msrr.core.kinematics import IKOptions, default_tree, forward, solve_ik

    robot = plugins.resolve(config.robot)          # at the top layer
    tree = default_tree(config, robot.default_joint_mode())
    moved = forward(tree, config, sigma).configuration
    sol = solve_ik(tree, config, target, IKOptions(seed=0))
    sol.sigma, sol.yaw, sol.rms_angle, sol.success, sol.reason
"""

from .build import default_tree, tree_centre
from .cycles import cyclic_groups, find_cycle_through
from .fk import Evaluator, FKResult, FKState, forward, tree_vectors
from .ground import GroundContact, GroundModel, GroundOp
from .ik import (
    IKOptions,
    IKPose,
    IKProblem,
    IKSolution,
    IKTerm,
    MotionCostTerm,
    Objective,
    StopReason,
    TermValue,
    VectorAngleTerm,
    solve_ik,
)
from .joints import RevoluteJoint
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
    "IKPose",
    "IKProblem",
    "IKSolution",
    "IKTerm",
    "IKTracker",
    "KinematicNode",
    "KinematicTree",
    "KinematicTreeError",
    "KinematicTreeFile",
    "ModuleJointNode",
    "MotionCostTerm",
    "NodeBatch",
    "NodeForward",
    "NodeJacobian",
    "NodeTypes",
    "Objective",
    "StopReason",
    "ParallelNode",
    "RevoluteJoint",
    "TermValue",
    "VectorAngleTerm",
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
