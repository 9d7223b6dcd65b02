"""Where a configuration of single-connector modules lies, without a simulator: the
pieces' centres from their connection vectors, and the world's layout of a start file
(:func:`place`), which the MuJoCo world builds from and the MISO planner pairs pieces by.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping, Sequence

import numpy as np
from scipy.spatial import cKDTree

from ..configuration import Configuration
from ..errors import ExecutionError
from ..kinematics.rotations import rotation_between

__all__ = ["DOCK_GAP", "SLIDE_OVERLAP", "WAY_IN", "lay_out_pieces", "place"]

DOCK_GAP = 0.001
"""Shell-to-shell gap of a docked pair [m] (the world's default ``gap``)."""

WAY_IN = 0.15
"""A docking piece's last stretch, straight in along its line, at the least [m]."""

SLIDE_OVERLAP = 0.01
"""How much closer than the spacing a piece sliding in may pass another's shell [m]."""

_EZ = np.array([0.0, 0.0, 1.0])


def lay_out_pieces(adjacent: Mapping[str, Sequence[tuple[str, np.ndarray]]],
                   order: Sequence[str], spacing: float) -> list[dict[str, np.ndarray]]:
    """The connected pieces of modules joined by unit vectors (``adjacent[u]`` holds
    ``(v, z)``: ``v``'s centre is ``spacing * z`` [m] from ``u``'s), each as centres (3,)
    [m] relative to its first module in ``order``, reached breadth first."""
    placed: set[str] = set()
    pieces: list[dict[str, np.ndarray]] = []
    for start in order:
        if start in placed:
            continue
        piece, queue = {start: np.zeros(3)}, deque([start])
        while queue:
            u = queue.popleft()
            for v, z in adjacent[u]:
                if v not in piece:
                    piece[v] = piece[u] + spacing * z
                    queue.append(v)
        placed.update(piece)
        pieces.append(piece)
    return pieces


def place(config: Configuration, length: float, radius: float
          ) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Centres (3,) and connector frames (3, 3) of ``config``'s modules in the world.

    Breadth-first from each group's smallest id, a connection ``i -> j`` puts ``j`` at
    ``p_i + length z``; each group is lifted so its lowest shell rests on the ground. A
    group with a module whose ``position`` the file gives is laid where the lab put it:
    shifted so that that module (its smallest id) is at its ``x, y``, the other given
    positions agreeing with the vectors within 1 mm; the others are set side by side
    along ``y``, ``4 radius`` apart. A connector's axis points along its connection's
    ``z``; a module without one points its connector down.

    Raises:
        ExecutionError: a connection without ``z``, a given position that disagrees with
            its piece's vectors, or two shells overlapping.
    """
    modules = [v for v in config.vertices() if not config.is_virtual(v)]
    adjacent: dict[str, list[tuple[str, np.ndarray]]] = {m: [] for m in modules}
    axis: dict[str, np.ndarray] = {}
    for e in config.edges():
        if e.z is None:
            raise ExecutionError(f"connection {e.id} has no vector z; the world cannot place it")
        z = np.asarray(e.z, dtype=np.float64)
        adjacent[e.source].append((e.target, z))
        adjacent[e.target].append((e.source, -z))
        axis[e.source] = z
    centres: dict[str, np.ndarray] = {}
    offset = 0.0
    for group in lay_out_pieces(adjacent, sorted(modules), length):
        points = np.array(list(group.values()))
        given = {m: config.position(m) for m in sorted(group)
                 if config.position(m) is not None}
        if given:
            first = next(iter(given))
            shift = np.append(given[first][:2] - group[first][:2], radius - points[:, 2].min())
            for m, at in given.items():
                off = float(np.linalg.norm(group[m][:2] + shift[:2] - at[:2]))
                if off > 1e-3:
                    raise ExecutionError(f"configuration {config.name!r}: module {m}: its "
                                         f"position is {off:.3f} m from where its piece's "
                                         f"vectors put it (from {first})")
        else:
            shift = np.array([0.0, offset - points[:, 1].min(), radius - points[:, 2].min()])
            offset += points[:, 1].max() - points[:, 1].min() + 4 * radius
        for m, p in group.items():
            centres[m] = p + shift
    names = sorted(centres)
    close = cKDTree(np.array([centres[m] for m in names])).query_pairs(2 * radius - 1e-3)
    if close:
        a, b = min(close)
        raise ExecutionError(f"modules {names[a]} and {names[b]} overlap in this configuration")
    frames = {m: _frame_along(axis.get(m, -_EZ)) for m in modules}
    return centres, frames


def _frame_along(z: np.ndarray) -> np.ndarray:
    """A rotation (3, 3) whose ``z`` column is ``z``: the minimal turn from the vertical."""
    return rotation_between(_EZ, z / np.linalg.norm(z))
