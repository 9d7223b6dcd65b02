"""MMRP docking rules (paper section 3.1, Definition 1).

Only Top-Bottom and Left-Right face pairs connect (connect(uT,vL) and
connect(uR,vB) would self-lock the modules); each face carries one connection;
configurations are trees. A ``z`` vector, when given, must point along the
source face's normal, since docked modules share one heading.
"""

from __future__ import annotations

import numpy as np

from msrr.core import Configuration, DockingRules, Violation
from msrr.core.robot import port_reuse_violations, tree_violations

from .robot import FACES

LEGAL_PAIRS = frozenset({frozenset({"T", "B"}), frozenset({"L", "R"})})
NORMALS = {face.name: np.array(face.normal) for face in FACES}


class MmrpRules(DockingRules):
    """T-B and L-R only, one connection per face, trees only."""

    robot = "mmrp"

    def ports_compatible(self, source_kind: str, source_port: str | None,
                         target_kind: str, target_port: str | None) -> bool:
        return frozenset({source_port, target_port}) in LEGAL_PAIRS

    def check_topology(self, config: Configuration) -> list[Violation]:
        found = [Violation(f"module {v}", "MMRP has no virtual vertices")
                 for v in config.vertices() if config.is_virtual(v)]
        found += [Violation(f"connection {e.id}", "needs ports (source face, target face)")
                  for e in config.edges() if e.ports is None]
        found += port_reuse_violations(config)
        for e in config.edges():
            if e.z is not None and e.ports and e.ports[0] in NORMALS \
                    and not np.allclose(e.z, NORMALS[e.ports[0]], atol=1e-6):
                found.append(Violation(f"connection {e.id}", f"z must be the normal of face "
                                       f"{e.ports[0]} {NORMALS[e.ports[0]].tolist()}"))
        return found + tree_violations(config)
