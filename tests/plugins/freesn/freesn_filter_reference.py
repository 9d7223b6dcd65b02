"""The FreeSN report filter as stop 42 wrote it, one node and one connector at a time:
kept only as the reference the batched :mod:`msrr.plugins.freesn.sim.filtering` is
compared against (issue 32: the same estimates on recorded noisy runs). Not imported
by the platform.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from msrr.core.alignment import rot_z, wrap_angle
from msrr.core.driver import Observation
from msrr.core.errors import ExecutionError
from msrr.core.freeform.mujoco import yaw_of
from msrr.core.kinematics.rotations import rodrigues, skew
from msrr.plugins.freesn.sim.commands import ENDS
from msrr.plugins.freesn.sim.geometry import END_SIGN
from msrr.plugins.freesn.sim.odometry import UPRIGHT
from msrr.plugins.freesn.sim.recognizer import Links, links_of, node_headings, root_order
from msrr.plugins.freesn.sim.world import Accuracy, NodeReport, StrutReport

__all__ = ["NodeState", "ReportFilter", "attitude_predict", "attitude_update",
           "direction_predict", "direction_update"]

Reports = Mapping[str, "NodeReport | StrutReport"]

_UP = np.array([0.0, 0.0, 1.0])


def _exp(rotvec: np.ndarray) -> np.ndarray:
    """The rotation (3, 3) of a rotation vector (3,) [rad]; to first order near zero."""
    angle = float(np.linalg.norm(rotvec))
    if angle < 1e-12:
        return np.eye(3) + skew(rotvec)
    return rodrigues(rotvec / angle, angle)


def _angle(u: np.ndarray, v: np.ndarray) -> float:
    return math.atan2(float(np.linalg.norm(np.cross(u, v))), float(u @ v))


# -- a direction on the sphere ------------------------------------------------------------

def direction_predict(u: np.ndarray, var: float, rolled: np.ndarray, q: float
                      ) -> tuple[np.ndarray, float]:
    """Move unit vector ``u`` (3,) by the rotation ``rolled`` (3, 3) the encoders counted;
    its variance per axis ``var`` [rad^2] grows by the rolling's ``q`` [rad^2]."""
    return rolled @ u, var + q


def direction_update(u: np.ndarray, var: float, fix: np.ndarray, r: float
                     ) -> tuple[np.ndarray, float]:
    """Kalman update of unit vector ``u`` (3,) (variance ``var`` [rad^2] per tangent axis)
    by a reading ``fix`` (3,) of variance ``r``: ``u`` turns toward ``fix`` along their
    great circle by ``k = var / (var + r)`` of their angle, ``var <- (1 - k) var``. From
    ``var = r`` and no motion, the ``n``-th reading gets ``k = 1/n``: the running mean,
    ``var = r / n``."""
    fix = fix / np.linalg.norm(fix)
    k = var / (var + r) if var + r > 0.0 else 1.0
    axis = np.cross(u, fix)
    size = float(np.linalg.norm(axis))
    if size > 1e-12:
        u = _exp(axis / size * (k * _angle(u, fix))) @ u
    return u / np.linalg.norm(u), (1.0 - k) * var


# -- a node's attitude and gyro bias ------------------------------------------------------

@dataclass
class NodeState:
    """One node's filtered attitude.

    Attributes:
        rotation: node -> gyro frame ``W`` (3, 3). bias: gyro bias estimate (3,) [rad/s].
        cov: covariance (6, 6) of the error state ``(dtheta, db)``: ``dtheta`` the attitude
            error in ``W`` [rad] (``R_true = exp([dtheta]) R``), ``db`` the bias error.
    """

    rotation: np.ndarray
    bias: np.ndarray = field(default_factory=lambda: np.zeros(3))
    cov: np.ndarray = field(default_factory=lambda: np.zeros((6, 6)))


def attitude_predict(state: NodeState, gyro: np.ndarray, dt: float, acc: Accuracy
                     ) -> NodeState:
    """Propagate by the gyro's mean body rate ``gyro`` (3,) [rad/s] over ``dt`` [s]:
    ``R <- R exp([(w - b) dt])``; ``P <- F P F^T + Q`` with ``F = [[I, -R dt], [0, I]]``
    and ``Q = diag(gyro_noise^2 dt I, gyro_walk^2 dt I)``."""
    f = np.eye(6)
    f[:3, 3:] = -state.rotation * dt
    q = np.diag([acc.gyro_noise**2 * dt] * 3 + [acc.gyro_walk**2 * dt] * 3)
    return NodeState(state.rotation @ _exp((gyro - state.bias) * dt), state.bias.copy(),
                     f @ state.cov @ f.T + q)


