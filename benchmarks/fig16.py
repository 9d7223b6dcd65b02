"""The ten topologies of the isomorphism-search benchmark (FreeSN paper, section 7.1, Fig. 16).

Five node modules and sixteen struts each; free struts end on virtual vertices.
Parallel struts between the same two nodes, and free struts on the same node, permute
freely, so the number of isomorphisms of a topology onto itself is the product of the
factorials of those multiplicities times its node symmetries: from dozens to tens of
thousands, one with exactly 57 600 = 5! (A-B struts) * 5! (free struts on C) * 2! * 2!.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from msrr.core.configuration import Configuration
from msrr.core.random_configurations import random_unit

__all__ = ["FIG16_TOPOLOGIES", "TopologySpec"]

NODES = "ABCDE"


@dataclass(frozen=True)
class TopologySpec:
    """A benchmark topology.

    Attributes:
        name: short name.
        struts: ``{"AB": 3, ...}``: number of struts between two nodes.
        free: ``{"C": 5, ...}``: number of free struts on a node.
        isomorphisms: number of isomorphisms onto itself (checked by the tests).
    """

    name: str
    struts: dict[str, int]
    free: dict[str, int]
    isomorphisms: int

    def configuration(self, rng: np.random.Generator, *, robot: str = "freesn") -> Configuration:
        """The topology with uniformly random strut vectors (the whole joint space)."""
        config = Configuration(robot, name=self.name)
        for node in NODES:
            config.add_module(node, "node")
        count = 0
        for pair, multiplicity in self.struts.items():
            for _ in range(multiplicity):
                count += 1
                config.connect(pair[0], pair[1], id=f"S{count}", kind="strut",
                               z=random_unit(rng))
        for node, multiplicity in self.free.items():
            for _ in range(multiplicity):
                count += 1
                config.add_virtual(f"v{count}")
                config.connect(node, f"v{count}", id=f"S{count}", kind="strut",
                               z=random_unit(rng))
        return config


FIG16_TOPOLOGIES: tuple[TopologySpec, ...] = (
    TopologySpec("T48", {"AB": 3, "BC": 2, "CD": 2, "DE": 1, "AC": 1, "BD": 1, "AE": 1,
                         "CE": 1}, {"A": 1, "C": 2, "E": 1}, 48),
    TopologySpec("T96", {"AB": 2, "BC": 2, "CD": 1, "DE": 1, "AC": 1, "BD": 1, "CE": 1,
                         "AE": 1}, {"A": 4, "D": 1, "E": 1}, 96),
    TopologySpec("T384", {"AB": 2, "BC": 2, "CD": 2, "DE": 2, "EA": 2},
                 {"A": 2, "C": 1, "D": 3}, 384),
    TopologySpec("T864", {"AB": 3, "BC": 3, "CD": 1, "DE": 1}, {"A": 2, "B": 1, "D": 3, "E": 2},
                 864),
    TopologySpec("T2304", {"AB": 3, "AC": 3, "AD": 1, "AE": 1}, {"B": 2, "C": 2, "D": 2, "E": 2},
                 2304),
    TopologySpec("T3456", {"AB": 4, "BC": 2, "CD": 2, "DE": 1, "AE": 1}, {"C": 3, "E": 3}, 3456),
    TopologySpec("T4608", {"AB": 4, "BC": 4, "CD": 1, "DE": 1}, {"A": 2, "D": 2, "E": 2}, 4608),
    TopologySpec("T10368", {"AB": 4, "BC": 3, "CD": 3, "DE": 1}, {"E": 3, "B": 2}, 10368),
    TopologySpec("T20736", {"AB": 4, "CD": 4, "BC": 1, "DE": 1}, {"A": 3, "E": 3}, 20736),
    TopologySpec("T57600", {"AB": 5, "CD": 2, "DE": 2, "BC": 1, "AE": 1}, {"C": 5}, 57600),
)
