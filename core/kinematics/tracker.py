"""Iterative inverse kinematics for the executor (FreeSN paper, section 3.4, last part).

In a moving action the IK runs every control tick while the robot moves, so an
optimal solution is not needed at each tick. :class:`IKTracker` follows the paper:

* the first :meth:`~IKTracker.step` is the initial phase: :func:`~.ik.solve_ik` with
  sampled restarts until a solution under the tolerance is found (or they run out);
* later steps *track*: one L-BFGS-B run warm-started from the previous ``sigma``,
  within ``tick_budget``, with the yaw *held* at :func:`held_yaw` (see below);
* meanwhile an *exploration* thread keeps optimising starts sampled globally from the
  joint space on the latest configuration; when one of its solutions is better than
  the tracked one (compared on the current configuration), the next tracking step
  starts from it instead.

Why the yaw is held: turning every joint about the vertical while the yaw ``theta``
turns the target with it leaves eq. 6's angle terms unchanged wherever the root holds
no strut (or only a steep one): only the small motion cost (eqs. 3-5, ``zeta``) opposes
it, and a step stopped at the tolerance never resolves that. The warm start is the
last ``sigma``, relative to last tick's configuration (eq. 7's ``Z^init``), so it repeats
the part of the last motion the robot has already carried out; along stiff directions
eq. 6 takes it back, along that free one nothing did, and a frame that turned between
ticks (a root node's shell spinning) was split between ``theta`` and the joints. The
turn was repeated tick after tick and the robot carried it out (the S4N5 squirm's
heading, issue 31). With ``theta`` held where the edges no joint moves put it (the
root's own, eq. 7, and any a joint only turns about itself: :func:`pinned_edges`), or,
where they do not pin it, where the target best aligns with the
configuration now (eq. 8: no net turn), the free direction is no longer free: the step
takes the repeated turn back like any other error, and every turn it commands is one
the goal asks for. The last ``sigma`` stays the start: started at ``sigma = 0`` instead
(nothing repeated), the FreeSN S12N6 crawl's stances were no longer reached at their
first tick and a foot's connection broke (docs/freesn.md, "The tracking step and the
free yaw").

The tracker holds state; the solver functions it calls stay pure.
"""

from __future__ import annotations

import threading
import time
from dataclasses import replace

import numpy as np

from ..alignment import align_yaw, median_yaw
from ..configuration import Configuration
from .fk import Evaluator, _layout, tree_vectors
from .ik import IKOptions, IKProblem, IKSolution, module_weights, solve_ik
from .tree import KinematicTree

__all__ = ["IKTracker", "held_yaw", "pinned_edges"]

PINNED_WEIGHT = 1e3
"""Weight of the pinned edges (:func:`pinned_edges`) in :func:`held_yaw` against 1 for
the others."""


def pinned_edges(tree: KinematicTree, current: Configuration) -> tuple[str, ...]:
    """The edges whose vectors no joint of ``tree`` moves in the root's frame: the root's
    own (eq. 7) and those of a joint that turns only what hangs beyond its edge (a
    revolute joint about its own strut; a SnailBot crawling on a substrate the tree
    reaches through it), each found unmoved by the forward kinematics (Alg. 1) from
    ``current`` at two sampled ``sigma`` (fixed seed, within the joint bounds)."""
    z0, x0, _ = tree_vectors(tree, current)
    if not tree.dim:
        return tuple(tree.edges)
    evaluator = Evaluator(tree, z0, x0)
    lo, hi = tree.bounds
    rng = np.random.default_rng(0)
    still = np.ones(len(tree.edges), dtype=bool)
    for _ in range(2):
        sigma = np.clip(rng.uniform(-0.5, 0.5, tree.dim), lo, hi)
        still &= np.linalg.norm(evaluator.evaluate(sigma).z - z0.T, axis=1) < 1e-9
    return tuple(e for e, s in zip(tree.edges, still, strict=True) if s)


