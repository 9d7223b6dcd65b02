"""The module reports as a filter over the run sees them: what each module's own motion
sensors predict, corrected by its noisy readings (issue 31, item 2).

A FreeSN report's angles carry white noise (``Accuracy.angle`` per axis, per report):
recognized from one report, each strut's direction is off by ~2.5 ``angle`` RMS (10 deg at
4 deg of noise), and a low-pass that averages it out lags the motion it tracks. But each
module also senses its own motion with little noise: a node's gyro its rotation, a
connector's wheel encoders its rolling on the node (:attr:`~.world.StrutReport.rolled`).
:class:`ReportFilter` keeps, for one run,

* per node, its attitude ``R`` (node -> the frame its gyros integrate in, ``W``) and gyro
  bias ``b``: an error-state Kalman filter (the multiplicative EKF of spacecraft attitude
  estimation, Markley & Crassidis 2014, ch. 6; :func:`attitude_predict`,
  :func:`attitude_update`) predicted by the gyro, ``R <- R exp([(w - b) dt])``, and
  corrected by the accelerometer's vertical (the reported tilt) and, except for the
  root of its group, by its heading relative to the root that the struts' attitudes give
  (:func:`.recognizer.node_headings`, the recognizer's least squares); ``dt`` and ``w dt``
  come from the report's stamp and delta-angle counter (:meth:`ReportFilter._gyros`), so
  a report the host holds is not used again and one after reports missed is predicted
  over the whole gap (issue 32: over the module link);
* per docked connector, its direction on the node ``u`` (node frame): predicted by the
  encoders' rolling ``u <- D u`` and corrected by the magnetic localisation, a Kalman
  filter on the sphere with one variance per axis (:func:`direction_predict`,
  :func:`direction_update`).

Every gain comes from the variances the reports state (:class:`~.world.Accuracy`): the
readings' ``angle``, the gyro's noise, bias and bias walk, the encoders' slip and drift.
A constant state read ``n`` times has its error fall as ``angle / sqrt(n)``; a moving one
keeps the motion the sensors predict, without a low-pass's lag.

The output is a report set of the same shape built from the filtered state -- node tilts
``Rz(-psi) R``, localisations ``u`` and strut attitudes ``Rz(-psi_i) S`` (``S`` the
strut's rotation, its axis the mean of its ends' ``R u``) -- so the recognizer and the
controllers read it as they read raw reports, and the node headings the controllers
turn commands with are the filter's. Exact readings (``angle`` 0) pass unchanged.

The filter is batched (issue 32): every node's attitude and every connector's direction
are rows of one array, and each step above is a handful of numpy operations on stacked
3x3 (and 6x6) matrices, whatever the number of modules; the functions below take one
item or a stack of them alike (leading dimensions).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.spatial.transform import Rotation

from msrr.core.alignment import wrap_angle
from msrr.core.driver import Observation
from msrr.core.errors import ExecutionError
from msrr.core.kinematics.rotations import rodrigues, skew

from .geometry import END_SIGN
from .odometry import UPRIGHT
from .recognizer import Links, links_of, node_headings, root_order
from .world import Accuracy, NodeReport, StrutReport

__all__ = ["NodeState", "ReportFilter", "attitude_predict", "attitude_update",
           "direction_predict", "direction_update", "tilt_residual"]

Reports = Mapping[str, "NodeReport | StrutReport"]

_EYE3 = np.eye(3)
_EYE6 = np.eye(6)


def _dot(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Dot products along the last axis, shape (...) (summed in order, as ``u @ v``)."""
    return (u * v).sum(axis=-1)


def _norm(v: np.ndarray) -> np.ndarray:
    """Euclidean norms along the last axis, shape (...)."""
    return np.sqrt(_dot(v, v))


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Cross products along the last axis (``np.cross``'s arithmetic, without its
    overhead on small stacks)."""
    return np.stack([u[..., 1] * v[..., 2] - u[..., 2] * v[..., 1],
                     u[..., 2] * v[..., 0] - u[..., 0] * v[..., 2],
                     u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]], axis=-1)


def _apply(rotation: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``rotation @ v`` for stacks: (..., 3, 3) and (..., 3) -> (..., 3)."""
    return (rotation @ v[..., None])[..., 0]


