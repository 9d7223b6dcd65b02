"""The FreeSN report filter (issue 31, item 2): its updates against their closed forms,
and on recorded noisy runs its error against the simulator's truth (the judge channel,
read here only): falling toward ``sigma / sqrt(n)`` at rest, and no lag in a swing; the
batched filter (issue 32) against the per-item one it replaced."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from freesn_filter_reference import ReportFilter as Reference
from scipy.spatial.transform import Rotation

from msrr.core.alignment import rot_z
from msrr.core.app.run import RunRequest, execute_run, prepare_run
from msrr.core.configuration import Configuration
from msrr.core.driver import Observation
from msrr.core.errors import ExecutionError
from msrr.core.freeform.mujoco import yaw_of
from msrr.core.library import load_library
from msrr.plugins.freesn.sim import FreeSNMujocoDriver
from msrr.plugins.freesn.sim.controller import FreeSNController
from msrr.plugins.freesn.sim.filtering import (
    NodeState,
    ReportFilter,
    attitude_predict,
    attitude_update,
    direction_update,
    tilt_residual,
)
from msrr.plugins.freesn.sim.recognizer import FreeSNRecognizer, links_of, root_order
from msrr.plugins.freesn.sim.world import Accuracy, NodeReport

NOISE = np.radians(4.0)
S6N3 = Path(__file__).resolve().parents[3] / "plugins" / "freesn" / "libraries" / "S6N3.json"


def _library_config(config_id: str) -> Configuration:
    sub = next(iter(load_library(S6N3).sublibraries.values()))
    return sub.configurations[config_id].configuration


def test_direction_update_from_the_reading_variance_is_the_running_mean():
    """No motion, ``var = r`` at the first reading: the n-th gain is 1/n, the variance
    ``r / n`` and the estimate the mean of the readings (to second order in their spread)."""
    rng = np.random.default_rng(4)
    truth = np.array([0.3, -0.2, 0.93])
    truth /= np.linalg.norm(truth)
    fixes = [Rotation.from_rotvec(rng.normal(0.0, NOISE, 3)).as_matrix() @ truth
             for _ in range(50)]
    u, var = fixes[0], NOISE**2
    for n, fix in enumerate(fixes[1:], start=2):
        u, var = direction_update(u, var, fix, NOISE**2)
        assert var == pytest.approx(NOISE**2 / n)
        mean = np.mean(fixes[:n], axis=0)
        mean /= np.linalg.norm(mean)
        assert np.degrees(np.arccos(min(1.0, u @ mean))) < 0.05
    assert np.degrees(np.arccos(u @ truth)) < 3.0 * np.degrees(NOISE) / np.sqrt(50)


def test_attitude_update_is_the_linear_kalman_update():
    """A tilt reading on a level node with a correlated attitude-bias covariance: the
    step, the new covariance and the turned attitude are ``K = P H^T (H P H^T + r)^-1``."""
    cov = np.diag([1e-3, 2e-3, 5e-4, 1e-6, 1e-6, 1e-6])
    cov[0, 3] = cov[3, 0] = 2e-5
    state = NodeState(np.eye(3), np.zeros(3), cov)
    tilted = Rotation.from_rotvec([0.01, -0.02, 0.0]).as_matrix()  # the node tilted by that
    residual = tilt_residual(state.rotation, tilted)
    np.testing.assert_allclose(residual, [0.01, -0.02], atol=1e-4)
    r = NOISE**2
    out = attitude_update(state, residual, np.eye(6)[:2], r * np.eye(2))
    k_x, k_y = cov[0, 0] / (cov[0, 0] + r), cov[1, 1] / (cov[1, 1] + r)
    turned = Rotation.from_matrix(out.rotation).as_rotvec()
    np.testing.assert_allclose(turned[:2], [k_x * residual[0], k_y * residual[1]], atol=1e-9)
    assert out.bias[0] == pytest.approx(cov[3, 0] / (cov[0, 0] + r) * residual[0])
    assert out.cov[0, 0] == pytest.approx((1 - k_x) * cov[0, 0])
    assert out.cov[3, 3] == pytest.approx(cov[3, 3] - cov[3, 0]**2 / (cov[0, 0] + r))
    assert out.cov[2, 2] == cov[2, 2]   # the heading is not seen by a tilt


def test_attitude_predict_integrates_the_gyro_and_grows_the_covariance():
    acc = Accuracy(angle=NOISE, gyro_noise=2e-4, gyro_walk=1e-4)
    rate, dt = np.array([0.4, -0.2, 0.7]), 0.1
    state = NodeState(np.eye(3), np.array([0.01, 0.0, 0.0]), np.zeros((6, 6)))
    for _ in range(20):
        state = attitude_predict(state, rate + np.array([0.01, 0.0, 0.0]), dt, acc)
    np.testing.assert_allclose(state.rotation, Rotation.from_rotvec(rate * 2.0).as_matrix(),
                               atol=1e-9)
    one = attitude_predict(NodeState(np.eye(3)), rate, dt, acc)
    np.testing.assert_allclose(np.diag(one.cov), [4e-8 * dt] * 3 + [1e-8 * dt] * 3)


def _errors(config: Configuration, truth: Configuration) -> float:
    """RMS angle [deg] of ``config``'s struts from the truth's."""
    return float(np.sqrt(np.mean([np.arccos(np.clip(config.edge(e.id).z @ e.z, -1, 1))**2
                                  for e in truth.edges() if e.z is not None])) * 180 / np.pi)


def _record(goals: list[Configuration | None]) -> np.ndarray:
    """S6N3 at 4 deg + 10 % slip, one tick of 0.1 s per goal (``None``: no command):
    per tick the raw, filtered and low-passed (weight 0.1, ~19 ticks) recognition's RMS
    error [deg] against the truth in the root's frame."""
    recognizer, controller = FreeSNRecognizer(), FreeSNController()
    rows, smooth = [], None
    with FreeSNMujocoDriver(noise=NOISE, slip=0.10, seed=11) as driver:
        driver.reset(_library_config("S6N3-2.2"))
        report_filter = recognizer.report_filter()
        for goal in goals:
            observation = driver.get_observation()
            filtered = report_filter.update(observation)
            raw = recognizer.recognize(observation.sensors)
            nodes = [m for m, r in observation.sensors.items() if isinstance(r, NodeReport)]
            truth = driver.world.ground_truth(root_order(nodes, links_of(observation.sensors))[0])
            z = {e.id: e.z for e in raw.edges()}
            smooth = z if smooth is None else {
                k: (0.9 * smooth[k] + 0.1 * v) / np.linalg.norm(0.9 * smooth[k] + 0.1 * v)
                for k, v in z.items()}
            rows.append([_errors(c, truth) for c in
                         (raw, recognizer.recognize(filtered.sensors), raw.with_vectors(z=smooth))])
            driver.send_action({} if goal is None else controller.commands(goal, filtered))
            driver.step(0.1)
    return np.array(rows)


