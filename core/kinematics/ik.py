"""Full-body skeletal inverse kinematics (FreeSN paper, section 3.4, eqs. 6-8).

Given the current configuration (the zero point of the joint space) and a target
skeletal configuration with the same ids, possibly measured in another horizontal
frame, :func:`solve_ik` finds the yaw ``theta`` and joint values ``sigma`` that
minimise eq. 6:

    sum_j w_j [ zeta C_j^2 + gamma angle(x_j^rot, Rz(theta) x_j^target)^2
                + angle(z_j^rot, Rz(theta) z_j^target)^2 ]

with ``Z^rot, X^rot, C`` from the skeletal forward kinematics (eq. 7, Alg. 1).

The solver (mink style: the :class:`IKProblem` is the model and objective, the
function is the solver):

1. the yaw is initialised by eq. 8 (:func:`msrr.core.alignment.align_yaw`);
2. L-BFGS-B minimises over ``(theta, sigma)`` with the analytic gradient
   (:meth:`IKProblem.value_and_grad`, reverse mode through the tree);
3. while the residual RMS angle is above the tolerance, new starts are sampled
   (BioIK-like: alternately around the best solution so far and uniformly in the
   joint bounds), each with its own eq. 8 yaw, until a solution is under the
   tolerance, the time budget is spent or the restarts are used up.

A floating base can be put on the ground after the forward kinematics with the
three-point contact model (``IKOptions.ground``, :mod:`.ground`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Literal

import numpy as np
from scipy.optimize import minimize
from threadpoolctl import ThreadpoolController

from ..alignment import align_yaw
from ..configuration import Configuration
from ..errors import ConfigurationError
from .fk import Evaluator, FKState, transformed_configuration, tree_vectors
from .ground import GroundContact, GroundModel, GroundOp
from .rotations import cross
from .tree import KinematicTree

__all__ = ["IKOptions", "IKProblem", "IKSolution", "solve_ik"]

_TINY = 1e-12
_THREADPOOLS: ThreadpoolController | None = None


def _single_threaded_blas():
    """A context that limits BLAS to one thread: L-BFGS-B's small dense algebra is
    an order of magnitude slower when BLAS threads compete for the cores."""
    global _THREADPOOLS
    if _THREADPOOLS is None:
        _THREADPOOLS = ThreadpoolController()
    return _THREADPOOLS.limit(limits=1, user_api="blas")


@dataclass(frozen=True)
class IKOptions:
    """Settings of :func:`solve_ik`.

    Attributes:
        time_budget: wall-clock limit of one solve [s]; the best solution so far is
            returned when it runs out.
        tolerance: a solution succeeds when its RMS angle residual is below this [rad].
        weights: ``w`` of eq. 6 per module (edge): ``{edge id: w}`` (others 1) or an
            array in tree layout; all ones by default.
        gamma: weight of the forward-vector term (0: skeletal, ``x`` ignored).
        zeta: weight of the squared motion costs.
        max_restarts: sampled starts after the first.
        seed: seed of the sampling.
        max_iterations: L-BFGS-B iterations per start.
        initial_sigma: first start (warm start), tree layout; zeros by default.
        initial_yaw: yaw of the first start [rad]; eq. 8 by default.
        solve_yaw: optimise the yaw; ``False`` keeps ``initial_yaw`` (or eq. 8's).
        ground: put the floating base on the ground (three-point contact) after the
            forward kinematics with this :class:`~.ground.GroundModel`
            (``GroundModel.for_configuration(config, robot.spec)`` for the robot's
            geometry); ``None`` leaves the base where the root holds it.
        gradient: ``"analytic"`` (reverse mode) or ``"finite_difference"`` (scipy's
            two-point differences; a reference for benchmarks).
        sample_scale: global samples are drawn from this fraction of the joint bounds.
        polish: L-BFGS-B iterations spent lowering the motion cost after a start first
            reaches the tolerance; a negative value runs L-BFGS-B to convergence.
        memory: L-BFGS-B memory (number of correction pairs).
        ftol: L-BFGS-B relative objective tolerance.
        gtol: L-BFGS-B projected-gradient tolerance.
    """

    time_budget: float = 0.5
    tolerance: float = float(np.deg2rad(0.5))
    weights: Mapping[str, float] | Sequence[float] | np.ndarray | None = None
    gamma: float = 0.0
    zeta: float = 1e-3
    max_restarts: int = 64
    seed: int | None = 0
    max_iterations: int = 400
    initial_sigma: np.ndarray | None = None
    initial_yaw: float | None = None
    solve_yaw: bool = True
    ground: GroundModel | None = None
    gradient: Literal["analytic", "finite_difference"] = "analytic"
    sample_scale: float = 0.5
    polish: int = 0
    memory: int = 20
    ftol: float = 1e-12
    gtol: float = 1e-7

    def __post_init__(self) -> None:
        if self.time_budget <= 0 or self.tolerance <= 0:
            raise ConfigurationError("IKOptions: time_budget and tolerance must be positive")
        if self.gamma < 0 or self.zeta < 0:
            raise ConfigurationError("IKOptions: gamma and zeta must be non-negative")
        if self.max_restarts < 0 or self.max_iterations < 1:
            raise ConfigurationError("IKOptions: max_restarts >= 0 and max_iterations >= 1")
        if self.gradient not in ("analytic", "finite_difference"):
            raise ConfigurationError(f"IKOptions: gradient must be 'analytic' or "
                                     f"'finite_difference', got {self.gradient!r}")


@dataclass(frozen=True)
class IKSolution:
    """Result of :func:`solve_ik` (an expected failure is a result, not an exception).

    Attributes:
        sigma: joint values, tree layout, shape (dim,).
        yaw: yaw ``theta`` [rad] that rotates the target into the root frame.
        cost: the eq. 6 objective.
        motion_cost: sum of the per-module motion costs ``C`` of the solution.
        rms_angle: RMS angle [rad] between the transformed vectors and the
            yaw-rotated target (``z``, and ``x`` where ``gamma > 0``).
        success: ``rms_angle < tolerance``.
        iterations: L-BFGS-B iterations over all starts.
        restarts: sampled starts used after the first.
        reason: ``"tolerance"`` (solved), ``"time_budget"``, ``"max_restarts"`` or
            ``"no_joints"`` (a tree without joints: only the yaw was solved).
        elapsed: wall-clock time of the solve [s].
        ground: the ground contact of the solution when the ground model was used.
        problem: the :class:`IKProblem` that was solved (rebuilds :attr:`configuration`).
    """

    sigma: np.ndarray
    yaw: float
    cost: float
    motion_cost: float
    rms_angle: float
    success: bool
    iterations: int
    restarts: int
    reason: str
    elapsed: float
    ground: GroundContact | None = None
    problem: IKProblem | None = field(default=None, repr=False, compare=False)

    @cached_property
    def configuration(self) -> Configuration:
        """The current configuration moved by the solution (FK, grounded if asked for)."""
        if self.problem is None:
            raise ConfigurationError("this IKSolution carries no problem to rebuild from")
        return self.problem.configuration(self.sigma)


class _Term:
    """Angles between transformed vectors ``a`` and yaw-rotated targets ``b`` (rows)."""

    __slots__ = ("angle", "cross", "sin", "target", "weights")

    def __init__(self, target: np.ndarray, vectors: np.ndarray, weights: np.ndarray):
        self.target = target
        self.weights = weights
        self.cross = cross(vectors, target)
        self.sin = np.sqrt(np.einsum("ni,ni->n", self.cross, self.cross))
        self.angle = np.arctan2(self.sin, np.einsum("ni,ni->n", vectors, target))


class IKProblem:
    """Eq. 6 for one tree, current configuration and target: value, gradient, residuals.

    Args:
        tree: the kinematic tree.
        current: the configuration now (``Z^init``, ``X^init``), the tree's ids.
        target: the target configuration, same ids, any horizontal frame.
        options: weights ``w``, ``gamma``, ``zeta`` and the ground model.
    """

    def __init__(self, tree: KinematicTree, current: Configuration, target: Configuration,
                 options: IKOptions = IKOptions()):
        self.tree = tree
        self.current = current
        self.options = options
        z0, x0, self.has_x = tree_vectors(tree, current)
        zt, xt, has_xt = tree_vectors(tree, target)
        self.evaluator = Evaluator(tree, z0, x0)
        n = len(tree.edges)
        self.n = n
        self.z_target = np.ascontiguousarray(zt.T)
        self.x_target = np.ascontiguousarray(xt.T)
        self.weights = self._weights(options.weights)
        self.use_x = self.has_x & has_xt if options.gamma > 0 else np.zeros(n, dtype=bool)
        self.x_weights = options.gamma * self.weights * self.use_x
        self.zeta = options.zeta
        self.ground = None if options.ground is None else GroundOp(tree, options.ground)
        lo, hi = tree.bounds
        self.lower, self.upper = lo, hi
        self.bounds = [(None, None)] + [(float(a), float(b)) for a, b in zip(lo, hi, strict=True)]
        self.evaluations = 0
        self._last: tuple[np.ndarray, float] | None = None
        self._count = n + int(self.use_x.sum())
        self._with_x = bool(self.x_weights.any())
        self._rz = np.eye(3)

    def _weights(self, weights: Mapping[str, float] | Sequence[float] | np.ndarray | None
                 ) -> np.ndarray:
        if weights is None:
            return np.ones(self.n)
        if isinstance(weights, Mapping):
            unknown = sorted(set(weights) - set(self.tree.edges))
            if unknown:
                raise ConfigurationError(f"IK weights for unknown modules {', '.join(unknown)}")
            return np.array([float(weights.get(e, 1.0)) for e in self.tree.edges])
        w = np.asarray(weights, dtype=np.float64)
        if w.shape != (self.n,):
            raise ConfigurationError(f"IK weights must have shape ({self.n},), got {w.shape}")
        return w

    # -- the objective ---------------------------------------------------------------------

    def _vectors(self, state: FKState) -> tuple[np.ndarray, np.ndarray, object]:
        if self.ground is None:
            return state.z, state.x, None
        contact, cache = self.ground.contact(state.z)
        rot = contact.rotation
        return state.z @ rot.T, state.x @ rot.T, cache

    def _angles(self, yaw: float, z: np.ndarray, x: np.ndarray) -> list[_Term]:
        """Angle terms of eq. 6: z always, x when ``gamma > 0`` and both sides have x."""
        c, s = math.cos(yaw), math.sin(yaw)
        rz = self._rz
        rz[0, 0] = rz[1, 1] = c
        rz[0, 1], rz[1, 0] = s, -s   # rz is Rz(yaw)^T: rows @ rz rotates by yaw
        out = [_Term(self.z_target @ rz, z, self.weights)]
        if self._with_x:
            out.append(_Term(self.x_target @ rz, x, self.x_weights))
        return out

    def _squares(self, terms: list[_Term]) -> float:
        squares = float(terms[0].angle @ terms[0].angle)
        if len(terms) > 1:
            angle = terms[1].angle[self.use_x]
            squares += float(angle @ angle)
        return squares

    def value(self, params: np.ndarray) -> float:
        """Eq. 6 at ``params = [theta, *sigma]``."""
        self.evaluations += 1
        state = self.evaluator.evaluate(params[1:])
        z, x, _ = self._vectors(state)
        total = sum(float(t.weights @ (t.angle * t.angle)) for t in self._angles(params[0], z, x))
        return total + self.zeta * float(self.weights @ (state.cost * state.cost))

    def value_and_grad(self, params: np.ndarray) -> tuple[float, np.ndarray]:
        """Eq. 6 and its analytic gradient with respect to ``[theta, *sigma]``."""
        self.evaluations += 1
        state = self.evaluator.evaluate(params[1:], derivatives=True)
        z, x, cache = self._vectors(state)
        terms = self._angles(params[0], z, x)
        grad = np.empty(len(params))
        total, d_yaw = 0.0, 0.0
        grads = []
        for t in terms:
            total += float(t.weights @ (t.angle * t.angle))
            # d angle^2 / d a = -2 angle / sin(angle) * b  (a: transformed, b: target);
            # angle / sin(angle) -> 1 as the angle -> 0
            factor = (2.0 * t.weights) * (t.angle / np.maximum(t.sin, _TINY))
            grads.append(t.target * -factor[:, None])
            d_yaw += float(factor @ t.cross[:, 2])   # d b / d theta = e_z x b
        grad[0] = d_yaw
        self._last = (params.copy(), math.sqrt(self._squares(terms) / max(self._count, 1)))
        gz = grads[0]
        gx = grads[1] if len(grads) > 1 else None
        if cache is not None:
            assert self.ground is not None
            gz, gx = self.ground.backward(cache, state.z, gz, state.x, gx)
        cost_w = self.weights * state.cost
        total += self.zeta * float(cost_w @ state.cost)
        grad[1:] = self.evaluator.gradient(state, gz, gx, (2.0 * self.zeta) * cost_w)
        return total, grad

    # -- reading a solution ------------------------------------------------------------

    def evaluate(self, sigma: np.ndarray, yaw: float
                 ) -> tuple[float, float, float, GroundContact | None]:
        """``(cost, motion_cost, rms_angle, ground contact)`` of a solution."""
        state = self.evaluator.evaluate(sigma)
        contact = None
        if self.ground is None:
            z, x = state.z, state.x
        else:
            contact = self.ground.contact(state.z)[0]
            z, x = state.z @ contact.rotation.T, state.x @ contact.rotation.T
        terms = self._angles(yaw, z, x)
        cost = sum(float(t.weights @ (t.angle * t.angle)) for t in terms)
        cost += self.zeta * float(self.weights @ (state.cost * state.cost))
        rms = math.sqrt(self._squares(terms) / self._count) if self._count else 0.0
        return cost, float(state.cost.sum()), rms, contact

    def yaw_estimate(self, sigma: np.ndarray) -> float:
        """Eq. 8: the yaw aligning the target with the forward kinematics at ``sigma``."""
        state = self.evaluator.evaluate(sigma)
        z, x, _ = self._vectors(state)
        use_x = self._with_x
        return align_yaw(z.T, self.z_target.T, weights=self.weights,
                         x=x.T if use_x else None,
                         x_target=self.x_target.T if use_x else None,
                         gamma=self.options.gamma if use_x else 0.0).theta

    def configuration(self, sigma: np.ndarray) -> Configuration:
        """The current configuration moved by ``sigma`` (and grounded if asked for)."""
        state = self.evaluator.evaluate(np.asarray(sigma, dtype=np.float64))
        z, x, _ = self._vectors(state)
        return transformed_configuration(self.current, self.tree, z.T, x.T, self.has_x)

    # -- one local solve -----------------------------------------------------------------

    def local_solve(self, sigma0: np.ndarray, yaw0: float, deadline: float | None = None
                    ) -> tuple[np.ndarray, float, int]:
        """L-BFGS-B from ``(yaw0, sigma0)``: ``(sigma, yaw, iterations)``.

        Stops early (at the current iterate) when ``deadline`` (``time.perf_counter``)
        passes.
        """
        x0 = np.concatenate([[yaw0], np.clip(sigma0, self.lower, self.upper)])
        bounds = self.bounds if self.options.solve_yaw else [(yaw0, yaw0), *self.bounds[1:]]
        polish, tolerance = self.options.polish, self.options.tolerance
        reached: list[int] = []
        iteration = 0

        def callback(intermediate_result) -> None:  # noqa: ANN001 - scipy's protocol
            nonlocal iteration
            iteration += 1
            if deadline is not None and time.perf_counter() > deadline:
                raise StopIteration
            if polish < 0:
                return
            x = intermediate_result.x
            last = self._last
            rms = last[1] if last is not None and np.array_equal(last[0], x) \
                else self.evaluate(x[1:], float(x[0]))[2]
            if rms < tolerance:
                reached.append(iteration)
                if iteration - reached[0] >= polish:
                    raise StopIteration

        opts = {"maxiter": self.options.max_iterations, "maxcor": self.options.memory,
                "ftol": self.options.ftol, "gtol": self.options.gtol}
        with _single_threaded_blas():
            if self.options.gradient == "analytic":
                result = minimize(self.value_and_grad, x0, jac=True, method="L-BFGS-B",
                                  bounds=bounds, options=opts, callback=callback)
            else:
                result = minimize(self.value, x0, jac="2-point", method="L-BFGS-B",
                                  bounds=bounds, options=opts, callback=callback)
        yaw = float(np.arctan2(np.sin(result.x[0]), np.cos(result.x[0])))
        return np.asarray(result.x[1:], dtype=np.float64), yaw, int(result.nit)


def solve_ik(tree: KinematicTree, current: Configuration, target: Configuration,
             options: IKOptions | None = None) -> IKSolution:
    """Full-body skeletal IK (eq. 6): joint values and yaw that move ``current`` onto ``target``.

    Args:
        tree: kinematic tree over the ids of both configurations.
        current: the configuration now: the zero point of the joint space.
        target: the target configuration; its horizontal frame may differ by a yaw.
        options: weights, tolerance, time budget, restarts, seed, ground model.

    Returns:
        The best solution found; ``success`` says whether its RMS angle residual is
        under ``options.tolerance``. The solve stops at the first start that reaches
        the tolerance.
    """
    options = options or IKOptions()
    started = time.perf_counter()
    deadline = started + options.time_budget
    problem = IKProblem(tree, current, target, options)
    rng = np.random.default_rng(options.seed)
    sigma0 = (np.zeros(tree.dim) if options.initial_sigma is None
              else np.asarray(options.initial_sigma, dtype=np.float64).reshape(tree.dim))
    best: tuple[tuple[float, float, float, GroundContact | None], np.ndarray, float] | None = None
    iterations = 0
    starts = 0
    reason = "max_restarts"
    span = problem.upper - problem.lower
    finite = np.isfinite(span)
    while starts <= options.max_restarts:
        if starts == 0:
            start, yaw0 = sigma0, options.initial_yaw
        else:
            start = _sample(rng, starts, problem, best[1] if best else sigma0, span, finite)
            yaw0 = None
        if yaw0 is None:
            yaw0 = problem.yaw_estimate(start)
        sigma, yaw, nit = problem.local_solve(start, yaw0, deadline)
        iterations += nit
        starts += 1
        found = problem.evaluate(sigma, yaw)
        if best is None or _better(found, best[0], options.tolerance):
            best = (found, sigma, yaw)
        if best[0][2] < options.tolerance:
            reason = "tolerance"
            break
        if tree.dim == 0:
            reason = "no_joints"
            break
        if time.perf_counter() > deadline:
            reason = "time_budget"
            break
    assert best is not None
    (cost, motion, rms, contact), sigma, yaw = best
    return IKSolution(sigma=sigma, yaw=yaw, cost=cost, motion_cost=motion, rms_angle=rms,
                      success=rms < options.tolerance, iterations=iterations,
                      restarts=starts - 1, reason=reason,
                      elapsed=time.perf_counter() - started, ground=contact, problem=problem)


def _better(found: tuple[float, float, float, object], best: tuple[float, float, float, object],
            tolerance: float) -> bool:
    """Solved beats unsolved; then the lower eq. 6 cost wins."""
    return (found[2] < tolerance, -found[0]) > (best[2] < tolerance, -best[0])


def _sample(rng: np.random.Generator, attempt: int, problem: IKProblem, best: np.ndarray,
            span: np.ndarray, finite: np.ndarray) -> np.ndarray:
    """A new start: odd attempts perturb the best so far, even ones sample the bounds."""
    scale = problem.options.sample_scale
    lo = np.where(finite, problem.lower, -np.pi)
    hi = np.where(finite, problem.upper, np.pi)
    if attempt % 2:
        spread = scale * 0.25 * np.where(finite, span, 2 * np.pi)
        return np.clip(best + rng.normal(size=best.shape) * spread, lo, hi)
    mid = 0.5 * (lo + hi)
    return mid + scale * (rng.random(best.shape) - 0.5) * (hi - lo)
