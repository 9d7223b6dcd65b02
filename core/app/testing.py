"""Test helpers for robot plugins, and the conformance suite every robot passes.

In the spirit of dm_control's one suite over every task: :func:`check_robot` asserts,
for one installed robot, what the platform promises of every robot. A plugin's own
tests run it with one line::

    from msrr.core.app.testing import check_robot

    def test_conformance():
        check_robot("hinge")

and the platform's suite runs it over every installed robot (``@robot_parameters()``).

**Shipped configurations** (the contract): the start and goal files of the robot's
scenarios (``msrr_scenarios``) and every ``*.json`` of robot ``name`` in the ``configs``
folder beside the module that describes it (the plugin module whose ``msrr_robot``
answers ``name``). A robot ships at least one.

**The checks**, each over every shipped configuration (``check_robot`` collects every
failure and raises one :class:`ConformanceError` listing them):

1. it loads and validates against the robot (structure and docking rules) and
   round-trips through JSON unchanged;
2. it matches itself with zero cost (:func:`msrr.core.matching.match`);
3. every planner of the robot plans it to itself with zero actions;
4. the default planner plans between configurations with the same module counts (each
   to the next of its counts, in a ring; every pair with ``all_pairs=True``) -- or says
   it cannot with a :class:`~msrr.core.errors.PlanningError` -- and the plan replays:
   each action's changes cover the topology change it makes, and the last target is
   the plan's goal;
5. in the kinematic driver (:mod:`msrr.core.generic`; robots with a physical simulator
   too), each configuration runs to itself and every plan of check 4 runs to success
   with the generic recognizer and controller (plans that move the ends of connections
   that are modules, FreeSN struts, and plans that need joints -- a dock within one
   connected group, a goal that differs in shape only -- are skipped and listed: the
   kinematic driver does not dock the first and has no joints);
6. a robot whose module kinds declare bodies (:class:`~msrr.core.robot.Body`) runs one
   plan of check 4 in the generic ``mujoco`` driver (:func:`run_physics`), judged on the
   simulator's ground truth (topology and shape): the first that needs joints, else the
   first with the fewest actions.
"""

from __future__ import annotations

import inspect
import json
import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import networkx as nx
import numpy as np

from .. import plugins
from ..actions import topology_diff
from ..bodies import has_bodies
from ..capabilities import Capabilities, Planner
from ..configuration import Configuration
from ..driver import ModuleCommand
from ..errors import MsrrError, PlanningError
from ..events import Run, RunResult
from ..executor import Executor, ExecutorOptions
from ..generic import KinematicDriver, LatchController, LatchRecognizer
from ..io import check_configuration, dump_configuration, parse_configuration
from ..kinematics import Evaluator, KinematicNode, KinematicTree, tree_vectors
from ..matching import Candidate, match
from ..plan import ActionType, Plan
from ..robot import Robot, RobotSpec

__all__ = [
    "ConformanceError",
    "ConformanceReport",
    "FakeDriver",
    "check_robot",
    "node_jacobian_errors",
    "replay_problems",
    "robot_parameters",
    "run_kinematic",
    "run_physics",
    "shipped_configurations",
    "tree_gradient_error",
]


CHECK_SPEED = 1.0
"""Module speed [m/s] of the conformance runs (twice the kinematic driver's default:
the checks are about topology, not timing)."""

CHECK_TURN_RATE = 4.0
"""Turn rate [rad/s] of the conformance runs."""


class ConformanceError(AssertionError):
    """A robot broke the platform's contract; the message lists every failed check."""


class FakeDriver(KinematicDriver):
    """The kinematic driver that records what it is told, for tests of controllers,
    recognizers and listeners.

    Args:
        spec: the robot's description.
        jammed: ``(module, port)`` pairs whose connector never latches (a failed dock).
        **options: as for :class:`~msrr.core.generic.driver.KinematicDriver`.

    Attributes:
        sent: every ``send_action`` argument, in order.
    """

    name = "fake"
    description = "kinematic world that records commands and can jam connectors"

    def __init__(self, spec: RobotSpec, *, jammed: Iterable[tuple[str, str]] = (), **options: Any):
        super().__init__(spec, **options)
        self.jammed = set(jammed)
        self.sent: list[dict[str, ModuleCommand]] = []

    def send_action(self, commands: Any) -> None:
        self.sent.append(dict(commands))
        super().send_action(commands)
        self.armed -= self.jammed