def attitude_update(state: NodeState, residual: np.ndarray, rows: np.ndarray,
                    r: np.ndarray) -> NodeState:
    """Kalman update by measurements ``residual`` (m,) = ``rows`` (m, 6) times the error
    state plus noise of covariance ``r`` (m, m): ``K = P H^T (H P H^T + r)^-1``, the error
    ``K y`` applied (``R <- exp([dtheta]) R``, ``b <- b + db``), ``P <- (I - K H) P``."""
    s = rows @ state.cov @ rows.T + r
    gain = np.linalg.solve(s, rows @ state.cov).T
    step = gain @ residual
    cov = (np.eye(6) - gain @ rows) @ state.cov
    return NodeState(_exp(step[:3]) @ state.rotation, state.bias + step[3:],
                     0.5 * (cov + cov.T))


def tilt_residual(rotation: np.ndarray, tilt: np.ndarray) -> np.ndarray:
    """The attitude error about ``W``'s x and y (2,) [rad] that the reported tilt (3, 3)
    shows: its vertical in the node frame (row 2), turned into ``W`` by ``rotation``, is
    ``e_z + e_z x dtheta`` to first order."""
    up = rotation @ tilt[2]
    return np.array([up[1], -up[0]])


_TILT_ROWS = np.eye(6)[:2]
_HEADING_ROWS = np.eye(6)[2:3]


# -- the filter of one run -----------------------------------------------------------------

def _group_roots(nodes: list[str], links: Links, root: str | None) -> dict[str, str]:
    """Each node's group root (:func:`.recognizer.root_order`, ``root`` first)."""
    nexts: dict[str, set[str]] = {n: set() for n in nodes}
    for (strut, end), node in links.items():
        other = links.get((strut, "b")) if end == "a" else None
        if other is not None and other != node:
            nexts[node].add(other)
            nexts[other].add(node)
    of: dict[str, str] = {}
    for start in ([root] if root in nexts else []) + root_order(nodes, links):
        if start in of:
            continue
        of[start] = start
        queue = deque([start])
        while queue:
            for v in nexts[queue.popleft()]:
                if v not in of:
                    of[v] = start
                    queue.append(v)
    return of


@dataclass
class _Connector:
    node: str
    u: np.ndarray
    var: float
    rolled: np.ndarray | None