def held_yaw(tree: KinematicTree, current: Configuration, target: Configuration,
             options: IKOptions, near: float, pinned: tuple[str, ...] | None = None, *,
             median: bool = False) -> float:
    """The yaw [rad] a tracking step holds: eq. 8 between ``target`` and ``current`` (the
    zero point of the joint space), the pinned edges (``pinned``, default
    :func:`pinned_edges`) weighted :data:`PINNED_WEIGHT` times the rest, the local
    minimum nearest ``near`` (the last step's yaw); with ``median``, the weighted median
    of the edges' turns instead (:func:`~msrr.core.alignment.median_yaw`, eq. 8 where no
    edge has a horizontal part).

    Eq. 8 is solved again on every tick's configuration, so a part that lags its goal
    (a chain still to be swung over the floor) pulls the least-squares yaw toward it on
    every tick, and the parts already in place are told to turn by that pull every tick:
    a turn that never ends (FreeBOT ``chains-to-tree``'s final move: a chain 9 deg short
    of its goal held the yaw 3.5 deg off the rest, and the tree turned -85 deg in 2 s until
    F3-F4 broke). The median stays with the parts in place; robots that ask for it
    (:attr:`~msrr.core.robot.RobotDefaults.median_yaw`) hold it.

    No joint moves a pinned edge, so where their horizontal parts pin the yaw any
    solution under the tolerance has theirs; where they do not (no edge, or vertical
    ones) the yaw is gauge freedom and the others choose it: the target turned onto the
    configuration as it is, so the step commands no net turn about the vertical.
    Weighting the root's edges alone missed a pinned edge the root does not hold: the
    step could then not reach the target, and its residual all fell on that edge
    (SnailBot pieces-to-tree's final move under noise: B6 crawls on B7 and roots the
    tree, the held yaw put B6-B7 up to 18 deg off, the rows were swung about it and
    B6-B7 broke; docs/snailbot.md).
    """
    pinned = pinned_edges(tree, current) if pinned is None else pinned
    z, _, _ = tree_vectors(tree, current)
    z_target, _, _ = tree_vectors(tree, target)
    weights = module_weights(tree, options.weights)
    weights = weights * np.where(np.isin(tree.edges, pinned), PINNED_WEIGHT, 1.0)
    robust = median_yaw(z, z_target, weights=weights, near=near) if median else None
    if robust is not None:
        return robust
    return align_yaw(z, z_target, weights=weights, near=near).theta