def run_kinematic(plan: Plan, spec: RobotSpec, *, rate: float = 10.0,
                  action_timeout: float = 60.0, driver: KinematicDriver | None = None
                  ) -> RunResult:
    """Execute ``plan`` in the kinematic driver with the generic recognizer and controller.

    No files are written and no recording is made; run events still go to every
    listener plugin. ``driver`` (say a :class:`FakeDriver`) replaces the default one.
    """
    run = Run(robot=spec.name, scenario="conformance", plan=plan, spec=spec,
              driver="kinematic", rate=rate)
    with driver or KinematicDriver(spec) as world:
        world.reset(plan.start)
        executor = Executor(run, world, LatchRecognizer(spec), LatchController(spec),
                            ExecutorOptions(rate=rate, action_timeout=action_timeout),
                            sink=plugins.emit)
        return executor.execute()


def run_physics(plan: Plan, spec: RobotSpec, *, rate: float = 10.0,
                action_timeout: float = 60.0, seed: int = 0) -> RunResult:
    """Execute ``plan`` in the generic ``mujoco`` driver with the generic recognizer and
    the drive controller, and judge it as ``platform run`` does: on the simulator's ground
    truth, topology and shape (the goal laid out by a second driver)."""
    from ..generic.drive import DriveController
    from ..generic.physics import PhysicsDriver
    from ..judge import Judge

    def layout(goal: Configuration) -> dict:
        with PhysicsDriver(spec, seed=seed) as other:
            other.reset(goal)
            return dict(other.witness().poses)

    run = Run(robot=spec.name, scenario="conformance", plan=plan, spec=spec,
              driver="mujoco", rate=rate, seed=seed)
    with PhysicsDriver(spec, seed=seed) as world:
        world.reset(plan.start)
        judge = Judge(run, world, layout=layout, tolerance=spec.defaults.shape_tolerance)
        executor = Executor(run, world, LatchRecognizer(spec), DriveController(spec),
                            ExecutorOptions(rate=rate, action_timeout=action_timeout),
                            sink=judge)
        return judge.conclude(executor.execute())


def needs_joints(plan: Plan) -> bool:
    """Whether ``plan`` has an action only joints can make: a dock of two modules already
    joined (closing a loop), or a move with neither changes nor planar goals (a shape)."""
    current = plan.start
    for action in plan.actions:
        if action.type is ActionType.MOVING and not action.goals:
            return True
        groups = {m: g for g in nx.connected_components(current.undirected()) for m in g}
        if any(groups[c.source] is groups[c.target] for c in action.made()):
            return True
        current = action.target
    return False


def shipped_configurations(name: str) -> list[Path]:
    """The configuration files robot ``name`` ships (see the module docstring), sorted."""
    found = set()
    for scenario in plugins.capabilities(name).scenarios.values():
        found |= {Path(scenario.start)} | {Path(s.goal) for s in scenario.all_stages()
                                            if s.goal is not None}
    for folder in _config_folders(name):
        for path in folder.glob("*.json"):
            try:
                robot = json.loads(path.read_text()).get("robot")
            except (OSError, ValueError, AttributeError):
                robot = name  # a broken file is the robot's: loading it reports why
            if robot == name:
                found.add(path)
    return sorted(found)


def _config_folders(name: str) -> list[Path]:
    """``configs/`` beside the module of the plugin that describes robot ``name``."""
    plugin = plugins.robot_plugin(name)
    module = inspect.getmodule(plugin) if inspect.ismodule(plugin) else \
        inspect.getmodule(type(plugin))
    source = getattr(module, "__file__", None)
    folder = Path(source).parent / "configs" if source else None
    return [folder] if folder is not None and folder.is_dir() else []


