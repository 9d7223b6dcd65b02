"""Helpers of the library tests: source paths and relabelled, perturbed systems."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from msrr.core import Configuration

ROOT = Path(__file__).resolve().parents[3]
SOURCES = ROOT / "plugins" / "freesn" / "library_sources"
LIBRARIES = ROOT / "plugins" / "freesn" / "libraries"


def source_files(name: str) -> list[Path]:
    return sorted((SOURCES / name).glob("*.json"))


def relabelled(config: Configuration, prefix: str, *, noise: float, seed: int
               ) -> Configuration:
    """``config`` with every id renamed and every ``z`` perturbed by ``noise`` (std, unitless)."""
    rng = np.random.default_rng(seed)
    vertices = {v: f"{prefix}{i}" for i, v in enumerate(reversed(config.vertices()))}
    edges = {e: f"{prefix}e{i}" for i, e in enumerate(reversed(config.edge_ids()))}
    out = config.relabel(vertices, edges)
    z = {}
    for edge in out.edges():
        v = edge.z + rng.normal(scale=noise, size=3)
        z[edge.id] = v / np.linalg.norm(v)
    out = out.with_vectors(z=z, x={})
    out.name = f"{prefix}-system"
    return out