class IKTracker:
    """Tracking IK with a background exploration worker.

    Args:
        tree: kinematic tree of the moving configuration.
        target: the target configuration (same ids; its yaw is solved).
        options: solver options; ``time_budget`` (if set) cuts the initial phase and
            each exploration run short, ``seed`` seeds both the solver and the explorer.
        tick_budget: time limit of one tracking step [s] (a control tick cannot wait;
            a step cut short says so in its ``reason``); ``None``: bounded by
            ``options.max_iterations`` only.
        explore: run the exploration thread (``False``: deterministic tracking only).
        explore_pause: pause between two exploration runs [s], to leave the cores to
            the control loop.
        median_yaw: hold the tracking steps' yaw at the edges' median turn, not eq. 8's
            (:func:`held_yaw`).

    Use as a context manager, or call :meth:`close`, to stop the exploration thread.
    """

    def __init__(self, tree: KinematicTree, target: Configuration,
                 options: IKOptions | None = None, *, tick_budget: float | None = 0.05,
                 explore: bool = True, explore_pause: float = 0.0, median_yaw: bool = False):
        self.tree = tree
        self.median_yaw = median_yaw
        self.options = options or IKOptions()
        self.tick_budget = tick_budget
        self.explore = explore and tree.dim > 0
        self.explore_pause = explore_pause
        self.last: IKSolution | None = None
        self.handovers = 0
        self._pinned: tuple[str, ...] | None = None
        self._target = target
        self._lock = threading.Lock()
        self._snapshot: tuple[Configuration, Configuration] | None = None
        self._offer: tuple[np.ndarray, float] | None = None
        self._offer_cost = np.inf
        self._stop = threading.Event()
        self._wake = threading.Event()
        self._thread: threading.Thread | None = None
        seed = None if self.options.seed is None else self.options.seed + 1
        self._rng = np.random.default_rng(seed)
        _layout(tree)  # built once here, shared read-only by both threads

    # -- the control loop's side --------------------------------------------------------

    @property
    def target(self) -> Configuration:
        return self._target

    @property
    def offer(self) -> tuple[np.ndarray, float] | None:
        """The exploration's pending ``(sigma, yaw)`` for the next step, if any."""
        with self._lock:
            return self._offer

    def set_target(self, target: Configuration) -> None:
        """Track a new target; the warm start is kept, the exploration offer dropped."""
        with self._lock:
            self._target = target
            self._offer, self._offer_cost = None, np.inf

    def step(self, current: Configuration) -> IKSolution:
        """Solve for this tick: joint values that move ``current`` onto the target."""
        target = self._target
        if self.last is None:
            solution = solve_ik(self.tree, current, target, self.options)
        else:
            solution = self._track(current, target)
        self.last = solution
        with self._lock:
            self._snapshot = (current, target)
        if self.explore:
            self._ensure_explorer()
            self._wake.set()
        return solution

    def _track(self, current: Configuration, target: Configuration) -> IKSolution:
        """One L-BFGS-B run from the last ``sigma`` with the yaw held at :func:`held_yaw`
        (module docstring), or from the exploration's offer when it beats the last
        solution."""
        assert self.last is not None
        options = replace(self.options, time_budget=self.tick_budget, max_restarts=0)
        sigma, yaw = self.last.sigma, self.last.yaw
        with self._lock:
            offer, self._offer, self._offer_cost = self._offer, None, np.inf
        if offer is not None:   # compare on this tick's configuration: the better start wins
            problem = IKProblem(self.tree, current, target, options)
            if problem.evaluate(*offer)[0] < problem.evaluate(sigma, yaw)[0]:
                self.handovers += 1
                return solve_ik(self.tree, current, target,
                                replace(options, initial_sigma=offer[0], initial_yaw=offer[1]))
        if self._pinned is None:   # structural: found once for the tree
            self._pinned = pinned_edges(self.tree, current)
        yaw = held_yaw(self.tree, current, target, options, near=yaw, pinned=self._pinned,
                       median=self.median_yaw)
        return solve_ik(self.tree, current, target,
                        replace(options, initial_sigma=sigma, initial_yaw=yaw, solve_yaw=False))

    # -- exploration --------------------------------------------------------------------

    def _ensure_explorer(self) -> None:
        if self._thread is None or not self._thread.is_alive():
            self._stop.clear()
            self._thread = threading.Thread(target=self._explore, name="msrr-ik-explore",
                                            daemon=True)
            self._thread.start()

    def _explore(self) -> None:
        while not self._stop.is_set():
            if not self.explore_once():
                self._wake.wait(0.1)
                self._wake.clear()
                continue
            if self.explore_pause:
                self._stop.wait(self.explore_pause)

    def explore_once(self) -> bool:
        """One exploration run (what the thread repeats): a start sampled from the joint
        bounds, optimised on the latest configuration; offered to the next tracking step
        if it beats the tracked solution and any earlier offer. ``False`` before the
        first :meth:`step`."""
        with self._lock:
            snapshot = self._snapshot
        if snapshot is None:
            return False
        current, target = snapshot
        problem = IKProblem(self.tree, current, target, self.options)
        lo, hi = self.tree.bounds
        lo = np.where(np.isfinite(lo), lo, -np.pi)
        hi = np.where(np.isfinite(hi), hi, np.pi)
        scale = self.options.sample_scale
        start = 0.5 * (lo + hi) + scale * (self._rng.random(self.tree.dim) - 0.5) * (hi - lo)
        budget = self.options.time_budget
        deadline = None if budget is None else time.perf_counter() + budget
        sigma, yaw, _ = problem.local_solve(start, problem.yaw_estimate(start), deadline)
        cost = problem.evaluate(sigma, yaw)[0]
        last = self.last
        reference = problem.evaluate(last.sigma, last.yaw)[0] if last is not None else np.inf
        with self._lock:
            if self._snapshot is snapshot and cost < min(reference, self._offer_cost):
                self._offer, self._offer_cost = (sigma, yaw), cost
        return True

    def close(self) -> None:
        """Stop the exploration thread (waits for its current run to end)."""
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None

    def __enter__(self) -> IKTracker:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:  # pragma: no cover - best effort at interpreter exit
        self._stop.set()
