"""Random legal MMRP trees that fit the plane (seeded), for tests and benchmarks.

Unlike the robot-agnostic :func:`msrr.core.random_configurations.random_configuration`,
these trees are grown on the grid of docked positions, so no two modules claim the
same cell and every tree can be built by real modules.
"""

from __future__ import annotations

import numpy as np

from msrr.core import Configuration

from .representation import GRID_STEP, from_links

__all__ = ["MATE", "random_tree"]

MATE = {"T": "B", "B": "T", "L": "R", "R": "L"}
"""The face that docks with each face (T-B and L-R only, section 3.1)."""


def random_tree(n: int, rng: np.random.Generator, *, name: str = "") -> Configuration:
    """A random MMRP tree of ``n`` modules with ids ``"1"``..``"n"`` in random order.

    Each new module docks one free face of a random module whose neighbouring grid
    cell is empty, through the mating face.
    """
    labels = [str(i) for i in rng.permutation(n) + 1]
    cells = {labels[0]: (0, 0)}
    occupied = {(0, 0)}
    used = {labels[0]: set()}
    links = []
    for child in labels[1:]:
        options = []
        for module, (x, y) in cells.items():
            for face, (dx, dy) in GRID_STEP.items():
                if face not in used[module] and (x + dx, y + dy) not in occupied:
                    options.append((module, face, (x + dx, y + dy)))
        parent, face, cell = options[int(rng.integers(len(options)))]
        cells[child] = cell
        occupied.add(cell)
        used[parent].add(face)
        used[child] = {MATE[face]}
        links.append((parent, face, child, MATE[face]))
    return from_links(sorted(labels, key=int), links, name=name)
