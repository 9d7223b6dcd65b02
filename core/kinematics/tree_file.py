"""The kinematic tree file format (``schema_version`` 1): its models and their reading.

A tree file holds the topology it covers (modules and connections, as in a
configuration file, without vectors) and the nodes in breadth-first order::

    {"schema_version": 1, "robot": "freesn", "configuration": "triangle-leg",
     "modules": [...], "connections": [...],
     "nodes": [{"type": "fixed", "edges": ["S1"], "vertices": ["N1", "N2"]},
               {"type": "parallel_strut", "edges": ["S2", "S3"], "vertices": ["N3"],
                "params": {"beta": 0.25}}, ...]}

This module turns a document into a topology and nodes and back;
:meth:`~.tree.KinematicTree.from_dict` and :meth:`~.tree.KinematicTree.to_dict` build
the tree from them.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from pydantic import Field

from ..configuration import Configuration
from ..errors import ConfigurationError, UnknownNameError
from ..files import Number, SchemaVersion, StrictModel, parse_model
from ..io import (
    ConfigurationFile,
    ConnectionModel,
    ModuleModel,
    configuration_from_model,
    configuration_to_model,
)
from .node import FixedNode, KinematicNode, KinematicTreeError

__all__ = [
    "TREE_SCHEMA_VERSION",
    "KinematicTreeFile",
    "NodeModel",
    "NodeTypes",
    "read_tree_document",
    "tree_document",
]

TREE_SCHEMA_VERSION = 1

NodeTypes = Mapping[str, type[KinematicNode]]
"""Node classes by joint-mode name, as in ``Robot.joint_modes``."""


class NodeModel(StrictModel):
    """One kinematic node of a tree file."""

    type: str = Field(min_length=1, description="Node type (joint mode) name, or 'fixed'.")
    edges: list[str] = Field(default_factory=list, description="Edge ids, in the node's order.")
    vertices: list[str] = Field(default_factory=list, description="Owned vertex ids (ports).")
    params: dict[str, Number] = Field(default_factory=dict,
                                     description="Node-type parameters that differ from defaults.")


class KinematicTreeFile(StrictModel):
    """A kinematic tree file: the topology it covers and its nodes in BFS order."""

    schema_version: SchemaVersion = Field(description="File format version.")
    robot: str = Field(min_length=1)
    configuration: str = Field(description="Name of the configuration it was made for "
                               "(may be empty; the key is required).")
    modules: list[ModuleModel]
    connections: list[ConnectionModel] = []
    nodes: list[NodeModel] = Field(min_length=1)


def tree_document(topology: Configuration, nodes: Iterable[KinematicNode]) -> dict[str, Any]:
    """The JSON-ready document of ``nodes`` over ``topology`` (vectors are not written)."""
    model = configuration_to_model(topology).model_dump(mode="json", exclude_none=True)
    return {"schema_version": TREE_SCHEMA_VERSION, "robot": topology.robot,
            "configuration": topology.name,
            "modules": model["modules"], "connections": model["connections"],
            "nodes": [node.to_dict() for node in nodes]}


def read_tree_document(data: Any, modes: NodeTypes, source: str | None = None
                       ) -> tuple[Configuration, list[KinematicNode]]:
    """The stored topology and the nodes of a tree document.

    Args:
        data: the parsed JSON.
        modes: node classes by name (``Robot.joint_modes``); ``"fixed"`` is
            :class:`FixedNode` unless given.
        source: file name for error messages.

    Raises:
        KinematicTreeError: a malformed document or an unknown node type (naming the
            field and listing the known types).
    """
    try:
        model = parse_model(KinematicTreeFile, data, source)
    except ConfigurationError as exc:
        raise KinematicTreeError(exc.message, source=exc.source, field=exc.field) from None
    topology = configuration_from_model(ConfigurationFile(
        schema_version=1, robot=model.robot, name=model.configuration,
        modules=model.modules, connections=model.connections), source)
    types = {"fixed": FixedNode, **modes}
    nodes = []
    for i, spec in enumerate(model.nodes):
        if spec.type not in types:
            raise KinematicTreeError(str(UnknownNameError(
                f"node type for robot {model.robot!r}", spec.type, types)),
                source=source, field=f"nodes[{i}].type")
        try:
            nodes.append(types[spec.type](spec.edges, spec.vertices, **spec.params))
        except ConfigurationError as exc:
            raise KinematicTreeError(exc.message, source=source, field=f"nodes[{i}]") from None
    return topology, nodes