def _rms(rows: np.ndarray) -> np.ndarray:
    return np.sqrt(np.mean(rows**2, axis=0))


def test_filtered_shape_at_rest_falls_toward_sigma_over_root_n():
    rows = _record([None] * 40)
    raw, filtered, _ = _rms(rows)
    assert raw > 6.0                                   # 4 deg per axis: ~9 deg per strut
    assert _rms(rows[:5])[1] > _rms(rows[30:])[1]
    assert _rms(rows[30:])[1] < 2.0 * raw / np.sqrt(30)


def test_filtered_shape_follows_a_swing_without_a_low_pass_lag():
    """S6N3 2.2 -> 2.3 swings a leg 150 deg in ~4 s, driven from the filtered reports."""
    rows = _record([None] * 5 + [_library_config("S6N3-2.3")] * 40)
    raw, filtered, low_passed = _rms(rows[5:])
    assert filtered < raw / 3.0
    assert filtered < low_passed / 5.0                 # the low-pass lags the swing


def test_exact_reports_pass_unchanged():
    recognizer = FreeSNRecognizer()
    with FreeSNMujocoDriver(seed=1) as driver:
        driver.reset(_library_config("S6N3-2.2"))
        observation = driver.get_observation()
        assert recognizer.report_filter().update(observation) is observation


