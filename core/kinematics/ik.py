"""Full-body skeletal inverse kinematics (FreeSN paper, section 3.4, eqs. 6-8).

Given the current configuration (the zero point of the joint space) and a target
skeletal configuration with the same ids, possibly measured in another horizontal
frame, :func:`solve_ik` finds the yaw ``theta`` and joint values ``sigma`` that
minimise eq. 6:

    sum_j w_j [ zeta C_j^2 + gamma angle(x_j^rot, Rz(theta) x_j^target)^2
                + angle(z_j^rot, Rz(theta) z_j^target)^2 ]

with ``Z^rot, X^rot, C`` from the skeletal forward kinematics (eq. 7, Alg. 1).

Mink style: eq. 6 is a sum of :class:`IKTerm` objects, each defining its value and
its gradient with respect to the pose (yaw, vectors, costs) once --
:class:`VectorAngleTerm` for the ``z`` and ``x`` angles, :class:`MotionCostTerm` for
``zeta C^2``. :class:`IKProblem` assembles them (:meth:`IKProblem.objective`) and
pulls the summed gradient back to ``sigma`` through the ground model and the tree.
The function :func:`solve_ik` is the solver:

1. the yaw is initialised by eq. 8 (:func:`msrr.core.alignment.align_yaw`);
2. L-BFGS-B minimises over ``(theta, sigma)`` with the analytic gradient
   (:meth:`IKProblem.value_and_grad`, reverse mode through the tree);
3. while the residual RMS angle is above the tolerance, new starts are sampled
   (BioIK-like: alternately around the best solution so far and uniformly in the
   joint bounds), each with its own eq. 8 yaw, until a solution is under the
   tolerance or ``max_restarts`` starts are used up (an optional time budget can
   only cut this short, and the solution then says so).

A floating base can be put on the ground after the forward kinematics with the
three-point contact model (``IKOptions.ground``, :mod:`.ground`).
"""

from __future__ import annotations

import math
import time
from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, Literal

import numpy as np
from scipy.optimize import minimize
from threadpoolctl import ThreadpoolController

from ..alignment import align_yaw
from ..configuration import Configuration
from ..errors import ConfigurationError
from .fk import Evaluator, FKState, transformed_configuration, tree_vectors
from .ground import GroundContact, GroundModel, ground_op
from .rotations import cross
from .tree import KinematicTree

__all__ = [
    "IKOptions",
    "IKPose",
    "IKProblem",
    "IKSolution",
    "IKTerm",
    "MotionCostTerm",
    "Objective",
    "StopReason",
    "TermValue",
    "VectorAngleTerm",
    "module_weights",
    "solve_ik",
]

_TINY = 1e-12

StopReason = Literal["tolerance", "max_restarts", "no_joints", "time_budget"]
"""Why :func:`solve_ik` stopped (see :attr:`IKSolution.reason`)."""
_THREADPOOLS: ThreadpoolController | None = None
_RECENT = 4   # FK evaluations an IKProblem keeps (IKProblem._forward)


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
        time_budget: optional wall-clock limit of one solve [s]. It can only stop the
            search early: the best solution so far is returned with ``reason
            "time_budget"``. ``None`` (the default): the solve is bounded by
            ``max_restarts`` and ``max_iterations`` alone, so its answer does not
            depend on the machine or its load.
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

    time_budget: float | None = None
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
        if (self.time_budget is not None and not self.time_budget > 0) or not self.tolerance > 0:
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
        reason: why the search stopped: ``"tolerance"`` (solved), ``"max_restarts"``
            (every start used), ``"no_joints"`` (a tree without joints: only the yaw
            was solved) or ``"time_budget"`` (``options.time_budget`` ran out first:
            the search was cut short, more starts might have found a better answer).
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
    reason: StopReason
    elapsed: float
    ground: GroundContact | None = None
    problem: IKProblem | None = field(default=None, repr=False, compare=False)

    @cached_property
    def configuration(self) -> Configuration:
        """The current configuration moved by the solution (FK, grounded if asked for)."""
        if self.problem is None:
            raise ConfigurationError("this IKSolution carries no problem to rebuild from")
        return self.problem.configuration(self.sigma)