def _t(m: np.ndarray) -> np.ndarray:
    """The transposes of a stack of matrices."""
    return np.swapaxes(m, -1, -2)


def _exp(rotvec: np.ndarray) -> np.ndarray:
    """The rotations (..., 3, 3) of rotation vectors (..., 3) [rad]; to first order near
    zero."""
    rotvec = np.asarray(rotvec, dtype=float)
    angle = _norm(rotvec)
    small = angle < 1e-12
    out = rodrigues(rotvec / np.where(small, 1.0, angle)[..., None], angle)
    if np.any(small):
        out[small] = _EYE3 + skew(rotvec[small])
    return out


def _yaw(rotation: np.ndarray) -> np.ndarray:
    """The yaws [rad] (...) of the rotations about ``z`` nearest to ``rotation``
    (..., 3, 3) (Frobenius; :func:`msrr.core.freeform.mujoco.yaw_of`)."""
    return np.arctan2(rotation[..., 1, 0] - rotation[..., 0, 1],
                      rotation[..., 0, 0] + rotation[..., 1, 1])


def _rot_z(theta: np.ndarray) -> np.ndarray:
    """Rotations (..., 3, 3) about ``z`` by ``theta`` (...) [rad]."""
    c, s = np.cos(theta), np.sin(theta)
    out = np.zeros((*np.shape(theta), 3, 3))
    out[..., 0, 0], out[..., 0, 1], out[..., 1, 0], out[..., 1, 1] = c, -s, s, c
    out[..., 2, 2] = 1.0
    return out


# -- a direction on the sphere ------------------------------------------------------------

