"""Library feasibility: the action edges as runnable cases, and the check file (section 6.2).

"The feasibility of the configuration sequences are evaluated using the simulation
during the library build" (FreeSN paper, section 6.2). A check runs every action edge
of a library from its source configuration in a simulator (the executor's closed loop,
:mod:`msrr.core.app.feasibility`) and records, per edge, whether it is feasible, why not,
and the simulated time.

**Where the flags live.** In a *sidecar* file beside the library, ``<LIB>.check.json``
(:func:`check_path`), not in the library file itself: a library build is a pure function
of its sources (the shipped files are rebuilt byte for byte), while a check depends on
the simulator, its options and its seed. The sidecar names the library file's SHA-256, so
a check of an older build is recognised as stale; :func:`apply_check` copies its flags
onto the library's :attr:`ActionEdge.feasible`, which retrieval then honours
(:meth:`SubLibrary.graph` leaves infeasible edges out).

This module receives the robot (:class:`~msrr.core.robot.Robot`) as an argument and never
asks the plugin host.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from pydantic import Field

from ..actions import detect_action
from ..configuration import Configuration
from ..files import StrictModel, atomic_write_text, parse_model, read_json
from ..plan import Action
from ..robot import Robot
from . import engine
from .model import ActionEdge, Library, LibraryError

__all__ = ["CHECK_REASONS", "CheckFile", "EdgeCase", "EdgeCheck", "apply_check",
           "apply_sidecar", "check_path", "edge_cases", "edge_key", "library_digest",
           "load_check", "save_check"]

CHECK_REASONS = ("timeout", "fell over", "connector broke", "self-collision", "torque limit",
                 "wrong shape", "wrong topology", "error")
"""Why an edge can be infeasible (the first reason found is recorded)."""


def edge_key(sub: str, edge: ActionEdge) -> str:
    """``"<sub-library>:<source>-><target>"``: one edge's name in a check file."""
    return f"{sub}:{edge.source}->{edge.target}"


@dataclass(frozen=True)
class EdgeCase:
    """One action edge, ready to run.

    Attributes:
        key: :func:`edge_key`.
        edge: the library edge.
        start: the source configuration (its group's reference ids).
        target: the target configuration in the source's ids (edge mapping inverted).
        action: the detected action, with the edge's kinematic tree in the right ids.
    """

    key: str
    edge: ActionEdge
    start: Configuration
    target: Configuration
    action: Action


def edge_cases(library: Library, robot: Robot) -> list[EdgeCase]:
    """Every action edge of ``library`` as an :class:`EdgeCase`, in file order.

    Raises:
        LibraryError: an edge's tree does not fit its configuration.
    """
    out = []
    for sub in library.sublibraries.values():
        for edge in sub.edges:
            source = sub.configurations[edge.source]
            start = source.configuration.skeletal()
            forward = edge.module_map(start)
            target_config = sub.configurations[edge.target].configuration.skeletal()
            target, back = forward.inverse().apply(
                target_config, name=sub.configurations[edge.target].name or edge.target)
            tree_doc = sub.groups[edge.tree.group].trees[edge.tree.name]
            try:
                if edge.tree.group == source.group:
                    tree = engine.load_tree(tree_doc, start, robot.joint_modes)
                else:
                    tree = engine.tree_in_ids(tree_doc, back, target, robot.joint_modes)
            except Exception as exc:  # the kinematics' own errors name the problem
                raise LibraryError(f"edge {edge_key(sub.name, edge)}: tree {edge.tree}: "
                                   f"{exc}") from None
            action = detect_action(start, target, note=f"library {edge_key(sub.name, edge)}")
            action.kinematic_tree = tree
            action.cost = edge.cost
            out.append(EdgeCase(edge_key(sub.name, edge), edge, start.copy(), target, action))
    return out


class EdgeCheck(StrictModel):
    """The check of one edge.

    Attributes:
        edge: :func:`edge_key`.
        action: the action type.
        feasible: ran to the target in simulation.
        reason: why not (one of :data:`CHECK_REASONS`, then details), ``""`` when feasible.
        sim_time: simulated time of the run [s].
        shape_error_deg: final RMS strut angle to the target after yaw alignment, ground truth.
        docks, undocks: dock and undock events counted from the simulator's constraints.
    """

    edge: str
    action: str
    feasible: bool
    reason: str = ""
    sim_time: float = 0.0
    shape_error_deg: float | None = None
    docks: int = 0
    undocks: int = 0


class CheckFile(StrictModel):
    """``<LIB>.check.json``: a library's feasibility check."""

    schema_version: int = Field(1, ge=1, le=1)
    library: str
    library_sha256: str
    robot: str
    driver: str
    seed: int
    options: dict[str, float | int | str | bool] = {}
    edges: list[EdgeCheck]

    @property
    def feasible_fraction(self) -> float:
        return sum(e.feasible for e in self.edges) / len(self.edges) if self.edges else 1.0


def check_path(library_path: str | Path) -> Path:
    """The sidecar of a library file: ``S6N3.json`` -> ``S6N3.check.json``."""
    path = Path(library_path)
    return path.with_name(f"{path.stem}.check.json")


def library_digest(library_path: str | Path) -> str:
    """SHA-256 of a library file's bytes."""
    return hashlib.sha256(Path(library_path).read_bytes()).hexdigest()


def save_check(check: CheckFile, path: str | Path) -> None:
    """Write ``check`` atomically (keys in a fixed order, two-space indent)."""
    atomic_write_text(path, check.model_dump_json(indent=2) + "\n")


def load_check(path: str | Path) -> CheckFile:
    """Read a check file; errors name the file and field."""
    return parse_model(CheckFile, read_json(path), str(path))


def apply_check(library: Library, check: CheckFile) -> int:
    """Copy the check's flags onto ``library``'s edges; how many edges were flagged.

    Raises:
        LibraryError: the check is of another library.
    """
    if check.library != library.name:
        raise LibraryError(f"check of library {check.library!r} applied to {library.name!r}")
    flags = {e.edge: e.feasible for e in check.edges}
    done = 0
    for sub in library.sublibraries.values():
        for edge in sub.edges:
            key = edge_key(sub.name, edge)
            if key in flags:
                edge.feasible = flags[key]
                done += 1
    return done


def apply_sidecar(library: Library, library_path: str | Path
                  ) -> Literal["applied", "stale", "none"]:
    """Copy the flags of the check file beside ``library_path`` onto ``library`` when it
    is a check of that very file (same SHA-256): ``"applied"``; ``"stale"`` when it
    checks another build (nothing copied); ``"none"`` when there is no check file."""
    sidecar = check_path(library_path)
    if not sidecar.exists():
        return "none"
    check = load_check(sidecar)
    if check.library_sha256 != library_digest(library_path):
        return "stale"
    apply_check(library, check)
    return "applied"
