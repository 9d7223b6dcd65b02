"""FreeSN configuration identification from module reports (paper sections 2.1, 4.2).

The recognizer reads only what modules report (:class:`~.world.NodeReport`,
:class:`~.world.StrutReport`), never a simulator's state:

1. topology: a strut end is docked on a node when the strut reports it and the node
   localises that connector;
2. connection vectors in each node's horizontal frame ``H_i``: the node's magnetic
   localisation (node frame) turned by its IMU tilt, ``d = tilt_i loc``;
3. yaw between horizontal frames: a strut docked on nodes ``i`` and ``j`` reports its
   attitude in both, ``A_i`` and ``A_j``, so ``R_{H_i H_j} = A_i A_j^T`` (ideally a
   rotation about the vertical by ``psi_j - psi_i``); the headings of all nodes in the
   root's frame are the least-squares solution over every such strut (one
   Gauss-Newton step from a breadth-first estimate, so loops average their
   measurements rather than keep one path's);
4. ``z = Rz(psi_i) d`` from each docked end (averaged when both are), ``x`` from the
   attitude; free ends become virtual vertices ``"<strut>:<end>"``.

The root of each connected group is its best-connected node, the smallest id among
equals (:func:`root_order`), or the one given: a leaf node may be a wheel or a foot, and
its frame turns as it rolls, which would turn the whole recognized configuration and the
commands given in it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from msrr.core.alignment import rot_z, wrap_angle
from msrr.core.configuration import Configuration
from msrr.core.errors import ConfigurationError
from msrr.core.freeform.mujoco import yaw_of
from msrr.core.freeform.recognition import spread_headings

from .commands import ENDS
from .geometry import END_SIGN
from .world import NodeReport, StrutReport

if TYPE_CHECKING:
    from .filtering import ReportFilter
    from .odometry import ImuOdometry

__all__ = ["FreeSNRecognizer", "Links", "links_of", "node_headings", "root_order"]

Reports = Mapping[str, "NodeReport | StrutReport"]
Links = dict[tuple[str, str], str]
"""``(strut, end)`` -> node for every docked connector."""


def links_of(reports: Reports) -> Links:
    """The docked connectors, where the strut and the node agree."""
    links: Links = {}
    for strut, report in reports.items():
        if not isinstance(report, StrutReport):
            continue
        for end in ENDS:
            node = report.docked.get(end)
            if node is None:
                continue
            seen = reports.get(node)
            if isinstance(seen, NodeReport) and f"{strut}:{end}" in seen.connectors \
                    and end in report.attitude:
                links[(strut, end)] = node
    return links


def root_order(nodes: list[str] | set[str], links: Links) -> list[str]:
    """``nodes`` in the order groups take their root from: most docked connectors
    first, then by id. The frames of a group's root anchor the recognized configuration
    (:func:`node_headings`) and the driving connectors' spanning tree
    (:func:`~.controller.driving_ends`) alike: a node spinning as a wheel (Fig. 18(a))
    or rolling as a foot (Fig. 19) is a leaf and never the root of a group that has more.
    """
    degree = dict.fromkeys(nodes, 0)
    for node in links.values():
        if node in degree:
            degree[node] += 1
    return sorted(degree, key=lambda n: (-degree[n], n))


def node_headings(reports: Reports, links: Links | None = None,
                  root: str | None = None) -> dict[str, float]:
    """Heading [rad] of every node's horizontal frame in its group's root frame.

    Args:
        reports: module reports by id.
        links: docked connectors (computed when omitted).
        root: the root node of its group (default: :func:`root_order`'s first).
    """
    links = links_of(reports) if links is None else links
    nodes = sorted(m for m, r in reports.items() if isinstance(r, NodeReport))
    measured: list[tuple[str, str, float]] = []   # (i, j, psi_j - psi_i)
    for strut, report in reports.items():
        if not isinstance(report, StrutReport):
            continue
        a, b = links.get((strut, "a")), links.get((strut, "b"))
        if a is not None and b is not None and a != b:
            rel = report.attitude["a"] @ report.attitude["b"].T
            measured.append((a, b, yaw_of(rel)))
    neighbours: dict[str, list[tuple[str, float]]] = {n: [] for n in nodes}
    for i, j, delta in measured:
        neighbours[i].append((j, delta))
        neighbours[j].append((i, -delta))
    heading, roots = spread_headings(neighbours, ([root] if root is not None else [])
                                     + root_order(nodes, links))
    free = [n for n in nodes if n not in roots]
    if measured and free:
        column = {n: c for c, n in enumerate(free)}
        jac = np.zeros((len(measured), len(free)))
        res = np.empty(len(measured))
        for row, (i, j, delta) in enumerate(measured):
            res[row] = wrap_angle(heading[j] - heading[i] - delta)
            if j in column:
                jac[row, column[j]] += 1.0
            if i in column:
                jac[row, column[i]] -= 1.0
        step = np.linalg.lstsq(jac, -res, rcond=None)[0]
        for n, c in column.items():
            heading[n] = float(wrap_angle(heading[n] + step[c]))
    return heading


def _length(v: np.ndarray) -> float:
    """``np.linalg.norm(v)`` of a vector by its own arithmetic (the square root of
    ``v.dot(v)`` of the raveled vector), without its Python layers: ~40 a tick here."""
    v = v.ravel(order="K")
    return math.sqrt(v.dot(v))


class FreeSNRecognizer:
    """Configuration identification of FreeSN (registered as ``freesn``).

    ``recognize`` takes the driver's ``observation.sensors``: module id ->
    :class:`~.world.NodeReport` or :class:`~.world.StrutReport`.
    """

    name = "freesn"
    description = ("magnetic localisation + IMU + odometry reports -> configuration in the "
                   "root node's horizontal frame; gyros + rolling contacts -> heading, place")

    def __init__(self, root: str | None = None):
        self.root = root

    def estimator(self) -> ImuOdometry:
        """A fresh estimate of the system's heading and place for one run: the nodes'
        gyros and rolling-contact odometry (:mod:`.odometry`)."""
        from .odometry import ImuOdometry  # it reads this module's links and headings

        return ImuOdometry(self.root)

    def report_filter(self) -> ReportFilter:
        """A fresh filter of one run's reports: node gyros and connector encoders
        predict, the noisy readings correct (:mod:`.filtering`)."""
        from .filtering import ReportFilter  # it reads this module's links and headings

        return ReportFilter(self.root)

    def recognize(self, observation: Reports, *, seed: int = 0) -> Configuration:
        """The configuration the reports show, in the modules' own ids.

        Raises:
            ConfigurationError: a report of an unknown type.
        """
        for module, report in observation.items():
            if not isinstance(report, NodeReport | StrutReport):
                raise ConfigurationError(f"module {module!r}: not a FreeSN report "
                                         f"({type(report).__name__})")
        links = links_of(observation)
        heading = node_headings(observation, links, self.root)
        config = Configuration("freesn")
        for module, report in observation.items():
            if isinstance(report, NodeReport):
                config.add_module(module, "node")
        for strut, report in observation.items():
            if not isinstance(report, StrutReport):
                continue
            ends, zs, x = [], [], None
            for end in ENDS:
                node = links.get((strut, end))
                if node is None:
                    ends.append(f"{strut}:{end}")
                    config.add_virtual(ends[-1])
                    continue
                ends.append(node)
                frame = rot_z(heading[node])
                loc = observation[node].connectors[f"{strut}:{end}"]
                direction = observation[node].tilt @ loc
                zs.append(END_SIGN[end] * frame @ (direction / _length(direction)))
                if x is None:
                    x = frame @ report.attitude[end][:, 0]
            if zs:
                # np.sum(zs, axis=0) to the bit: its sum starts at +0
                z = (zs[0] + zs[1] if len(zs) == 2 else zs[0]) + 0.0
                z = z / _length(z)
            else:  # a strut on its own: its IMU, in its own horizontal frame
                z, x = report.tilt[:, 2], report.tilt[:, 0]
            x = x - (x @ z) * z
            x = x / _length(x)
            config.connect(ends[0], ends[1], id=strut, kind="strut", z=z, x=x)
        return config
