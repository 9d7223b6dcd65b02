"""Shared helpers of the kinematics tests: random FreeSN configurations, differences."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from msrr.core import Configuration, plugins
from msrr.core.alignment import rot_z
from msrr.core.kinematics import KinematicTree, default_tree
from msrr.core.random_configurations import random_configuration

FREESN = plugins.resolve("freesn")


def freesn_tree(config: Configuration, mode: str | None = None, **kwargs) -> KinematicTree:
    """The default tree of a FreeSN configuration with joint mode ``mode`` (default mode if None)."""
    cls = FREESN.default_joint_mode() if mode is None else FREESN.joint_modes[mode]
    return default_tree(config, cls, **kwargs)


def random_freesn(n_edges: int, seed: int, *, free: int = 0, with_x: bool = True
                  ) -> Configuration:
    """A random tree-shaped FreeSN configuration with ``n_edges`` struts."""
    rng = np.random.default_rng(seed)
    spec, rules = plugins.robot("freesn"), plugins.docking_rules("freesn")
    config = random_configuration(spec, rules, n_edges + 1 - free, rng, free_connectors=free)
    return config if with_x else config.with_vectors(x={})


def yawed(config: Configuration, yaw: float) -> Configuration:
    """``config`` as seen from a horizontal frame turned by ``-yaw``: vectors turned by ``yaw``."""
    r = rot_z(yaw)
    return config.with_vectors(z={e.id: r @ e.z for e in config.edges()},
                               x={e.id: r @ e.x for e in config.edges() if e.x is not None})


def central_difference(f: Callable[[np.ndarray], np.ndarray], x: np.ndarray,
                       h: float = 1e-6) -> np.ndarray:
    """Central differences of array-valued ``f`` at ``x``; the last axis is the parameter."""
    columns = []
    for i in range(len(x)):
        e = np.zeros_like(x)
        e[i] = h
        columns.append((np.asarray(f(x + e)) - np.asarray(f(x - e))) / (2 * h))
    return np.stack(columns, axis=-1)


def relative_error(analytic: np.ndarray, numeric: np.ndarray) -> float:
    scale = max(float(np.linalg.norm(numeric)), float(np.linalg.norm(analytic)), 1e-12)
    return float(np.linalg.norm(np.asarray(analytic) - numeric)) / scale


def random_units(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` random unit vectors as columns, shape (3, n)."""
    v = rng.normal(size=(3, n))
    return v / np.linalg.norm(v, axis=0)