def replay_problems(plan: Plan) -> list[str]:
    """What is wrong when ``plan`` is replayed action by action (empty: it replays).

    Each action's planned changes must cover the topology change from the previous
    target to its own (the executor's consistency rule), and the last target must have
    the topology of ``plan.goal``.
    """
    problems = []
    current = plan.start
    for index, action in enumerate(plan.actions):
        needed = {c.key for c in topology_diff(current, action.target).changes()}
        planned = {c.key for c in action.changes}
        if planned and not needed <= planned:
            problems.append(f"action {index + 1} ({action}) needs {topology_diff(current, action.target)}")
        if not planned and needed:
            problems.append(f"action {index + 1} ({action}) changes the topology but lists no change")
        current = action.target
    left = topology_diff(current, plan.goal)
    if left:
        problems.append(f"the last target differs from the plan's goal: {left}")
    return problems


def robot_parameters(names: Iterable[str] | None = None, *,
                     known_failures: Mapping[str, str] | None = None) -> Callable:
    """``@robot_parameters()``: a ``pytest.mark.parametrize("robot", ...)`` over the
    installed robots (or ``names``), one test id per robot.

    ``known_failures`` maps a robot to the reason it cannot pass yet: its case is a strict
    ``xfail`` on :class:`ConformanceError`, so it turns red again once it passes.
    """
    import pytest  # only tests need pytest; the platform does not depend on it

    robots = sorted(plugins.robots()) if names is None else list(names)
    known = known_failures or {}
    return pytest.mark.parametrize("robot", [
        pytest.param(r, marks=pytest.mark.xfail(raises=ConformanceError, strict=True,
                                                reason=known[r])) if r in known else r
        for r in robots], ids=robots)


@dataclass
class ConformanceReport:
    """What :func:`check_robot` checked.

    Attributes:
        robot: the robot's name.
        passed: every check that passed, one line each.
        declined: plans the default planner declined with a ``PlanningError`` (and why).
        skipped: runs the kinematic driver cannot make (the ends of connections that
            are modules, FreeSN struts, do not dock there), and why.
        failures: every check that failed (then :func:`check_robot` raises).
    """

    robot: str
    passed: list[str] = field(default_factory=list)
    declined: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    failures: list[str] = field(default_factory=list)

    fail_fast: bool = False

    def fail(self, message: str) -> None:
        """Record a failed check; with ``fail_fast``, raise at once."""
        self.failures.append(message)
        if self.fail_fast:
            raise ConformanceError(f"robot {self.robot!r} fails (first failure): {message}")

    def check(self, what: str, step: Callable[[], Any]) -> Any:
        try:
            value = step()
        except (MsrrError, AssertionError, ValueError, KeyError) as exc:
            self.fail(f"{what}: {type(exc).__name__}: {exc}")
            return None
        self.passed.append(what)
        return value


def check_robot(name: str, *, run: bool = True, all_pairs: bool = False,
                fail_fast: bool = False, rate: float = 5.0) -> ConformanceReport:
    """Assert that robot ``name`` keeps the platform's contract (module docstring).

    Args:
        name: an installed robot.
        run: also execute in the kinematic driver (check 5).
        all_pairs: plan every ordered pair of configurations with the same module counts;
            by default each one plans to the next of its counts (file order, the last
            to the first), which keeps a robot with many configurations fast.
        fail_fast: raise at the first failed check instead of listing them all (a
            robot known to fail, checked only to notice when it passes).
        rate: control rate [Hz] of those runs.

    Raises:
        ConformanceError: the robot cannot be resolved (naming the plugin that fails), or
            listing every failed check, with the file and the reason.
    """
    report = ConformanceReport(name, fail_fast=fail_fast)
    try:
        capabilities = plugins.capabilities(name)
    except MsrrError as exc:
        raise ConformanceError(f"robot {name!r} cannot be resolved: {exc}") from None
    files = shipped_configurations(name)
    if not files:
        raise ConformanceError(f"robot {name!r} ships no configuration: register a scenario or "
                               "put files in a configs/ folder beside its plugin module")
    configs = _check_files(report, capabilities, files)
    plans = _check_plans(report, capabilities.planner(), configs, all_pairs)
    if run:
        _check_runs(report, capabilities.robot, configs, plans, rate)
        if has_bodies(capabilities.robot.spec):
            _check_physics(report, capabilities.robot.spec, plans)
    if report.failures:
        raise ConformanceError(f"robot {name!r} fails {len(report.failures)} check(s):\n  "
                               + "\n  ".join(report.failures))
    return report