@dataclass(slots=True)
class IKPose:
    """What the objective's terms see at one evaluation.

    Attributes:
        yaw: ``theta`` [rad].
        rz: ``Rz(theta)^T``, shape (3, 3): ``rows @ rz`` turns row vectors by ``theta``.
        z: transformed connection vectors ``Z^rot`` (grounded if asked for), rows (n, 3).
        x: transformed forward vectors ``X^rot``, rows (n, 3).
        cost: motion cost per module ``C``, shape (n,).
    """

    yaw: float
    rz: np.ndarray
    z: np.ndarray
    x: np.ndarray
    cost: np.ndarray


@dataclass(slots=True)
class TermValue:
    """One term's value at a pose and, when asked for, its gradient.

    Attributes:
        value: the term's contribution to eq. 6.
        residual: angles [rad] this term adds to the RMS residual, or ``None``.
        z, x: ``d value / d pose.z`` and ``d value / d pose.x`` (rows (n, 3)), or
            ``None`` when the term does not depend on them.
        cost: ``d value / d pose.cost`` (n,), or ``None``.
        yaw: ``d value / d pose.yaw``.
    """

    value: float
    residual: np.ndarray | None = None
    z: np.ndarray | None = None
    x: np.ndarray | None = None
    cost: np.ndarray | None = None
    yaw: float = 0.0


class IKTerm(ABC):
    """One term of the IK objective (mink style: the solver sums the terms).

    A term computes its value and, if ``derivatives``, its gradient with respect to
    the pose (:class:`IKPose`); :class:`IKProblem` adds the terms up and pulls the
    summed gradient back through the ground model and the tree to ``sigma``. Adding
    a term to eq. 6 is a subclass and one line in :meth:`IKProblem.default_terms`.
    """

    name: str = ""

    @abstractmethod
    def evaluate(self, pose: IKPose, derivatives: bool = False) -> TermValue:
        """The term's value at ``pose``; with ``derivatives`` also its pose gradient."""


class VectorAngleTerm(IKTerm):
    """``sum_j w_j angle(a_j, Rz(theta) b_j)^2`` over the ``z`` or ``x`` vectors (eq. 6).

    With ``s = |a x b|`` and ``angle = atan2(s, a . b)``:
    ``d angle^2 / d a = -2 angle / s * b`` (the part along ``a`` cancels on the unit
    sphere; ``angle / s -> 1`` as the angle -> 0) and, since ``d b / d theta =
    e_z x b``, ``d angle^2 / d theta = 2 angle / s * (a x b)_z``.

    Args:
        vector: ``"z"`` (connection vectors) or ``"x"`` (forward vectors).
        target: target vectors ``b`` before the yaw, rows (n, 3).
        weights: ``w_j`` (times ``gamma`` for ``x``), shape (n,).
        counted: which angles enter the RMS residual, shape (n,); all by default.
    """

    def __init__(self, vector: Literal["z", "x"], target: np.ndarray, weights: np.ndarray,
                 counted: np.ndarray | None = None):
        self.name = f"{vector}_angle"
        self.vector = vector
        self.target = target
        self.weights = weights
        self.counted = None if counted is None or counted.all() else counted

    def evaluate(self, pose: IKPose, derivatives: bool = False) -> TermValue:
        a = pose.z if self.vector == "z" else pose.x
        b = self.target @ pose.rz
        axb = cross(a, b)
        sin = np.sqrt(np.einsum("ni,ni->n", axb, axb))
        angle = np.arctan2(sin, np.einsum("ni,ni->n", a, b))
        out = TermValue(float(self.weights @ (angle * angle)),
                        angle if self.counted is None else angle[self.counted])
        if derivatives:
            factor = (2.0 * self.weights) * (angle / np.maximum(sin, _TINY))
            grad = b * -factor[:, None]
            if self.vector == "z":
                out.z = grad
            else:
                out.x = grad
            out.yaw = float(factor @ axb[:, 2])
        return out