def test_reports_stating_different_accuracies_are_refused_not_averaged():
    """The gains are one noise model's: reports that disagree on it stop the run with a
    reason instead of being filtered with the first report's figures."""
    node = NodeReport(np.eye(3), {}, np.zeros(3), Accuracy(angle=0.03))
    reports = {"n0": node, "n1": replace(node, accuracy=Accuracy(angle=0.06))}
    with pytest.raises(ExecutionError, match="2 different ones"):
        ReportFilter().update(Observation(time=0.0, sensors=reports))


class _Twin:
    """The batched filter, with the per-item reference fed the same observations; the
    largest difference of their estimates over the run in ``worst``."""

    def __init__(self, root: str | None):
        self.batched, self.reference = ReportFilter(root), Reference(root)
        self.worst, self.filtered = 0.0, 0

    def update(self, observation: Observation) -> Observation:
        out, ref = self.batched.update(observation), self.reference.update(observation)
        for module, report in ref.sensors.items():
            got = out.sensors[module]
            pairs = [(got.tilt, report.tilt)] + [
                (getattr(got, name)[k], v) for name in ("connectors", "attitude")
                for k, v in getattr(report, name, {}).items()]
            for a, b in pairs:
                self.worst = max(self.worst, float(np.abs(a - b).max()))
        self.filtered += out is not observation
        return out


def test_the_batched_filter_estimates_what_the_per_item_filter_did(tmp_path, monkeypatch):
    """Issue 32: a closed-loop run at 4 deg + 10 % slip (S6N3 2.3 -> 3.1, a leg swings and
    docks: new connectors mid-run), every observation through both: the same estimates
    to 1e-9 (nodes, connectors, strut attitudes). The run takes 10 filtered observations
    with the connectors' estimates fused at 0.02 (``SimOptions.fusion``; 11 at 0.05, 20
    and more at 0.2)."""
    twins: list[_Twin] = []

    def twin(self: FreeSNRecognizer) -> _Twin:
        twins.append(_Twin(self.root))
        return twins[-1]

    monkeypatch.setattr(FreeSNRecognizer, "report_filter", twin)
    configs = S6N3.parents[1] / "configs" / "library"
    result = execute_run(prepare_run(RunRequest(
        robot="freesn", start=configs / "S6N3-2.3.json", goal=configs / "S6N3-3.1.json",
        out=tmp_path / "run", log=False, seed=5,
        driver_options=(("noise", float(NOISE)), ("slip", 0.10)))))
    assert result.docks == 1
    assert twins and sum(t.filtered for t in twins) >= 10
    assert max(t.worst for t in twins) < 1e-9


def _turning_node(rates: list[np.ndarray], step: float = 0.1) -> list[NodeReport]:
    """One node turning at ``rates[k]`` [rad/s, node frame] through step ``k``, from a
    tilted start: its reports after each step (the first at time 0), tilts exact,
    ``gyro`` the step's rate, ``turned`` their product, stamped by the module's clock."""
    start = Rotation.from_rotvec([0.1, -0.05, 0.3]).as_matrix()
    acc = Accuracy(angle=NOISE, gyro_noise=2e-4, gyro_bias=5e-4, gyro_walk=1e-4)
    turned, out = np.eye(3), []
    for k, rate in enumerate([np.zeros(3), *rates]):
        turned = turned @ Rotation.from_rotvec(rate * (step if k else 0.0)).as_matrix()
        true = start @ turned
        out.append(NodeReport(rot_z(-yaw_of(true)) @ true, {}, rate, acc, turned,
                              round(k * step, 9), step if k else 0.0))
    return out


def _fed(reports: list[tuple[float, NodeReport]]) -> ReportFilter:
    report_filter = ReportFilter()
    for time, report in reports:
        report_filter.update(Observation(time=time, sensors={"N1": report}))
    return report_filter


