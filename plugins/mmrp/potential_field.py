"""Distributed dynamic mapping of free vertices by artificial forces (paper section 4.3).

Every free module hat-v_c moves under the resultant force of eq. 5,
F = F_a + F_r + F_obs:

* eq. 2, attraction K_a / d^2 toward every target position not yet taken, so the
  nearest one dominates;
* eq. 3, repulsion K_r / d from another free module closer than d_r;
* eq. 4, obstacle force from the mapped subconfigurations (and modules already
  parked): K_r / d away inside d_safe-, nothing inside the ring
  [d_safe-, d_safe+], K_r * d back toward them beyond d_safe+.

A module that comes within ``reach`` of a free target takes it: the target stops
attracting and the module stops (it becomes an obstacle). This yields the mapping
f: hat-V_c -> hat-V_g. A field can stall (a local minimum, two modules deadlocked);
the modules still free then are assigned by a minimum-total-distance assignment
(``scipy.optimize.linear_sum_assignment``) and the result says so.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

__all__ = ["FieldParameters", "FieldResult", "map_free_vertices", "resultant_forces"]


@dataclass(frozen=True)
class FieldParameters:
    """Gains and distances of eqs. 2-5, lengths in pitches (one pitch = docked distance).

    Attributes:
        k_a: attractive factor K_a (eq. 2).
        k_r: repulsive factor K_r (eqs. 3 and 4).
        d_r: repulsion range between free modules (eq. 3) [pitch].
        d_safe_minus: inner radius of the obstacle ring (eq. 4) [pitch].
        d_safe_plus: outer radius of the obstacle ring (eq. 4) [pitch].
        step: distance a module drives per simulation step [pitch].
        reach: distance at which a module takes a target [pitch].
        patience: steps without a newly taken target before the field counts as stalled.
        max_steps: hard limit of simulation steps.
        jitter: standard deviation of the seeded start perturbation [pitch].
    """

    k_a: float = 1.0
    k_r: float = 0.05
    d_r: float = 0.9
    d_safe_minus: float = 0.7
    d_safe_plus: float = 6.0
    step: float = 0.05
    reach: float = 0.06
    patience: int = 200
    max_steps: int = 20000
    jitter: float = 1e-3


@dataclass(frozen=True)
class FieldResult:
    """The free-vertex mapping and how it was found.

    Attributes:
        mapping: current free module -> goal free module.
        arrival: current free modules in the order they took their targets.
        fallback: modules assigned by the minimum-distance assignment after a stall.
        steps: simulation steps run.
        travelled: path length of every free module [m].
    """

    mapping: dict[str, str]
    arrival: tuple[str, ...]
    fallback: tuple[str, ...]
    steps: int
    travelled: dict[str, float]

    @property
    def stalled(self) -> bool:
        """Whether the field stalled and the fallback assignment was used."""
        return bool(self.fallback)


def resultant_forces(positions: np.ndarray, targets: np.ndarray, obstacles: np.ndarray,
                     params: FieldParameters) -> np.ndarray:
    """Resultant force F = F_a + F_r + F_obs (eq. 5) on every free module.

    Args:
        positions: free modules, shape (k, 2) [pitch].
        targets: free target positions, shape (t, 2) [pitch].
        obstacles: mapped modules, shape (o, 2) [pitch].
        params: gains and distances.

    Returns:
        Forces, shape (k, 2).
    """
    force = np.zeros_like(positions)
    if len(targets):                                       # eq. 2
        diff = targets[None, :, :] - positions[:, None, :]
        dist = np.maximum(np.linalg.norm(diff, axis=2), 1e-9)
        force += np.sum(diff / dist[..., None] * (params.k_a / dist**2)[..., None], axis=1)
    if len(positions) > 1:                                 # eq. 3
        diff = positions[:, None, :] - positions[None, :, :]
        dist = np.linalg.norm(diff, axis=2)
        near = (dist > 0) & (dist < params.d_r)
        safe = np.where(near, dist, 1.0)
        force += np.sum(np.where(near[..., None], diff / safe[..., None]
                                 * (params.k_r / safe)[..., None], 0.0), axis=1)
    if len(obstacles):                                     # eq. 4
        diff = obstacles[None, :, :] - positions[:, None, :]
        dist = np.linalg.norm(diff, axis=2)
        nearest = np.argmin(dist, axis=1)
        rows = np.arange(len(positions))
        d = dist[rows, nearest]
        toward = diff[rows, nearest] / np.maximum(d, 1e-9)[:, None]
        magnitude = np.where(d < params.d_safe_minus, -params.k_r / np.maximum(d, 1e-9),
                             np.where(d > params.d_safe_plus, params.k_r * d, 0.0))
        force += toward * np.where(d > 0, magnitude, 0.0)[:, None]
    return force


def map_free_vertices(free: Mapping[str, tuple[float, float]],
                      targets: Mapping[str, tuple[float, float]],
                      obstacles: list[tuple[float, float]], *, unit: float = 1.0,
                      params: FieldParameters | None = None, seed: int = 0) -> FieldResult:
    """Simulate the free modules in the field until each takes a target (section 4.3).

    Args:
        free: start position of every current free module [m].
        targets: position of every goal free module in the same frame [m].
        obstacles: positions of modules of mapped subconfigurations [m].
        unit: the pitch [m]; the field works in pitches.
        params: gains and distances, defaults from :class:`FieldParameters`.
        seed: seed of the start perturbation that breaks exact symmetries.

    Returns:
        The mapping, in which any stalled modules are assigned by minimum total distance.
    """
    params = params or FieldParameters()
    if len(free) != len(targets):
        raise ValueError(f"{len(free)} free modules for {len(targets)} targets")
    names = list(free)
    goal_names = list(targets)
    rng = np.random.default_rng(seed)
    pos = np.array([free[m] for m in names], dtype=float).reshape(-1, 2) / unit
    pos += rng.normal(scale=params.jitter, size=pos.shape)
    goal = np.array([targets[g] for g in goal_names], dtype=float).reshape(-1, 2) / unit
    fixed = [np.asarray(o, dtype=float) / unit for o in obstacles]
    moving = list(range(len(names)))
    open_targets = list(range(len(goal_names)))
    travelled = np.zeros(len(names))
    mapping: dict[str, str] = {}
    arrival: list[str] = []
    steps = idle = 0
    while moving and steps < params.max_steps and idle < params.patience:
        steps += 1
        idle += 1
        obstacle_array = np.array(fixed).reshape(-1, 2)
        force = resultant_forces(pos[moving], goal[open_targets], obstacle_array, params)
        norm = np.linalg.norm(force, axis=1)
        move = np.where(norm[:, None] > 1e-12, force / np.maximum(norm, 1e-12)[:, None], 0.0)
        pos[moving] += params.step * move
        travelled[moving] += params.step * (norm > 1e-12)
        dist = np.linalg.norm(pos[moving][:, None, :] - goal[open_targets][None, :, :], axis=2)
        for row, col in sorted(zip(*np.nonzero(dist < params.reach), strict=True), key=lambda rc: dist[rc]):
            m, t = moving[row], open_targets[col]
            if names[m] in mapping or goal_names[t] in mapping.values():
                continue
            mapping[names[m]] = goal_names[t]
            arrival.append(names[m])
            pos[m] = goal[t]
            fixed.append(goal[t].copy())
            idle = 0
        moving = [m for m in moving if names[m] not in mapping]
        taken = set(mapping.values())
        open_targets = [t for t in open_targets if goal_names[t] not in taken]
    fallback: list[str] = []
    if moving:
        cost = np.linalg.norm(pos[moving][:, None, :] - goal[open_targets][None, :, :], axis=2)
        rows, cols = linear_sum_assignment(cost)
        for row, col in zip(rows, cols, strict=True):
            mapping[names[moving[row]]] = goal_names[open_targets[col]]
            fallback.append(names[moving[row]])
    return FieldResult(mapping, tuple(arrival), tuple(fallback), steps,
                       {m: float(travelled[i] * unit) for i, m in enumerate(names)})


def assign_free_vertices(free: Mapping[str, tuple[float, float]],
                         targets: Mapping[str, tuple[float, float]]) -> FieldResult:
    """The field's intent without simulating it: minimum total distance, nearest first.

    For many free modules the field of eqs. 2-5 crowds the ring around the mapped
    subconfigurations and stalls. This replaces the simulation by what it aims at:
    every free module takes a near free target and no two paths cross -- a
    minimum-total-Euclidean-distance assignment has no two crossing segments (if two
    crossed, swapping their targets would shorten the total, by the triangle
    inequality). Collisions on the way, which the repulsion of eq. 3 avoids, are
    avoided by routing the moves on the grid (:mod:`.routing`). Arrival order is by
    assigned distance, as the nearest module reaches its target first in the field.

    Args:
        free: start position of every current free module [m].
        targets: position of every goal free module in the same frame [m].

    Returns:
        The mapping; ``fallback`` is empty and ``steps`` 0 (nothing was simulated).
    """
    if len(free) != len(targets):
        raise ValueError(f"{len(free)} free modules for {len(targets)} targets")
    names, goal_names = list(free), list(targets)
    if not names:
        return FieldResult({}, (), (), 0, {})
    pos = np.array([free[m] for m in names], dtype=float).reshape(-1, 2)
    goal = np.array([targets[g] for g in goal_names], dtype=float).reshape(-1, 2)
    cost = np.linalg.norm(pos[:, None, :] - goal[None, :, :], axis=2)
    rows, cols = linear_sum_assignment(cost)
    order = np.argsort(cost[rows, cols], kind="stable")
    mapping = {names[rows[k]]: goal_names[cols[k]] for k in order}
    return FieldResult(mapping, tuple(mapping), (), 0,
                       {names[r]: float(cost[r, c]) for r, c in zip(rows, cols, strict=True)})