def _check_files(report: ConformanceReport, capabilities: Capabilities,
                 files: list[Path]) -> dict[str, Configuration]:
    """Checks 1-3 on every shipped file: load, validate, round trip, match itself, each
    planner plans it to itself with no action. Returns the loaded ones by file name."""
    robot = capabilities.robot
    configs: dict[str, Configuration] = {}
    for path in files:
        config = report.check(f"{path.name}: load", lambda p=path: plugins.load_configuration(p))
        if config is None:
            continue
        configs[path.name] = config
        report.check(f"{path.name}: validate", lambda c=config: check_configuration(c, robot))
        report.check(f"{path.name}: JSON round trip", lambda c=config: _round_trip(c))
        report.check(f"{path.name}: match itself", lambda c=config: _self_match(c, robot))
        for planner_name, planner in capabilities.planners.items():
            report.check(f"{path.name}: planner {planner_name} to itself",
                         lambda c=config, p=planner: _zero_plan(p.plan(c, c)))
    return configs


def _check_plans(report: ConformanceReport, planner: Planner,
                 configs: dict[str, Configuration], all_pairs: bool
                 ) -> list[tuple[str, Plan]]:
    """Check 4: the default planner's plans between files of the same module counts (each
    to the next of its counts, or every pair) replay. Returns the plans made."""
    plans: list[tuple[str, Plan]] = []
    same: dict[tuple, list[str]] = {}
    for label, config in configs.items():
        same.setdefault(config.signature().counts, []).append(label)
    ring = {(group[i], group[(i + 1) % len(group)]) for group in same.values()
            for i in range(len(group))}
    for a, start in configs.items():
        for b, goal in configs.items():
            if a == b or start.signature().counts != goal.signature().counts:
                continue
            if not all_pairs and (a, b) not in ring:
                continue
            try:
                plan = planner.plan(start, goal)
            except PlanningError as exc:
                report.declined.append(f"plan {a} -> {b} ({planner.name}): {exc}")
                continue
            except MsrrError as exc:
                report.fail(f"plan {a} -> {b} ({planner.name}): {type(exc).__name__}: {exc}")
                continue
            if isinstance(plan, Plan):
                plans.append((f"{a} -> {b}", plan))
                problems = replay_problems(plan)
                if problems:
                    report.fail(f"plan {a} -> {b} ({planner.name}) does not replay: "
                                + "; ".join(problems))
                else:
                    report.passed.append(f"plan {a} -> {b} ({planner.name}) replays")
    return plans


def _check_runs(report: ConformanceReport, robot: Robot, configs: dict[str, Configuration],
                plans: list[tuple[str, Plan]], rate: float) -> None:
    """Check 5: every file runs to itself, and every plan runs, in the kinematic driver
    (plans that dock the ends of edge modules are skipped: it does not dock them)."""
    spec = robot.spec
    for label, config in configs.items():
        report.check(f"{label}: run to itself in the kinematic driver",
                     lambda c=config: _succeeds(run_kinematic(
                         Plan(spec.name, "conformance", c, c, []), spec, rate=rate)))
    struts = bool(spec.kinds_with_role("edge"))
    for label, plan in plans:
        if struts and any(a.changes for a in plan.actions):
            report.skipped.append(f"run {label}: the kinematic driver does not dock the ends "
                                  "of connections that are modules")
            continue
        if needs_joints(plan):
            report.skipped.append(f"run {label}: it needs joints, which the kinematic driver "
                                  "does not have")
            continue
        report.check(f"run {label} in the kinematic driver",
                     lambda p=plan: _succeeds(run_kinematic(
                         p, spec, rate=rate,
                         driver=KinematicDriver(spec, speed=CHECK_SPEED,
                                                turn_rate=CHECK_TURN_RATE))))


def _check_physics(report: ConformanceReport, spec: RobotSpec,
                   plans: list[tuple[str, Plan]]) -> None:
    """Check 6: one plan in the generic ``mujoco`` driver, judged on its ground truth."""
    moving = [(label, plan) for label, plan in plans if plan.actions]
    if not moving:
        report.skipped.append("physics run: no plan of check 4 has an action")
        return
    label, plan = min(moving, key=lambda item: (not needs_joints(item[1]),
                                                len(item[1].actions)))
    report.check(f"run {label} in the mujoco driver (judged on ground truth)",
                 lambda: _succeeds(run_physics(plan, spec)))