class MotionCostTerm(IKTerm):
    """``zeta sum_j w_j C_j^2``: the motion-cost term of eq. 6.

    Args:
        weights: ``zeta w_j``, shape (n,).
    """

    name = "motion_cost"

    def __init__(self, weights: np.ndarray):
        self.weights = weights

    def evaluate(self, pose: IKPose, derivatives: bool = False) -> TermValue:
        weighted = self.weights * pose.cost
        out = TermValue(float(weighted @ pose.cost))
        if derivatives:
            out.cost = 2.0 * weighted
        return out


@dataclass
class Objective:
    """Eq. 6 at one point: the total, each term's value, the residual and the gradient.

    Attributes:
        value: the sum of the terms.
        terms: each term's value by name.
        rms_angle: RMS of the terms' residual angles [rad].
        motion_cost: ``sum_j C_j`` [rad].
        grad: gradient with respect to ``[theta, *sigma]`` when asked for, else ``None``.
        ground: the ground contact when the ground model is on.
    """

    value: float
    terms: dict[str, float]
    rms_angle: float
    motion_cost: float
    grad: np.ndarray | None = None
    ground: GroundContact | None = None


class IKProblem:
    """Eq. 6 for one tree, current configuration and target: the terms, their sum and
    its gradient.

    Args:
        tree: the kinematic tree.
        current: the configuration now (``Z^init``, ``X^init``), the tree's ids.
        target: the target configuration, same ids, any horizontal frame.
        options: weights ``w``, ``gamma``, ``zeta`` and the ground model.

    Attributes:
        terms: the :class:`IKTerm` objects whose sum is the objective.
    """

    def __init__(self, tree: KinematicTree, current: Configuration, target: Configuration,
                 options: IKOptions = IKOptions()):
        self.tree = tree
        self.current = current
        self.options = options
        z0, x0, self.has_x = tree_vectors(tree, current)
        zt, xt, has_xt = tree_vectors(tree, target)
        self.evaluator = Evaluator(tree, z0, x0)
        self.n = len(tree.edges)
        self.z_target = np.ascontiguousarray(zt.T)
        self.x_target = np.ascontiguousarray(xt.T)
        self.weights = self._weights(options.weights)
        self.use_x = self.has_x & has_xt if options.gamma > 0 else np.zeros(self.n, dtype=bool)
        self.ground = None if options.ground is None else ground_op(tree, options.ground)
        lo, hi = tree.bounds
        self.lower, self.upper = lo, hi
        self.bounds = [(None, None)] + [(float(a), float(b)) for a, b in zip(lo, hi, strict=True)]
        self.terms: list[IKTerm] = self.default_terms()
        self.evaluations = 0
        self._last: tuple[np.ndarray, float] | None = None
        self._recent: dict[bytes, tuple] = {}

    def default_terms(self) -> list[IKTerm]:
        """The terms of eq. 6: ``z`` angles, ``x`` angles (``gamma > 0`` and both sides
        have ``x``), motion costs (``zeta > 0``)."""
        options = self.options
        terms: list[IKTerm] = [VectorAngleTerm("z", self.z_target, self.weights)]
        if self.use_x.any():
            terms.append(VectorAngleTerm("x", self.x_target,
                                         options.gamma * self.weights * self.use_x, self.use_x))
        if options.zeta > 0:
            terms.append(MotionCostTerm(options.zeta * self.weights))
        return terms

    def _weights(self, weights: Mapping[str, float] | Sequence[float] | np.ndarray | None
                 ) -> np.ndarray:
        return module_weights(self.tree, weights)

    # -- the objective ---------------------------------------------------------------------

    def objective(self, params: np.ndarray, derivatives: bool = False) -> Objective:
        """Eq. 6 at ``params = [theta, *sigma]``: the terms' sum, and its gradient if
        ``derivatives`` (reverse mode: terms -> ground model -> tree)."""
        params = np.asarray(params, dtype=np.float64)
        yaw = float(params[0])
        state, z, x, contact, cache = self._forward(params[1:], derivatives)
        c, s = math.cos(yaw), math.sin(yaw)
        rz = np.array(((c, s, 0.0), (-s, c, 0.0), (0.0, 0.0, 1.0)))
        pose = IKPose(yaw, rz, z, x, state.cost)
        total = squares = d_yaw = 0.0
        count = 0
        values: dict[str, float] = {}
        gz = gx = gc = None
        for term in self.terms:
            part = term.evaluate(pose, derivatives)
            total += part.value
            values[term.name] = part.value
            if part.residual is not None:
                squares += float(part.residual @ part.residual)
                count += len(part.residual)
            if derivatives:
                d_yaw += part.yaw
                gz = _add(gz, part.z)
                gx = _add(gx, part.x)
                gc = _add(gc, part.cost)
        out = Objective(total, values, math.sqrt(squares / count) if count else 0.0,
                        float(state.cost.sum()), ground=contact)
        if derivatives:
            gz = np.zeros_like(z) if gz is None else gz
            if cache is not None:
                assert self.ground is not None
                gz, gx = self.ground.backward(cache, state.z, gz, state.x, gx)
            grad = np.empty(len(params))
            grad[0] = d_yaw
            grad[1:] = self.evaluator.gradient(state, gz, gx, gc)
            out.grad = grad
        return out

    def _forward(self, sigma: np.ndarray, derivatives: bool = False
                 ) -> tuple[FKState, np.ndarray, np.ndarray, GroundContact | None, Any]:
        """The FK at ``sigma`` and its vectors (rows), put on the ground if the ground
        model is on, with the contact and what :meth:`GroundOp.backward` needs.

        The last evaluations with derivatives are kept by ``sigma``'s bytes: the point
        L-BFGS-B returns is one of them, and :meth:`evaluate` and :meth:`configuration`
        read it again (a value only depends on ``sigma``, so it is the same to the bit).
        """
        key = sigma.tobytes()
        kept = self._recent.get(key)
        if kept is not None:
            return kept
        state = self.evaluator.evaluate(sigma, derivatives)
        if self.ground is None:
            out = (state, state.z, state.x, None, None)
        else:
            contact, cache = self.ground.contact(state.z)
            out = (state, state.z @ contact.rotation.T, state.x @ contact.rotation.T, contact,
                   cache)
        if derivatives and _RECENT:
            if len(self._recent) >= _RECENT:
                del self._recent[next(iter(self._recent))]
            self._recent[key] = out
        return out

    def value(self, params: np.ndarray) -> float:
        """Eq. 6 at ``params = [theta, *sigma]``."""
        self.evaluations += 1
        return self.objective(params).value

    def value_and_grad(self, params: np.ndarray) -> tuple[float, np.ndarray]:
        """Eq. 6 and its analytic gradient with respect to ``[theta, *sigma]``."""
        self.evaluations += 1
        out = self.objective(params, derivatives=True)
        assert out.grad is not None
        self._last = (params.copy(), out.rms_angle)
        return out.value, out.grad

    # -- reading a solution ------------------------------------------------------------

    def evaluate(self, sigma: np.ndarray, yaw: float
                 ) -> tuple[float, float, float, GroundContact | None]:
        """``(cost, motion_cost, rms_angle, ground contact)`` of a solution."""
        out = self.objective(np.concatenate([[yaw], sigma]))
        return out.value, out.motion_cost, out.rms_angle, out.ground

    def yaw_estimate(self, sigma: np.ndarray) -> float:
        """Eq. 8: the yaw aligning the target with the forward kinematics at ``sigma``."""
        _, z, x, _, _ = self._forward(np.asarray(sigma, dtype=np.float64))
        use_x = bool(self.use_x.any())
        return align_yaw(z.T, self.z_target.T, weights=self.weights,
                         x=x.T if use_x else None,
                         x_target=self.x_target.T if use_x else None,
                         gamma=self.options.gamma if use_x else 0.0).theta

    def configuration(self, sigma: np.ndarray) -> Configuration:
        """The current configuration moved by ``sigma`` (and grounded if asked for)."""
        _, z, x, _, _ = self._forward(np.asarray(sigma, dtype=np.float64))
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
        # every variable fixed by its bounds (no joints, the yaw held): scipy returns at
        # once, with no iteration count
        return np.asarray(result.x[1:], dtype=np.float64), yaw, int(result.get("nit", 0))