def test_a_report_delivered_twice_changes_nothing():
    """Issue 32: over the link the host holds a module's last report until the next
    arrives; the filter takes it again at the next tick. Its stamp says it is no new
    reading: the node's estimate (attitude, bias, covariance) stays as it was, rather
    than the held rate being integrated again and its tilt counted twice."""
    r = _turning_node([np.array([0.3, -0.6, 1.2])])
    once = _fed([(0.0, r[0]), (0.1, r[1])]).nodes["N1"]
    twice = _fed([(0.0, r[0]), (0.1, r[1]), (0.2, r[1]), (0.3, r[1])]).nodes["N1"]
    for field in ("rotation", "bias", "cov"):
        np.testing.assert_array_equal(getattr(twice, field), getattr(once, field))


def test_two_reports_with_one_missed_between_give_the_estimate_of_all_three():
    """The second of three reports lost (or polled past): the third's delta-angle
    counter against the first's gives the rotation of both steps, so the attitude is the
    one all three give (and the truth: the tilts here are exact), not the last step's
    rate integrated over the whole gap."""
    rates = [np.array([0.3, -0.6, 1.2]), np.array([-0.9, 0.2, -0.4])]
    r = _turning_node(rates)
    every = _fed([(0.0, r[0]), (0.1, r[1]), (0.2, r[2])]).nodes["N1"]
    missed = _fed([(0.0, r[0]), (0.2, r[2])]).nodes["N1"]
    np.testing.assert_allclose(missed.rotation, every.rotation, atol=1e-9)
    truth = Rotation.from_rotvec([0.1, -0.05, 0.3]).as_matrix() @ r[2].turned
    yaw = yaw_of(truth) - yaw_of(every.rotation)   # the filter's heading starts at 0
    np.testing.assert_allclose(rot_z(yaw) @ every.rotation, truth, atol=1e-9)
    np.testing.assert_allclose(missed.bias, every.bias, atol=1e-12)


def test_the_simulated_node_gyro_counts_its_rates_with_the_module_clock():
    """A noisy S6N3 swinging a leg: each node report's ``turned`` is the last one times
    the rotation of its ``gyro`` over its ``step``, stamped with the simulator's time."""
    controller = FreeSNController()
    with FreeSNMujocoDriver(noise=NOISE, slip=0.10, seed=11) as driver:
        driver.reset(_library_config("S6N3-2.2"))
        before = driver.get_observation()
        for _ in range(5):
            driver.send_action(controller.commands(_library_config("S6N3-2.3"), before))
            driver.step(0.1)
            after = driver.get_observation()
            for node, report in after.sensors.items():
                if not isinstance(report, NodeReport):
                    continue
                assert report.stamp == after.time and report.step == pytest.approx(0.1)
                step = Rotation.from_rotvec(report.gyro * report.step).as_matrix()
                np.testing.assert_allclose(report.turned, before.sensors[node].turned @ step,
                                           atol=1e-12)
            before = after
    assert any(np.abs(r.gyro).max() > 0.05 for r in after.sensors.values()
               if isinstance(r, NodeReport))   # the nodes did turn


def test_a_held_observation_moves_no_connector():
    """The whole observation delivered again at the next tick (the host heard no module):
    no node report is new, so no localisation is read again and every filtered report --
    tilts, connector directions, strut attitudes -- is what it was (to the rounding of
    the encoders' unchanged count turned by itself)."""
    with FreeSNMujocoDriver(noise=NOISE, slip=0.10, seed=11) as driver:
        driver.reset(_library_config("S6N3-2.2"))
        first = driver.get_observation()
        driver.step(0.1)
        second = driver.get_observation()
    report_filter = ReportFilter()
    report_filter.update(first)
    fresh = report_filter.update(second)
    held = report_filter.update(replace(second, time=second.time + 0.1))
    for module, report in fresh.sensors.items():
        again = held.sensors[module]
        arrays = [("tilt", report.tilt, again.tilt)] + [
            (f"{name} {k}", v, getattr(again, name)[k]) for name in ("connectors", "attitude")
            for k, v in getattr(report, name, {}).items()]
        for what, a, b in arrays:
            np.testing.assert_allclose(b, a, atol=1e-12, err_msg=f"{module} {what}")