def _round_trip(config: Configuration) -> None:
    again = parse_configuration(json.loads(dump_configuration(config)))
    if again != config:
        raise AssertionError("the configuration changes through JSON")


def _self_match(config: Configuration, robot: Any) -> None:
    """Each connected piece matches itself at zero cost (a kinematic tree spans one
    piece; a forest of MISO modules is a configuration too)."""
    for piece in _pieces(config):
        result = match(piece, [Candidate(piece, None, "itself")], robot=robot)
        if result is None:
            raise AssertionError("no match with itself")
        cost = result.ranked[0].cost
        if not math.isfinite(cost) or abs(cost) > 1e-6:
            raise AssertionError(f"matching itself costs {cost:.3g}, expected 0")


def _pieces(config: Configuration) -> list[Configuration]:
    """``config`` itself when connected, else one copy per connected piece."""
    if config.is_connected():
        return [config]
    out = []
    for piece in sorted(map(sorted, nx.connected_components(config.undirected()))):
        copy = config.copy()
        for vertex in set(copy.vertices()) - set(piece):
            copy.remove_module(vertex)
        out.append(copy)
    return out


def _zero_plan(plan: Plan) -> None:
    if plan.actions:
        raise AssertionError(f"{len(plan.actions)} action(s) from a configuration to itself: "
                             + ", ".join(str(a) for a in plan.actions))


def _succeeds(result: RunResult) -> None:
    if not result.success:
        raise AssertionError(f"run failed: {result.reason}")


# -- derivative checks for joint-mode authors ---------------------------------------------


def node_jacobian_errors(node: KinematicNode, z: np.ndarray, x: np.ndarray,
                         sigma: np.ndarray, h: float = 1e-6) -> dict[str, float]:
    """Relative error of every analytic derivative of ``node`` against central differences.

    Args:
        node: a kinematic node (a joint mode's instance).
        z, x: its initial vectors, shape (3, m).
        sigma: the joint values, shape (dim,).
        h: the difference step.

    Returns:
        ``"d<what>/dsigma[i]"`` -> relative error, for ``what`` in ``z``, ``x``, ``cost``
        and ``rotations`` (the port rotations); errors are relative to the numeric
        derivative's norm, floored at 1e-3.
    """
    jac = node.jacobian(z, x, sigma)
    errors: dict[str, float] = {}
    for i in range(node.dim):
        step = np.zeros(node.dim)
        step[i] = h
        plus, minus = node.forward(z, x, sigma + step), node.forward(z, x, sigma - step)
        for name, analytic in (("z", jac.z), ("x", jac.x), ("cost", jac.cost),
                               ("rotations", jac.rotations)):
            numeric = (getattr(plus, name) - getattr(minus, name)) / (2 * h)
            errors[f"d{name}/dsigma[{i}]"] = float(
                np.linalg.norm(analytic[..., i] - numeric) / max(np.linalg.norm(numeric), 1e-3))
    return errors


def tree_gradient_error(tree: KinematicTree, config: Configuration, seed: int,
                        h: float = 1e-6) -> float:
    """Relative error of the tree's reverse-mode FK gradient (Alg. 1) of a random linear
    loss of ``Z``, ``X`` and the motion costs, against central differences, at random
    joint values (seeded)."""
    rng = np.random.default_rng(seed)
    z0, x0, _ = tree_vectors(tree, config)
    evaluator = Evaluator(tree, z0, x0)
    n = len(tree.edges)
    gz, gx, gc = rng.normal(size=(n, 3)), rng.normal(size=(n, 3)), rng.normal(size=n)
    sigma = rng.normal(size=tree.dim) * 0.6

    def loss(s: np.ndarray) -> float:
        state = evaluator.evaluate(s)
        return float(np.sum(state.z * gz) + np.sum(state.x * gx) + state.cost @ gc)

    analytic = evaluator.gradient(evaluator.evaluate(sigma, derivatives=True), gz, gx, gc)
    numeric = np.array([(loss(sigma + h * e) - loss(sigma - h * e)) / (2 * h)
                        for e in np.eye(tree.dim)])
    return float(np.linalg.norm(analytic - numeric) / max(np.linalg.norm(numeric), 1e-12))
