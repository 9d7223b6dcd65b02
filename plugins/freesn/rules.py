"""FreeSN docking rules: strut ends dock on node surfaces, anywhere (freeform).

Every edge is a strut whose two ends are node modules or virtual vertices (free
connectors); connectors have no discrete docking ports on the node, so a
connection names no ports; every strut carries its connection vector ``z``.
"""

from __future__ import annotations

from msrr.core import Configuration, DockingRules, Violation
from msrr.core.robot import vector_violations


class FreeSNRules(DockingRules):
    """Strut ends on node surfaces; no discrete ports; ``z`` on every strut."""

    robot = "freesn"

    def ports_compatible(self, source_kind: str, source_port: str | None,
                         target_kind: str, target_port: str | None) -> bool:
        return source_port is None and target_port is None

    def check_topology(self, config: Configuration) -> list[Violation]:
        found = vector_violations(config, "z")
        for edge in config.edges():
            if config.is_virtual(edge.source) and config.is_virtual(edge.target) \
                    and len(config) > 2:
                found.append(Violation(f"connection {edge.id}", "a strut with both ends free "
                                       "must be a configuration of its own"))
        return found