class ReportFilter:
    """The filter of one run's reports (see the module docstring).

    Args:
        root: the root node the recognizer was given (``None``: :func:`root_order`'s).
    """

    def __init__(self, root: str | None = None):
        self.root = root
        self._reset()

    def _reset(self) -> None:
        """Forget the run: no state, no time."""
        self.time: float | None = None
        self.nodes: dict[str, NodeState] = {}
        self.connectors: dict[tuple[str, str], _Connector] = {}
        self.last: Observation | None = None

    def update(self, observation: Observation) -> Observation:
        """``observation`` with its reports replaced by the filtered ones; the same
        observation time again returns the last answer (a tick may read twice)."""
        if self.last is not None and self.time is not None:
            if observation.time == self.time:
                return self.last
            if observation.time < self.time:   # a new run on the same driver
                self._reset()
        reports: Reports = observation.sensors
        stated = {r.accuracy for r in reports.values() if isinstance(r, NodeReport | StrutReport)}
        if len(stated) > 1:   # the gains below are one model's; never guess between two
            raise ExecutionError(f"the FreeSN report filter models one accuracy for every "
                                 f"module; the reports at t={observation.time:.2f} s state "
                                 f"{len(stated)} different ones")
        acc = stated.pop() if stated else Accuracy()
        dt = 0.0 if self.time is None else observation.time - self.time
        self.time = observation.time
        if acc.angle <= 0.0:
            self.last = observation
            return observation
        links = links_of(reports)
        self._nodes(reports, links, acc, dt)
        self._connectors(reports, links, acc, dt)
        self.last = replace(observation, sensors=self._reports(reports, links))
        return self.last

    def _nodes(self, reports: Reports, links: Links, acc: Accuracy, dt: float) -> None:
        """Predict every node by its gyro, correct by its tilt and relative heading."""
        nodes = sorted(m for m, r in reports.items() if isinstance(r, NodeReport))
        roots = _group_roots(nodes, links, self.root)
        relative = node_headings(reports, links, self.root)
        r_tilt = acc.angle**2 * np.eye(2)
        r_heading = 2.0 * acc.angle**2 * np.eye(1)   # two attitudes per relative yaw
        for node in sorted(nodes, key=lambda n: n != roots[n]):   # roots first
            report: NodeReport = reports[node]  # type: ignore[assignment]
            root = roots[node]
            state = self.nodes.get(node)
            if state is None:
                state = self._first(node, root, report, relative, acc)
            else:
                state = attitude_predict(state, np.asarray(report.gyro, float), dt, acc)
            state = attitude_update(state, tilt_residual(state.rotation, report.tilt),
                                    _TILT_ROWS, r_tilt)
            base = self.nodes.get(root) if node != root else None
            if base is not None and base.rotation[2, 2] >= UPRIGHT \
                    and state.rotation[2, 2] >= UPRIGHT:
                seen = float(wrap_angle(relative[node] + yaw_of(base.rotation) - yaw_of(state.rotation)))
                state = attitude_update(state, np.array([seen]), _HEADING_ROWS, r_heading)
            self.nodes[node] = state
        for gone in set(self.nodes) - set(nodes):
            del self.nodes[gone]

    def _first(self, node: str, root: str, report: NodeReport,
               relative: Mapping[str, float], acc: Accuracy) -> NodeState:
        """A node seen for the first time: its tilt, and its heading from the struts
        relative to its root (the root of a new group: heading 0)."""
        tilt = np.asarray(report.tilt, dtype=float)
        base = self.nodes.get(root) if node != root else None
        psi = 0.0 if base is None else yaw_of(base.rotation) + relative.get(node, 0.0)
        heading_var = 0.0 if base is None else 2.0 * acc.angle**2
        cov = np.diag([acc.angle**2, acc.angle**2, heading_var] + [acc.gyro_bias**2] * 3)
        return NodeState(rot_z(psi) @ rot_z(-yaw_of(tilt)) @ tilt, np.zeros(3), cov)

    def _connectors(self, reports: Reports, links: Links, acc: Accuracy, dt: float) -> None:
        """Predict every docked connector by its encoders, correct by its localisation."""
        r = acc.angle**2
        kept: dict[tuple[str, str], _Connector] = {}
        for (strut, end), node in links.items():
            fix = np.asarray(reports[node].connectors[f"{strut}:{end}"], dtype=float)  # type: ignore[union-attr]
            rolled = reports[strut].rolled.get(end)  # type: ignore[union-attr]
            old = self.connectors.get((strut, end))
            if old is None or old.node != node or old.rolled is None or rolled is None:
                c = _Connector(node, fix / np.linalg.norm(fix), r, rolled)
            else:
                step = rolled @ old.rolled.T
                turned = math.acos(max(-1.0, min(1.0, 0.5 * (np.trace(step) - 1.0))))
                u, var = direction_predict(old.u, old.var, step,
                                           (acc.slip * turned)**2 + acc.drift**2 * dt)
                u, var = direction_update(u, var, fix, r)
                c = _Connector(node, u, var, rolled)
            kept[(strut, end)] = c
        self.connectors = kept

    def _reports(self, reports: Reports, links: Links) -> dict[str, NodeReport | StrutReport]:
        """The reports the filtered state gives (the module docstring)."""
        out: dict[str, NodeReport | StrutReport] = dict(reports)
        located: dict[str, dict[str, np.ndarray]] = {}
        for (strut, end), c in self.connectors.items():
            located.setdefault(c.node, {})[f"{strut}:{end}"] = c.u
        for node, state in self.nodes.items():
            report: NodeReport = reports[node]  # type: ignore[assignment]
            psi = yaw_of(state.rotation)
            out[node] = replace(report, tilt=rot_z(-psi) @ state.rotation,
                                connectors={**report.connectors, **located.get(node, {})})
        for strut, report in reports.items():
            if not isinstance(report, StrutReport):
                continue
            ends = [e for e in ENDS if (strut, e) in self.connectors]
            if not ends:
                continue
            z = np.zeros(3)
            x = np.zeros(3)
            for end in ends:
                c = self.connectors[(strut, end)]
                rotation = self.nodes[c.node].rotation
                z += END_SIGN[end] * rotation @ c.u
                x += rot_z(yaw_of(rotation)) @ report.attitude[end][:, 0]
            z /= np.linalg.norm(z)
            x -= (x @ z) * z
            x /= np.linalg.norm(x)
            frame = np.column_stack([x, np.cross(z, x), z])
            attitude = {**report.attitude, **{
                e: rot_z(-yaw_of(self.nodes[self.connectors[(strut, e)].node].rotation))
                @ frame for e in ends}}
            out[strut] = replace(report, attitude=attitude)
        return out
