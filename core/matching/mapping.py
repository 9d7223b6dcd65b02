"""The result of matching two configurations: a module map with its distance and yaw.

A :class:`Mapping` is the :class:`~msrr.core.mapping.ModuleMap` from the *system*
configuration onto the *reference* configuration that the isomorphism search found,
together with the eq. 8 distance of the two configurations under it and the yaw that
aligns them (FreeSN paper, Alg. 2 output ``{eps, f_node, f_edge, inv}``). Renaming,
inversion, composition and the treatment of reversed edges are the module map's
(:mod:`msrr.core.mapping`); this type only adds the score.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..alignment import rot_z
from ..configuration import Configuration
from ..mapping import EdgeImage, ModuleMap

__all__ = ["EdgeImage", "Mapping"]


@dataclass(frozen=True)
class Mapping(ModuleMap):
    """An isomorphism from a system configuration onto a reference configuration.

    Attributes:
        nodes: system vertex -> reference vertex (virtual vertices included).
        edges: system edge -> ``(reference edge, inv)``; ``inv`` is true when the two
            edges point in opposite directions (Alg. 3 line 8).
        distance: eq. 8 cost at the aligned yaw: sum over edges with ``z`` on both sides
            of the squared angle [rad^2] between the system ``z`` and the rotated
            reference ``z`` (negated when ``inv``).
        yaw: ``theta`` [rad] such that ``rot_z(theta) @ z_ref`` matches ``z_sys``.
        rms_angle: root-mean-square of those angles [rad].
    """

    distance: float = 0.0
    yaw: float = 0.0
    rms_angle: float = 0.0

    def reference_in_system_ids(self, reference: Configuration, *, rotate: bool = True
                                ) -> Configuration:
        """``reference`` renamed into system ids, each edge turned to the system's direction.

        Args:
            reference: the reference configuration this mapping points into.
            rotate: also rotate ``z``/``x`` by :attr:`yaw` into the system's horizontal frame.
        """
        return self.inverse().apply(reference, rotation=rot_z(self.yaw) if rotate else None)[0]

    def system_in_reference_ids(self, system: Configuration, *, rotate: bool = False
                                ) -> Configuration:
        """``system`` renamed into reference ids, each edge turned to the reference's direction.

        Args:
            system: the system configuration this mapping starts from.
            rotate: also rotate ``z``/``x`` by ``-yaw`` into the reference's frame (off by
                default: the inverse kinematics estimates the yaw itself).
        """
        return self.apply(system, rotation=rot_z(-self.yaw) if rotate else None)[0]