def module_weights(tree: KinematicTree,
                   weights: Mapping[str, float] | Sequence[float] | np.ndarray | None
                   ) -> np.ndarray:
    """Eq. 6's ``w`` in tree layout from :attr:`IKOptions.weights`, shape (n,).

    Raises:
        ConfigurationError: a module that is not in the tree, or an array of another shape.
    """
    n = len(tree.edges)
    if weights is None:
        return np.ones(n)
    if isinstance(weights, Mapping):
        unknown = sorted(set(weights) - set(tree.edges))
        if unknown:
            raise ConfigurationError(f"IK weights for unknown modules {', '.join(unknown)}")
        return np.array([float(weights.get(e, 1.0)) for e in tree.edges])
    w = np.asarray(weights, dtype=np.float64)
    if w.shape != (n,):
        raise ConfigurationError(f"IK weights must have shape ({n},), got {w.shape}")
    return w


def solve_ik(tree: KinematicTree, current: Configuration, target: Configuration,
             options: IKOptions | None = None) -> IKSolution:
    """Full-body skeletal IK (eq. 6): joint values and yaw that move ``current`` onto ``target``.

    Args:
        tree: kinematic tree over the ids of both configurations.
        current: the configuration now: the zero point of the joint space.
        target: the target configuration; its horizontal frame may differ by a yaw.
        options: weights, tolerance, restarts, seed, ground model, optional time budget.

    Returns:
        The best solution found; ``success`` says whether its RMS angle residual is
        under ``options.tolerance`` and ``reason`` why the search stopped. The solve
        stops at the first start that reaches the tolerance; without a time budget
        the result depends only on the inputs and ``options`` (deterministic).

    Raises:
        ConfigurationError: ``options.initial_sigma`` or ``options.initial_yaw`` is not
            finite (a NaN start would be "solved" as NaN).
    """
    options = options or IKOptions()
    if options.initial_sigma is not None and not np.isfinite(
            np.asarray(options.initial_sigma, dtype=np.float64)).all():
        raise ConfigurationError("the IK start initial_sigma has non-finite values",
                                 field="initial_sigma")
    if options.initial_yaw is not None and not math.isfinite(options.initial_yaw):
        raise ConfigurationError(f"the IK start initial_yaw is {options.initial_yaw}",
                                 field="initial_yaw")
    started = time.perf_counter()
    deadline = None if options.time_budget is None else started + options.time_budget
    problem = IKProblem(tree, current, target, options)
    rng = np.random.default_rng(options.seed)
    sigma0 = (np.zeros(tree.dim) if options.initial_sigma is None
              else np.asarray(options.initial_sigma, dtype=np.float64).reshape(tree.dim))
    best: tuple[tuple[float, float, float, GroundContact | None], np.ndarray, float] | None = None
    iterations = 0
    starts = 0
    reason: StopReason = "max_restarts"
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
        if deadline is not None and time.perf_counter() > deadline:
            reason = "time_budget"
            break
    assert best is not None
    (cost, motion, rms, contact), sigma, yaw = best
    return IKSolution(sigma=sigma, yaw=yaw, cost=cost, motion_cost=motion, rms_angle=rms,
                      success=rms < options.tolerance, iterations=iterations,
                      restarts=starts - 1, reason=reason,
                      elapsed=time.perf_counter() - started, ground=contact, problem=problem)


def _add(total: np.ndarray | None, part: np.ndarray | None) -> np.ndarray | None:
    """``total + part``, where ``None`` stands for zero."""
    if part is None:
        return total
    return part if total is None else total + part


def _better(found: tuple[float, float, float, object], best: tuple[float, float, float, object],
            tolerance: float) -> bool:
    """Solved beats unsolved; a finite answer beats a non-finite one; then the lower eq. 6
    cost wins."""
    def rank(result: tuple[float, float, float, object]) -> tuple[bool, bool, float]:
        finite = math.isfinite(result[0]) and math.isfinite(result[2])
        return (finite and result[2] < tolerance, finite, -result[0] if finite else 0.0)

    return rank(found) > rank(best)


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