def direction_predict(u: np.ndarray, var: float | np.ndarray, rolled: np.ndarray,
                      q: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Move unit vectors ``u`` (..., 3) by the rotations ``rolled`` (..., 3, 3) the encoders
    counted; their variance per axis ``var`` (...) [rad^2] grows by the rolling's ``q``
    [rad^2]."""
    return _apply(rolled, np.asarray(u, dtype=float)), np.asarray(var + q, dtype=float)


def direction_update(u: np.ndarray, var: float | np.ndarray, fix: np.ndarray, r: float
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Kalman update of unit vectors ``u`` (..., 3) (variance ``var`` (...) [rad^2] per
    tangent axis) by readings ``fix`` (..., 3) of variance ``r``: ``u`` turns toward
    ``fix`` along their great circle by ``k = var / (var + r)`` of their angle,
    ``var <- (1 - k) var``. From ``var = r`` and no motion, the ``n``-th reading gets
    ``k = 1/n``: the running mean, ``var = r / n``."""
    u = np.asarray(u, dtype=float)
    var = np.asarray(var, dtype=float)
    fix = np.asarray(fix, dtype=float)
    fix = fix / _norm(fix)[..., None]
    total = var + r
    k = np.where(total > 0.0, var / np.where(total > 0.0, total, 1.0), 1.0)
    axis = _cross(u, fix)
    size = _norm(axis)
    turns = size > 1e-12
    angle = np.arctan2(size, _dot(u, fix))
    rotvec = axis / np.where(turns, size, 1.0)[..., None] * (k * angle)[..., None]
    u = np.where(turns[..., None], _apply(_exp(rotvec), u), u)
    return u / _norm(u)[..., None], (1.0 - k) * var


# -- a node's attitude and gyro bias ------------------------------------------------------

@dataclass
class NodeState:
    """One node's filtered attitude (or, with leading dimensions, a stack of them).

    Attributes:
        rotation: node -> gyro frame ``W`` (3, 3). bias: gyro bias estimate (3,) [rad/s].
        cov: covariance (6, 6) of the error state ``(dtheta, db)``: ``dtheta`` the attitude
            error in ``W`` [rad] (``R_true = exp([dtheta]) R``), ``db`` the bias error.
    """

    rotation: np.ndarray
    bias: np.ndarray = field(default_factory=lambda: np.zeros(3))
    cov: np.ndarray = field(default_factory=lambda: np.zeros((6, 6)))

    def __getitem__(self, index: np.ndarray | slice) -> NodeState:
        return NodeState(self.rotation[index], self.bias[index], self.cov[index])

    def __setitem__(self, index: np.ndarray | slice, value: NodeState) -> None:
        self.rotation[index], self.bias[index], self.cov[index] = \
            value.rotation, value.bias, value.cov


def attitude_predict(state: NodeState, gyro: np.ndarray, dt: float | np.ndarray,
                     acc: Accuracy) -> NodeState:
    """Propagate by the gyros' mean body rates ``gyro`` (..., 3) [rad/s] over ``dt`` [s]
    (a scalar or one per node, (...)): ``R <- R exp([(w - b) dt])``; ``P <- F P F^T + Q``
    with ``F = [[I, -R dt], [0, I]]`` and ``Q = diag(gyro_noise^2 dt I, gyro_walk^2 dt I)``."""
    dt = np.asarray(dt, dtype=float)
    f = np.broadcast_to(_EYE6, state.cov.shape).copy()
    f[..., :3, 3:] = -state.rotation * dt[..., None, None]
    q = _EYE6 * (np.array([acc.gyro_noise**2] * 3 + [acc.gyro_walk**2] * 3)
                 * dt[..., None])[..., None, :]
    return NodeState(state.rotation @ _exp((gyro - state.bias) * dt[..., None]),
                     state.bias.copy(), f @ state.cov @ _t(f) + q)


def attitude_update(state: NodeState, residual: np.ndarray, rows: np.ndarray,
                    r: np.ndarray) -> NodeState:
    """Kalman update by measurements ``residual`` (..., m) = ``rows`` (m, 6) times the
    error state plus noise of covariance ``r`` (m, m): ``K = P H^T (H P H^T + r)^-1``,
    the error ``K y`` applied (``R <- exp([dtheta]) R``, ``b <- b + db``),
    ``P <- (I - K H) P``."""
    s = rows @ state.cov @ rows.T + r
    gain = _t(np.linalg.solve(s, rows @ state.cov))
    step = (gain @ residual[..., None])[..., 0]
    cov = (_EYE6 - gain @ rows) @ state.cov
    return NodeState(_exp(step[..., :3]) @ state.rotation, state.bias + step[..., 3:],
                     0.5 * (cov + _t(cov)))


def tilt_residual(rotation: np.ndarray, tilt: np.ndarray) -> np.ndarray:
    """The attitude errors about ``W``'s x and y (..., 2) [rad] that the reported tilts
    (..., 3, 3) show: their vertical in the node frame (row 2), turned into ``W`` by
    ``rotation``, is ``e_z + e_z x dtheta`` to first order."""
    up = _apply(rotation, tilt[..., 2, :])
    return np.stack([up[..., 1], -up[..., 0]], axis=-1)


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
class _Connectors:
    """The docked connectors' directions, one row each."""

    keys: list[tuple[str, str]]
    """``(strut, end)`` per row."""
    nodes: list[str]
    u: np.ndarray
    """(m, 3) unit vectors in the node frames."""
    var: np.ndarray
    """(m,) variances per axis [rad^2]."""
    rolled: np.ndarray
    """(m, 3, 3) the encoders' count at the last report (identity where none)."""
    encoded: np.ndarray
    """(m,) whether the report had an encoder count."""


def _no_connectors() -> _Connectors:
    return _Connectors([], [], np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3, 3)),
                       np.zeros(0, dtype=bool))


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
        self._ids: list[str] = []
        self._state = NodeState(np.zeros((0, 3, 3)), np.zeros((0, 3)), np.zeros((0, 6, 6)))
        self._stamps = np.zeros(0)               # per node, the stamp of the reading used last
        self._turned = np.zeros((0, 3, 3))       # ... and its delta-angle counter
        self._new: dict[str, bool] = {}          # per node, whether this update's reading is new
        self._connectors = _no_connectors()
        self.last: Observation | None = None

    @property
    def nodes(self) -> dict[str, NodeState]:
        """Every node's filtered state, by id (a copy)."""
        return {n: NodeState(self._state.rotation[i].copy(), self._state.bias[i].copy(),
                             self._state.cov[i].copy()) for i, n in enumerate(self._ids)}

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
        self._update_connectors(reports, links, acc, dt)
        self.last = replace(observation, sensors=self._reports(reports))
        return self.last

    def _nodes(self, reports: Reports, links: Links, acc: Accuracy, dt: float) -> None:
        """Predict every node by its gyro, correct by its tilt and (all but the roots of
        their groups, after the roots) by their heading relative to their root."""
        ids = sorted(m for m, r in reports.items() if isinstance(r, NodeReport))
        n = len(ids)
        row = {m: i for i, m in enumerate(ids)}
        roots = _group_roots(ids, links, self.root)
        relative = node_headings(reports, links, self.root)
        base = np.array([row[roots[m]] for m in ids], dtype=int)
        is_root = base == np.arange(n)
        tilt = np.array([reports[m].tilt for m in ids], dtype=float).reshape(n, 3, 3)  # type: ignore[union-attr]
        was = {m: i for i, m in enumerate(self._ids)}
        prev = np.array([was.get(m, -1) for m in ids], dtype=int)
        known = prev >= 0
        rates, gaps, new = self._gyros(reports, ids, prev, dt)
        moved, held = known & new, known & ~new   # held: a reading already used, no news
        state = NodeState(np.empty((n, 3, 3)), np.zeros((n, 3)), np.empty((n, 6, 6)))
        if np.any(held):
            state[held] = self._state[prev[held]]
        if np.any(moved):
            state = _put(state, moved, attitude_predict(_take(self._state, prev[moved]),
                                                        rates[moved], gaps[moved], acc))
        fresh = ~known & is_root   # the root of a new group: heading 0
        if np.any(fresh):
            state[fresh] = _first(tilt[fresh], np.zeros(int(fresh.sum())), 0.0, acc)
        r_tilt = acc.angle**2 * np.eye(2)
        ready = moved | fresh
        if np.any(ready):
            state = _put(state, ready, attitude_update(_at(state, ready), tilt_residual(
                _at(state, ready).rotation, _at(tilt, ready)), _TILT_ROWS, r_tilt))
        late = ~known & ~is_root   # new in a known group: its heading from the struts, after its root's
        if np.any(late):
            psi = _yaw(state.rotation[base[late]]) + np.array(
                [relative.get(ids[i], 0.0) for i in np.flatnonzero(late)])
            state[late] = _first(tilt[late], psi, 2.0 * acc.angle**2, acc)
            state[late] = attitude_update(state[late], tilt_residual(state.rotation[late],
                                                                     tilt[late]),
                                          _TILT_ROWS, r_tilt)
        upright = state.rotation[:, 2, 2] >= UPRIGHT
        seen = np.flatnonzero(~is_root & new & upright & upright[base])
        if seen.size:
            yaw = _yaw(state.rotation)
            heading = wrap_angle(np.array([relative[ids[i]] for i in seen])
                                 + yaw[base[seen]] - yaw[seen])
            state[seen] = attitude_update(state[seen], heading[:, None], _HEADING_ROWS,
                                          2.0 * acc.angle**2 * np.eye(1))   # two attitudes
        self._ids, self._state = ids, state
        self._new = dict(zip(ids, new.tolist(), strict=True))

    def _gyros(self, reports: Reports, ids: list[str], prev: np.ndarray, dt: float
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per node of ``ids`` (``prev`` its row before, -1 if none): the mean rate (n, 3)
        [rad/s] it turned at since the reading used last, over how long (n,) [s], and
        whether its reading is new (n,). A stamped report (:attr:`.world.NodeReport.stamp`)
        whose stamp is not past the last one used is not new (a report the host holds or
        an older one); one step past it, its ``gyro`` is that step's rate; further, the
        counter's difference over the stamps' (``log(Q_0^T Q_1) / (t_1 - t_0)``: the steps
        in between included, however many reports were missed). Unstamped: ``gyro`` over
        the observations' ``dt``, every report new. Keeps the stamps and counters used."""
        n = len(ids)
        nodes: list[NodeReport] = [reports[m] for m in ids]  # type: ignore[misc]
        stamps = np.array([np.nan if r.stamp is None else r.stamp for r in nodes], dtype=float)
        turned = np.array([r.turned for r in nodes], dtype=float).reshape(n, 3, 3)
        steps = np.array([r.step for r in nodes], dtype=float)
        rates = np.array([r.gyro for r in nodes], dtype=float).reshape(n, 3)
        known = prev >= 0
        last = np.full(n, np.nan)
        last[known] = self._stamps[prev[known]]
        stamped = ~np.isnan(stamps) & ~np.isnan(last)
        gaps = np.where(stamped, stamps - np.where(stamped, last, 0.0), dt)
        new = ~stamped | (gaps > 0.0)
        counted = stamped & new & (gaps >= 1.5 * steps)
        if np.any(counted):
            j = prev[counted]
            turn = Rotation.from_matrix(_t(self._turned[j]) @ turned[counted]).as_rotvec()
            rates[counted] = turn / gaps[counted][:, None]
        keep = known & ~new
        stamps[keep], turned[keep] = self._stamps[prev[keep]], self._turned[prev[keep]]
        self._stamps, self._turned = stamps, turned
        return rates, gaps, new

    def _update_connectors(self, reports: Reports, links: Links, acc: Accuracy, dt: float
                           ) -> None:
        """Predict every docked connector by its encoders, correct by its localisation."""
        r = acc.angle**2
        keys = list(links)
        nodes = [links[k] for k in keys]
        m = len(keys)
        fix = np.array([reports[node].connectors[f"{s}:{e}"]  # type: ignore[union-attr]
                        for (s, e), node in zip(keys, nodes, strict=True)],
                       dtype=float).reshape(m, 3)
        counts = [reports[s].rolled.get(e) for s, e in keys]  # type: ignore[union-attr]
        encoded = np.array([c is not None for c in counts], dtype=bool)
        rolled = np.array([_EYE3 if c is None else c for c in counts], dtype=float).reshape(m, 3, 3)
        old = self._connectors
        was = {k: i for i, k in enumerate(old.keys)}
        prev = np.array([was.get(k, -1) for k in keys], dtype=int)
        go_on = encoded & np.array([p >= 0 and old.nodes[p] == node
                                    for p, node in zip(prev, nodes, strict=True)], dtype=bool)
        go_on[go_on] &= old.encoded[prev[go_on]]
        u = fix / _norm(fix)[:, None]
        var = np.full(m, r)
        if np.any(go_on):
            j = prev[go_on]
            step = rolled[go_on] @ _t(old.rolled[j])
            turned = np.arccos(np.clip(0.5 * (np.trace(step, axis1=-2, axis2=-1) - 1.0),
                                       -1.0, 1.0))
            moved, grown = direction_predict(old.u[j], old.var[j], step,
                                             (acc.slip * turned)**2 + acc.drift**2 * dt)
            read = np.array([self._new.get(nodes[i], True) for i in np.flatnonzero(go_on)],
                            dtype=bool)   # a node report already used: no new localisation
            if not read.all():
                moved[read], grown[read] = direction_update(moved[read], grown[read],
                                                            fix[go_on][read], r)
                u[go_on], var[go_on] = moved, grown
            else:
                u[go_on], var[go_on] = direction_update(moved, grown, fix[go_on], r)
        self._connectors = _Connectors(keys, nodes, u, var, rolled, encoded)

    def _reports(self, reports: Reports) -> dict[str, NodeReport | StrutReport]:
        """The reports the filtered state gives (the module docstring)."""
        out: dict[str, NodeReport | StrutReport] = dict(reports)
        state, c = self._state, self._connectors
        yaw = _yaw(state.rotation)
        tilts = _rot_z(-yaw) @ state.rotation
        located: dict[str, dict[str, np.ndarray]] = {}
        for (strut, end), node, u in zip(c.keys, c.nodes, c.u, strict=True):
            located.setdefault(node, {})[f"{strut}:{end}"] = u
        for i, node in enumerate(self._ids):
            report: NodeReport = reports[node]  # type: ignore[assignment]
            out[node] = replace(report, tilt=tilts[i],
                                connectors={**report.connectors, **located.get(node, {})})
        if not c.keys:
            return out
        row = {m: i for i, m in enumerate(self._ids)}
        at = np.array([row[n] for n in c.nodes], dtype=int)
        struts = {s: i for i, s in enumerate(dict.fromkeys(s for s, _ in c.keys))}
        slot = np.array([struts[s] for s, _ in c.keys], dtype=int)
        side = np.array([0 if e == "a" else 1 for _, e in c.keys], dtype=int)
        sign = np.array([END_SIGN[e] for _, e in c.keys])
        ends = np.zeros((2, len(struts), 2, 3))   # z and x terms per strut and end
        ends[0, slot, side] = sign[:, None] * _apply(state.rotation[at], c.u)
        columns = np.array([reports[s].attitude[e][:, 0] for s, e in c.keys], dtype=float)  # type: ignore[union-attr]
        ends[1, slot, side] = _apply(_rot_z(yaw[at]), columns)
        z, x = ends[0, :, 0] + ends[0, :, 1], ends[1, :, 0] + ends[1, :, 1]
        z /= _norm(z)[:, None]
        x -= _dot(x, z)[:, None] * z
        x /= _norm(x)[:, None]
        frames = np.stack([x, _cross(z, x), z], axis=-1)
        attitudes = _rot_z(-yaw[at]) @ frames[slot]
        by_strut: dict[str, dict[str, np.ndarray]] = {}
        for (strut, end), attitude in zip(c.keys, attitudes, strict=True):
            by_strut.setdefault(strut, {})[end] = attitude
        for strut, attitude in by_strut.items():
            report: StrutReport = reports[strut]  # type: ignore[assignment,no-redef]
            out[strut] = replace(report, attitude={**report.attitude, **attitude})
        return out


def _at(array: NodeState | np.ndarray, mask: np.ndarray) -> NodeState | np.ndarray:
    """The rows of ``mask`` (all of them without a copy)."""
    return array if bool(mask.all()) else array[mask]


def _take(state: NodeState, index: np.ndarray) -> NodeState:
    """The rows ``index`` of ``state`` (in order: ``state`` itself)."""
    same = len(index) == len(state.rotation) and bool((index == np.arange(len(index))).all())
    return state if same else state[index]


def _put(state: NodeState, mask: np.ndarray, rows: NodeState) -> NodeState:
    """``state`` with the rows of ``mask`` replaced by ``rows`` (all: ``rows``)."""
    if bool(mask.all()):
        return rows
    state[mask] = rows
    return state


def _first(tilt: np.ndarray, psi: np.ndarray, heading_var: float, acc: Accuracy
           ) -> NodeState:
    """Nodes seen for the first time: their tilts (k, 3, 3) turned to headings ``psi``
    (k,) (from the struts relative to their roots; 0 for the root of a new group, whose
    heading variance is then 0)."""
    k = len(tilt)
    cov = np.zeros((k, 6, 6))
    cov[:] = np.diag([acc.angle**2, acc.angle**2, heading_var] + [acc.gyro_bias**2] * 3)
    return NodeState(_rot_z(psi) @ _rot_z(-_yaw(tilt)) @ tilt, np.zeros((k, 3)), cov)
