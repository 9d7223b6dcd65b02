"""Orchestration of ``platform run``: scenario -> plan -> execute -> files.

:func:`prepare_run` checks the request and the output folder, loads and checks the two
configurations, resolves the robot's driver, controller, recognizer and planner once
(a :class:`PreparedRun`), plans from the start file, and only then claims the output
folder; :func:`execute_run` places the modules on a fresh driver, recognizes the
configuration at the first tick and plans again from it (the run recognizes and matches
itself, FreeSN Alg. 4: the start file only placed the modules; the plan written is this
one) unless it is the state the first plan started from
(:meth:`~msrr.core.configuration.Configuration.same_state`), and runs it;
:func:`write_outputs` writes the files. Every bad option or output place, an
unreachable goal (different module counts, an illegal face pair) fails with a
one-line error before anything is written. A run writes into its folder:

* ``run.rrd`` -- the rerun recording (via the timeline plugin), unless ``log=False``;
* ``plan.json`` -- the executed plan (:func:`msrr.core.plan.save_plan`);
* ``summary.json`` -- the :class:`~msrr.core.events.RunResult` numbers.

All three are written also when the run fails, meets a fault or is interrupted
(:class:`~msrr.core.interrupts.Interrupted`): the driver is told to stop every module,
then disconnected, and ``summary.json`` says ``success: false`` with the reason.
Every driver goes through :class:`~msrr.core.faults.GuardedDriver` (NaN readings held,
the overall deadlines of driver time and of wall time) watched by a
:class:`~msrr.core.watchdog.Watchdog` (a driver call that does not return within
``stall`` seconds ends the run) and, with ``faults``, a
:class:`~msrr.core.faults.FaultyDriver`.
"""

from __future__ import annotations

import json
import math
import shutil
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from datetime import datetime
from pathlib import Path

from .. import plugins
from ..capabilities import Capabilities, Controller, DriverFactory, Planner, Recognizer
from ..configuration import Configuration
from ..driver import Driver, OptionValue, Pose, check_driver_options
from ..errors import (
    ConfigurationError,
    ExecutionError,
    MsrrError,
    OutputError,
    UnknownNameError,
)
from ..events import ActionStatus, EventSink, FaultEvent, Run, RunResult, Tick, TopologyEvent
from ..executor import Executor, ExecutorOptions
from ..faults import Fault, FaultyDriver, GuardedDriver, check_fault_modules, parse_faults
from ..files import atomic_write_text, check_output_place
from ..interrupts import Interrupted, shielded
from ..judge import Judge
from ..plan import Action, ActionType, Plan, join_plans, save_plan
from ..scenario import MAX_TIME, Scenario, Stage
from ..watchdog import DRIVER_STALL, Watchdog
from ..witness import poses_seen

__all__ = ["MAX_RATE", "RUN_FILES", "PreparedRun", "RunRequest", "check_out_dir", "claim_out_dir",
           "default_deadline", "default_out_dir", "default_wall_deadline", "execute_run", "interrupted_result", "leftovers", "parse_driver_options",
           "parse_parameters", "plan_stages", "prepare_run", "resolve_scenario", "write_outputs"]

RUN_FILES = ("run.rrd", "plan.json", "summary.json")
"""The files a finished run leaves in its folder."""

MAX_RATE = 1000.0
"""Highest control rate ``platform run`` accepts [Hz]."""

MAX_SEED = 2**32 - 1
"""Largest ``--seed`` (numpy's seed range, as every command's ``--seed``)."""

MAX_STALL = 3600.0
"""Longest ``--stall`` [s]."""

WALL_FLOOR = 600.0
"""Wall time every run may take besides :data:`WALL_FACTOR` times its deadline [s]."""

WALL_FACTOR = 20.0
"""Wall seconds a run may take per second of its driver-time deadline by default."""

SAME_STATE_RESOLUTION = 1e-9
"""The first tick's recognition is the start file's state when their numbers agree within
this (a file rounds its vectors, the human example's to 12 decimals; the recognizer
computes them from the bodies: 3e-13 apart there)."""


@dataclass(frozen=True)
class RunRequest:
    """What the user asked for (``platform run`` options).

    Attributes:
        robot: robot name.
        scenario: scenario name; ``None`` for the robot's default (unless files are given).
        start: start configuration file (with ``goal``, instead of a scenario).
        goal: goal configuration file.
        seed: seed of planning and recognition.
        out: output folder; default ``runs/<timestamp>-<robot>-<scenario>``.
        log: write the rerun recording.
        gui: open the simulator's GUI.
        rate: control rate [Hz].
        action_timeout: driver time one action phase may take [s].
        driver: driver name (default: the robot's first).
        planner: planner name (default: the robot's first).
        driver_options: extra keyword options of the driver factory (``noise``, ``slip``):
            text as given (``parse_driver_options``), or values already typed; typed and
            checked against the driver's declaration by :func:`prepare_run`.
        force: replace a run already in ``out``.
        faults: fault SPEC (:func:`msrr.core.faults.parse_faults`), or ``""``.
        deadline: overall driver time the run may take [s]; ``None``:
            :func:`default_deadline`.
        wall_deadline: overall wall time the run's execution may take [s]; ``None``:
            :func:`default_wall_deadline`.
        stall: wall time one call of the driver may take [s] before the watchdog ends
            the run (:mod:`msrr.core.watchdog`).
        plan: a saved plan file (``platform plan --json``) to execute instead of
            planning; validated against the robot on load.
        behavior: a behavior of the robot's library to run after the goal (or from the
            start, without one): ``platform run --behavior NAME``.
        parameters: the behavior's parameter values (``--param speed=0.05``).
        duration: how long a mapping behavior runs [s of driver time] (``--duration``).
        loops: how many loops of a sequence behavior run (``--loops``).
        distance: the behavior stops once the system's centre moved this far [m].
    """

    robot: str
    scenario: str | None = None
    start: Path | None = None
    goal: Path | None = None
    seed: int = 0
    out: Path | None = None
    log: bool = True
    gui: bool = False
    rate: float = 10.0
    action_timeout: float = 90.0
    driver: str | None = None
    planner: str | None = None
    driver_options: tuple[tuple[str, object], ...] = ()
    force: bool = False
    faults: str = ""
    deadline: float | None = None
    wall_deadline: float | None = None
    stall: float = DRIVER_STALL
    plan: Path | None = None
    behavior: str | None = None
    parameters: tuple[tuple[str, float], ...] = ()
    duration: float | None = None
    loops: int | None = None
    distance: float | None = None

    def check(self) -> None:
        """Refuse non-finite or out-of-range numbers (one line naming the option)."""
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) \
                or not 0 <= self.seed <= MAX_SEED:
            raise ConfigurationError(f"must be a whole number in [0, {MAX_SEED}], got "
                                     f"{self.seed!r}", field="--seed")
        for name, value, high in (("--rate", self.rate, MAX_RATE),
                                  ("--timeout", self.action_timeout, MAX_TIME),
                                  ("--deadline", self.deadline, MAX_TIME),
                                  ("--wall-deadline", self.wall_deadline, MAX_TIME),
                                  ("--stall", self.stall, MAX_STALL)):
            if value is None:
                continue
            if isinstance(value, bool) or not math.isfinite(value) or value <= 0:
                raise ConfigurationError(f"must be a finite number > 0, got {value!r}",
                                         field=name)
            if high is not None and value > high:
                raise ConfigurationError(f"must be at most {high:g}, got {value:g}", field=name)
        if self.behavior is None:
            for name, given in (("--param", bool(self.parameters)),
                                ("--duration", self.duration is not None),
                                ("--loops", self.loops is not None),
                                ("--distance", self.distance is not None)):
                if given:
                    raise ConfigurationError("applies to a behavior; give --behavior NAME",
                                             field=name)
        else:
            try:
                Stage(behavior=self.behavior, parameters=self.parameters,
                      duration=self.duration, loops=self.loops, distance=self.distance)
            except ConfigurationError as exc:
                raise ConfigurationError(exc.message, field=f"--{exc.field}"
                                         if exc.field in ("duration", "loops", "distance")
                                         else "--param") from None


def default_deadline(plan: Plan, action_timeout: float) -> float:
    """The overall driver time [s] a run of ``plan`` may take by default: one
    ``action_timeout`` per action plus one, and every behavior's duration, so a run
    whose every action runs to its timeout still ends, and no run can go on forever."""
    behaviors = sum(a.behavior.duration or 0.0 for a in plan.actions if a.behavior is not None)
    return (len(plan.actions) + 1) * action_timeout + behaviors


def default_wall_deadline(deadline: float) -> float:
    """The overall wall time [s] a run with ``deadline`` seconds of driver time may take
    by default: :data:`WALL_FLOOR` plus :data:`WALL_FACTOR` times the deadline (a
    simulation may run slower than real time; a driver that stops answering is ended
    by the stall watchdog long before), at most :data:`~msrr.core.scenario.MAX_TIME`."""
    return min(WALL_FLOOR + WALL_FACTOR * deadline, MAX_TIME)


def parse_parameters(items: tuple[str, ...] | list[str]) -> tuple[tuple[str, float], ...]:
    """``("speed=0.05", "yaw_rate=0")`` -> ``(("speed", 0.05), ("yaw_rate", 0.0))``.

    Raises:
        ConfigurationError: an item without ``=`` or whose value is not a finite number.
    """
    out = []
    for item in items:
        key, sep, text = item.partition("=")
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not sep or not key.strip() or not math.isfinite(value):
            raise ConfigurationError(f"{item!r} is not NAME=NUMBER", field="--param")
        out.append((key.strip(), value))
    return tuple(out)


def plan_stages(capabilities: Capabilities, planner: Planner, start: Configuration,
                stages: Sequence[tuple[Stage, Configuration | None]], *, seed: int = 0
                ) -> Plan:
    """One plan through every stage (a scenario's goal, its further goals, behaviors):
    stage ``i`` is planned from where stage ``i - 1`` ends (the plan's goal, in the
    system's ids), and the plans are joined (:func:`msrr.core.plan.join_plans`). A goal
    stage's last action is marked ``reaches`` with the stage's name, so the executor
    judges the shape there. Behavior stages go to ``planner`` if it plans behaviors
    (:class:`~msrr.core.capabilities.BehaviorPlanner`), else to the robot's first
    planner that does.

    Args:
        capabilities: the robot's (its planners plan behavior stages).
        planner: the planner of goal stages.
        start: the system's start configuration, in its own ids.
        stages: each stage with its loaded goal configuration (``None`` for behaviors).
        seed: seed of every planner call.

    Raises:
        PlanningError: a stage cannot be planned.
        UnknownNameError: a behavior stage, and no planner of the robot plans behaviors.
    """
    plans: list[Plan] = []
    here = start
    for stage, goal in stages:
        if goal is not None:
            plan = planner.plan(here, goal, seed=seed)
            if stage.joint_mode:
                _moves_in(plan, capabilities.robot.joint_modes, stage.joint_mode)
            if plan.actions:
                plan.actions[-1].reaches = stage.name or goal.name or \
                    (stage.goal.stem if stage.goal else "goal")
        else:
            assert stage.behavior is not None
            plan = capabilities.behavior_planner(planner).plan_behavior(
                here, stage.behavior, parameters=dict(stage.parameters),
                duration=stage.duration, loops=stage.loops, distance=stage.distance, seed=seed)
        plans.append(plan)
        here = plan.goal
    return join_plans(plans)


def _moves_in(plan: Plan, modes: Mapping[str, type], name: str) -> None:
    """Give each moving action of ``plan`` without a kinematic tree the default tree of
    joint mode ``name`` on its target.

    Raises:
        UnknownNameError: the robot has no joint mode ``name``.
    """
    from ..kinematics import default_tree

    if name not in modes:
        raise UnknownNameError("joint mode of a scenario stage", name, modes)
    for action in plan.actions:
        if action.type is ActionType.MOVING and action.kinematic_tree is None:
            action.kinematic_tree = default_tree(action.target, modes[name])


def resolve_scenario(robot: str, name: str | None) -> Scenario:
    """The scenario ``name`` of ``robot``, or its default one."""
    found = plugins.capabilities(robot).scenarios
    if name is not None:
        if name not in found:
            raise UnknownNameError(f"scenario for robot {robot!r}", name, found)
        return found[name]
    for scenario in found.values():
        if scenario.default:
            return scenario
    if found:
        return next(iter(found.values()))
    raise UnknownNameError(f"scenario for robot {robot!r}", "(default)", ())


def parse_driver_options(items: tuple[str, ...] | list[str]) -> tuple[tuple[str, str], ...]:
    """``("noise=0.035", "slip=0.05")`` -> ``(("noise", "0.035"), ("slip", "0.05"))``; the
    values are typed and checked against the driver's declaration when the run is
    prepared (:func:`msrr.core.driver.check_driver_options`).

    Raises:
        ConfigurationError: an item without ``=`` or without a name.
    """
    out: list[tuple[str, str]] = []
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not key.strip():
            raise ConfigurationError(f"{item!r} is not KEY=VALUE", field="--driver-option")
        out.append((key.strip(), text.strip()))
    return tuple(out)


def default_out_dir(robot: str, scenario: str, root: Path = Path("runs")) -> Path:
    """``runs/<YYYYmmdd-HHMMSS>-<robot>-<scenario>`` (:func:`claim_out_dir` adds ``-2``,
    ``-3``, ... when another run took it first)."""
    return root / f"{datetime.now():%Y%m%d-%H%M%S}-{robot}-{scenario}"


def leftovers(folder: Path) -> list[str]:
    """Files an interrupted or killed run left in ``folder``: a recording still named
    ``*.part``, temporary files of an atomic write (``.<name>.*.tmp``)."""
    try:
        names = sorted(p.name for p in folder.iterdir())
    except OSError:
        return []
    return [n for n in names if n.endswith(".part")
            or (n.startswith(".") and n.endswith(".tmp"))]


def _found(folder: Path) -> tuple[list[str], list[str]]:
    return [n for n in RUN_FILES if (folder / n).exists()], leftovers(folder)


def check_out_dir(out: Path | None, *, force: bool = False) -> list[str]:
    """Refuse a bad output folder before any work; say what an earlier run left in it.

    Refused: an empty path, an existing file, a path under a file, a place where no
    folder can be created, and (unless ``force``) a folder that holds a run's files or
    an interrupted run's leftovers.

    Returns:
        one line per thing found that ``force`` will replace (empty for a new folder).

    Raises:
        ConfigurationError: naming ``--out`` and the path.
    """
    if out is None:
        return []
    check_output_place(out, option="--out", folder=True)
    if not out.is_dir():
        return []
    finished, left = _found(out)
    if not finished and not left:
        return []
    what = []
    if finished:
        what.append(f"a run ({', '.join(finished)})")
    if left:
        what.append(f"an interrupted run's leftovers ({', '.join(left)})")
    text = " and ".join(what)
    if not force:
        raise ConfigurationError(f"holds {text}; use --force to replace it", field="--out",
                                 source=str(out))
    return [f"{out} held {text}: replaced"]


def claim_out_dir(out: Path, *, default: bool, force: bool = False) -> Path:
    """Create the run's folder; returns the folder claimed.

    A default folder (``default``) is created exclusively: when a run started in the
    same second took the name, ``-2``, ``-3``, ... is appended. A given folder is
    created if missing; with ``force`` the files of an earlier run and its leftovers
    are removed first, so nothing in it can describe another run.

    Raises:
        ConfigurationError: the folder cannot be created.
    """
    try:
        if default:
            out.parent.mkdir(parents=True, exist_ok=True)
            for number in range(1, 10_000):
                candidate = out if number == 1 else out.with_name(f"{out.name}-{number}")
                try:
                    candidate.mkdir()
                    return candidate
                except FileExistsError:
                    continue
            raise ConfigurationError("no free run folder name", source=str(out))
        out.mkdir(parents=True, exist_ok=True)
        if force:
            finished, left = _found(out)
            for name in finished + left:
                (out / name).unlink(missing_ok=True)
        return out
    except OSError as exc:
        raise ConfigurationError(f"cannot create the folder: {exc.strerror or exc}",
                                 field="--out", source=str(out)) from None


@dataclass(frozen=True)
class PreparedRun:
    """A planned run and the capabilities that will execute it, each resolved once.

    Attributes:
        run: the event payload (robot, scenario, plan, output paths).
        capabilities: the robot's, resolved once (the executor gets its robot and
            controllers from here).
        driver: factory of the driver, called as ``driver(gui=..., seed=...)``.
        recognizer: the robot's recognizer.
        controller: the robot's controller.
        options: rate and action timeout of the executor.
        gui: open the simulator's window.
        driver_options: extra keyword options of the driver factory.
        faults: the faults to inject (empty: none).
        deadline: overall driver time the run may take [s].
        wall_deadline: overall wall time the run's execution may take [s].
        deadline_grows: ``deadline`` is the default one, moved later by the time the
            controller says each phase needs (:func:`default_deadline` cannot know it).
        wall_deadline_grows: ``wall_deadline`` is the default one, moved later by
            :data:`WALL_FACTOR` times that time.
        stall: wall time one driver call may take [s].
        notes: what was found in the output folder and replaced (one line each).
        problems: what could not be written at the run's end (the recording on a full
            disk: one line each, filled by :func:`execute_run`; the command exits 1).
        planner: the planner of the goal stages; ``None`` for a saved plan (``--plan``),
            executed as it is.
        stages: the stages with their goals loaded, planned again by
            :func:`execute_run` from the recognized start (unless it is the plan's).
    """

    run: Run
    capabilities: Capabilities
    driver: DriverFactory
    recognizer: Recognizer
    controller: Controller
    options: ExecutorOptions
    gui: bool = False
    driver_options: tuple[tuple[str, float | int | bool | str], ...] = ()
    faults: tuple[Fault, ...] = ()
    deadline: float = math.inf
    wall_deadline: float = math.inf
    deadline_grows: bool = False
    wall_deadline_grows: bool = False
    stall: float = DRIVER_STALL
    notes: tuple[str, ...] = ()
    problems: list[str] = field(default_factory=list)
    planner: Planner | None = None
    stages: tuple[tuple[Stage, Configuration | None], ...] = ()


def _configurations(request: RunRequest
                    ) -> tuple[str, Configuration, list[tuple[Stage, Configuration | None]]]:
    """The run's name, start and stages (each goal stage with its configuration loaded)
    from ``--from``/``--to``/``--behavior`` or the scenario."""
    behavior = () if request.behavior is None else (Stage(
        behavior=request.behavior, parameters=request.parameters, duration=request.duration,
        loops=request.loops, distance=request.distance),)
    if request.start is not None or request.goal is not None:
        if request.scenario is not None:
            raise ConfigurationError("give --scenario or --from/--to, not both")
        if request.start is None:
            raise ConfigurationError("give --from with --to")
        if request.goal is None and not behavior:
            raise ConfigurationError("give --to or --behavior with --from")
        name, start_path = "custom", request.start
        stages = ((Stage(goal=request.goal),) if request.goal is not None else ()) + behavior
    else:
        scenario = resolve_scenario(request.robot, request.scenario)
        name, start_path = scenario.name, scenario.start
        if behavior:
            stages = ((Stage(goal=scenario.goal),) if scenario.goal is not None
                      and request.scenario is not None else ()) + behavior
            name = request.behavior if request.scenario is None else f"{name}+{request.behavior}"
        else:
            stages = scenario.all_stages()
    start = plugins.load_configuration(start_path)
    loaded: list[tuple[Stage, Configuration | None]] = []
    for stage in stages:
        loaded.append((stage, None if stage.goal is None
                       else plugins.load_configuration(stage.goal)))
    for config, path in [(start, start_path), *((g, s.goal) for s, g in loaded if g)]:
        if config.robot != request.robot:
            raise ConfigurationError(f"is a {config.robot!r} configuration, not "
                                     f"{request.robot!r}", source=str(path))
    return name, start, loaded


def prepare_run(request: RunRequest) -> PreparedRun:
    """Check the options and the output folder, load the configurations, resolve the
    capabilities and plan; the output folder is created only once all that succeeded.

    Raises:
        ConfigurationError: a bad option or output place, a file missing or invalid.
        PlanningError: the goal cannot be reached.
        UnknownNameError: unknown scenario, planner or driver, or the robot has no
            recognizer or controller.
    """
    request.check()
    faults = parse_faults(request.faults) if request.faults.strip() else ()
    notes = check_out_dir(request.out, force=request.force)
    capabilities = plugins.capabilities(request.robot)
    spec = capabilities.robot.spec
    if request.plan is not None:
        if request.start is not None or request.goal is not None or request.scenario:
            raise ConfigurationError("give --plan, --scenario or --from/--to, one of them")
        if request.behavior is not None:
            raise ConfigurationError("--plan executes a saved plan: it takes no --behavior")
        if request.planner is not None:
            raise ConfigurationError("--plan executes a saved plan: it takes no --planner")
        saved: Plan | None = plugins.load_plan(request.plan)
        if saved.robot != request.robot:
            raise ConfigurationError(f"is a plan for robot {saved.robot!r}, not "
                                     f"{request.robot!r}", source=str(request.plan),
                                     field="robot")
        name = "plan"
    else:
        saved = None
        name, start, stages = _configurations(request)
    factory = capabilities.driver(request.driver)
    driver_options = check_driver_options(factory, request.driver_options)
    _try_driver(factory, request, driver_options)
    # a driver may name the recognizer and controller that read and command it (the
    # generic kinematic driver does); otherwise the robot's first ones
    controller = capabilities.controller(factory.companions.controller)
    recognizer = capabilities.recognizer(factory.companions.recognizer)
    options = ExecutorOptions(rate=request.rate, action_timeout=request.action_timeout)
    planner = None if saved is not None else capabilities.planner(request.planner)
    # planned from the file here, so an unreachable goal is refused before anything is
    # written; execute_run plans again from what the modules report
    plan: Plan = saved if saved is not None else plan_stages(
        capabilities, planner, start, stages, seed=request.seed)
    check_fault_modules(faults, plan.start.modules())
    deadline = request.deadline or default_deadline(plan, request.action_timeout)
    wall_deadline = request.wall_deadline or default_wall_deadline(deadline)
    if request.out is None:
        out = claim_out_dir(default_out_dir(request.robot, name), default=True)
    else:
        out = claim_out_dir(request.out, default=False, force=request.force)
    run = Run(robot=request.robot, scenario=name, plan=plan, spec=spec, driver=factory.name,
              rate=request.rate, seed=request.seed, out_dir=out,
              recording=out / "run.rrd" if request.log else None)
    return PreparedRun(run, capabilities, factory, recognizer, controller, options, request.gui,
                       driver_options, faults, deadline, wall_deadline,
                       request.deadline is None, request.wall_deadline is None, request.stall,
                       tuple(notes), planner=planner,
                       stages=() if saved is not None else tuple(stages))


def _try_driver(factory: DriverFactory, request: RunRequest,
                options: tuple[tuple[str, OptionValue], ...]) -> None:
    """Build the run's driver once, without connecting it, so options only the driver
    can judge (the link driver's systems file) are refused before anything is written."""
    try:
        factory(gui=request.gui, seed=request.seed, **dict(options))
    except MsrrError:
        raise
    except (TypeError, ValueError) as exc:
        raise ConfigurationError(f"driver {factory.name!r} refused its options: "
                                 f"{type(exc).__name__}: {exc}",
                                 field="--driver-option") from None


class _Progress:
    """Where a run is (for the line that says what an interruption or error stopped) and
    the faults it met: the run's :class:`~msrr.core.events.EventSink`, passing every
    event on to ``listeners`` (the judge, then the plugins' event hooks)."""

    def __init__(self, run: Run, *listeners: EventSink):
        self.run = run
        self.listeners = listeners
        self.driver: Driver | None = None  # its witness goes with every tick
        self.current: int | None = None
        self.done = 0
        self.faults: list[FaultEvent] = []
        self.started = False  # faults before run_start (the first observation) wait for it

    def run_start(self, run: Run) -> None:
        for listener in self.listeners:
            listener.run_start(run)
        self.started = True
        for fault in self.faults:
            for listener in self.listeners:
                listener.fault(run, fault)

    def tick(self, run: Run, tick: Tick) -> None:
        if self.driver is not None:
            tick = replace(tick, witness=self.driver.witness())
        for listener in self.listeners:
            listener.tick(run, tick)

    def action(self, run: Run, action: Action, status: ActionStatus) -> None:
        index = next((i for i, a in enumerate(run.plan.actions) if a is action), None)
        if status == ActionStatus.STARTED:
            self.current = index
        elif status == ActionStatus.SUCCEEDED:
            self.done += 1
            self.current = None
        for listener in self.listeners:
            listener.action(run, action, status)

    def topology_change(self, run: Run, change: TopologyEvent) -> None:
        for listener in self.listeners:
            listener.topology_change(run, change)

    def fault(self, run: Run, fault: FaultEvent) -> None:
        self.faults.append(fault)
        for listener in self.listeners if self.started else ():
            listener.fault(run, fault)

    def run_end(self, run: Run, result: RunResult) -> None:
        for listener in self.listeners:
            listener.run_end(run, result)

    def on_fault(self, event: FaultEvent) -> None:
        """The faults layer's and the guard's callback."""
        self.fault(self.run, event)

    def where(self) -> str:
        """``"action 4/9: moving 4, 8"``, or what runs outside an action."""
        actions = self.run.plan.actions
        if self.current is not None:
            return f"action {self.current + 1}/{len(actions)}: {actions[self.current]}"
        if self.done == len(actions):
            return "the final check"
        if self.done == 0:
            return "the run's start, after the plan was made, before its first action"
        return f"between actions {self.done}/{len(actions)}"


def _stop(driver: Driver) -> None:
    """Tell every module to stop (an empty command set); the driver disconnects next."""
    if driver.is_connected:
        driver.send_action({})


def _deadline_growth(prepared: PreparedRun, driver: GuardedDriver
                     ) -> Callable[[float], None] | None:
    """What moves the run's default deadlines when a phase is granted more time, never
    past :data:`~msrr.core.scenario.MAX_TIME` (a controller that says it needs a year
    does not make a run endless); ``None`` when the user set both."""
    driver_time = 1.0 if prepared.deadline_grows else 0.0
    wall_time = WALL_FACTOR if prepared.wall_deadline_grows else 0.0
    if not (driver_time or wall_time):
        return None

    def grow(seconds: float) -> None:
        driver.extend(min(driver_time * seconds, max(MAX_TIME - driver.deadline, 0.0)),
                      min(wall_time * seconds, max(MAX_TIME - driver.wall_deadline, 0.0)))
    return grow


@contextmanager
def _driver_for(prepared: PreparedRun, progress: _Progress,
                stuck: Callable[[str], None] | None = None) -> Iterator[GuardedDriver]:
    """The run's driver, wrapped: faults (if any) inside, the guard outside, its calls
    watched (:class:`~msrr.core.watchdog.Watchdog`; ``stuck`` is its last resort);
    stopped and disconnected on the way out whatever happens."""
    run = prepared.run
    inner: Driver = prepared.driver(gui=prepared.gui, seed=run.seed,
                                    **dict(prepared.driver_options))
    if prepared.faults:
        inner = FaultyDriver(inner, prepared.faults, seed=run.seed, on_fault=progress.on_fault)
    driver = GuardedDriver(inner, deadline=prepared.deadline,
                           wall_deadline=prepared.wall_deadline, on_fault=progress.on_fault)
    with Watchdog(driver, stall=prepared.stall, last_resort=stuck):
        try:
            driver.connect()
            yield driver
        finally:
            with shielded(raise_deferred=False):
                try:
                    _stop(driver)
                finally:
                    driver.disconnect()


def _goal_layout(prepared: PreparedRun, goal: Configuration) -> dict[str, Pose] | None:
    """Where the robot's own driver places ``goal`` (a fresh, fault-free driver)."""
    run = prepared.run
    # a driver that cannot place modules (``link``) names the simulator that lays them out
    layout = prepared.driver.layout
    factory, options = ((layout, {}) if layout is not None
                        else (prepared.driver, dict(prepared.driver_options)))
    with factory(gui=False, seed=run.seed, **options) as driver:
        driver.reset(goal)
        return dict(poses_seen(driver)) or None


def _recognized_plan(prepared: PreparedRun, driver: Driver) -> Plan:
    """The run's plan from the configuration the recognizer reports at the first tick
    (docs/freesn.md: a run recognizes and matches itself); the plan made from the file
    when that is the state it started from (the same modules, connections and vectors,
    within :data:`SAME_STATE_RESOLUTION`: the planner's input, up to connection labels;
    the file's module positions are where the lab laid them, which no report shows); a
    saved plan as it is.

    Raises:
        PlanningError: the recognized start cannot reach a goal (the run stops there).
    """
    run = prepared.run
    if prepared.planner is None:
        return run.plan
    seen = prepared.recognizer.recognize(driver.get_observation().sensors, seed=run.seed)
    if seen.same_state(run.plan.start, tolerance=SAME_STATE_RESOLUTION, positions=False):
        return run.plan
    seen.name, seen.description = run.plan.start.name, "as recognized at the first tick"
    return plan_stages(prepared.capabilities, prepared.planner, seen, prepared.stages,
                       seed=run.seed)


def execute_run(prepared: PreparedRun, *,
                last_resort: Callable[[RunResult], None] | None = None) -> RunResult:
    """Execute ``prepared.run.plan`` on a fresh driver; fires every run event.

    Never raises for what happens during the run: a failed action, an error of the
    driver or controller, a fault, a deadline or a driver call that does not return
    (the watchdog, :mod:`msrr.core.watchdog`) all end in a :class:`RunResult` with
    ``success=False`` and a one-line reason, after the modules were told to stop. An
    :class:`~msrr.core.interrupts.Interrupted` (or ``KeyboardInterrupt``) is re-raised
    after that clean-up, carrying the result as ``exc.result``. ``msrr_on_run_end``
    is always fired, so listeners close their files.

    Args:
        prepared: from :func:`prepare_run`.
        last_resort: called, from the watchdog's thread, with the failed result (its
            listeners already told the run ended) when the driver did not let go of the
            main thread even after the watchdog interrupted it; it should write the
            files and end the process (``platform run`` does). ``None``: keep waiting.
    """
    run = prepared.run
    progress = _Progress(run, plugins.emit)
    result = RunResult(success=False, reason="did not start", actions_total=len(run.plan.actions))
    started = False

    def stuck(reason: str) -> None:  # the watchdog's thread; the main thread is lost
        assert last_resort is not None
        ended = _failed(result, progress, f"stopped during {progress.where()}: {reason}; "
                        "the driver did not let go")
        ended.faults = list(progress.faults)
        _end_listeners(prepared, progress, ended, start=not started)
        last_resort(ended)

    try:
        with _driver_for(prepared, progress, stuck if last_resort else None) as driver:
            driver.reset(run.plan.start)
            placed = run.plan.start   # as the lab lays the modules out from the file
            run.plan = _recognized_plan(prepared, driver)
            result.actions_total = len(run.plan.actions)
            judge = Judge(run, driver, layout=lambda goal: _goal_layout(prepared, goal),
                          tolerance=run.spec.defaults.shape_tolerance)
            progress.listeners = (judge, *progress.listeners)
            progress.driver = driver
            executor = Executor(run, driver, prepared.recognizer, prepared.controller,
                                prepared.options, sink=progress,
                                robot=prepared.capabilities.robot,
                                controllers=prepared.capabilities.controllers,
                                on_grant=_deadline_growth(prepared, driver), placed=placed)
            result = executor.result  # its counts are kept on every way out
            progress.run_start(run)
            started = True
            try:
                executor.execute()
            finally:
                result.simulator = driver.constraint_events()
            judge.conclude(result)
    except (Interrupted, KeyboardInterrupt) as exc:
        name = exc.name if isinstance(exc, Interrupted) else "SIGINT"
        result = _failed(result, progress, f"interrupted during {progress.where()} ({name})")
        result.interrupted = name
        exc.result = result  # type: ignore[union-attr]
        raise
    except MsrrError as exc:
        result = _failed(result, progress, f"stopped during {progress.where()}: {exc}")
    except Exception as exc:  # a driver's or controller's bug must not lose the run
        result = _failed(result, progress, f"stopped during {progress.where()}: "
                         f"{type(exc).__name__}: {exc}")
    finally:
        result.faults = list(progress.faults)
        _end_listeners(prepared, progress, result, start=not started)
    return result


def _end_listeners(prepared: PreparedRun, listeners: EventSink, result: RunResult, *,
                   start: bool) -> None:
    """Fire ``msrr_on_run_end`` (and ``msrr_on_run_start`` first, when ``start``: the run
    stopped before it started), so listeners close their files. A listener that fails
    there (the recording on a full disk) is noted in ``prepared.problems`` and its
    partial recording removed; the run's result stands."""
    run = prepared.run
    with shielded(raise_deferred=False):
        try:
            if start:
                listeners.run_start(run)
            listeners.run_end(run, result)
        except MsrrError as exc:
            prepared.problems.append(_recording_lost(run, exc))


def _recording_lost(run: Run, exc: MsrrError) -> str:
    """The line saying the recording could not be finished; its ``.part`` file removed."""
    if run.recording is None:
        return f"the run's end failed: {exc}"
    part = run.recording.with_name(run.recording.name + ".part")
    removed = part.exists()
    part.unlink(missing_ok=True)
    cause = str(exc)
    try:
        if shutil.disk_usage(run.recording.parent).free < 1 << 20:
            cause = "its disk is full"
    except OSError:
        pass
    return (f"the recording {run.recording} could not be written ({cause})"
            + (f"; removed {part.name}" if removed else ""))


def interrupted_result(prepared: PreparedRun, exc: BaseException) -> RunResult:
    """The result of a run interrupted before :func:`execute_run` could say where; fires
    ``msrr_on_run_start`` and ``msrr_on_run_end`` so listeners still write their files."""
    name = exc.name if isinstance(exc, Interrupted) else "SIGINT"
    run = prepared.run
    result = RunResult(success=False, reason=f"interrupted after the plan was made, before "
                       f"the run started ({name})",
                       actions_total=len(run.plan.actions), interrupted=name)
    _end_listeners(prepared, plugins.emit, result, start=True)
    return result


def _failed(result: RunResult, progress: _Progress, reason: str) -> RunResult:
    """``result`` marked failed with ``reason``, counted from what ``progress`` saw."""
    result.success = False
    result.reason = " ".join(reason.split())
    result.actions_done = max(result.actions_done, progress.done)
    if progress.current is not None:
        result.failed_action = progress.current
    return result


def _finite(value: object) -> object:
    """``value`` with every non-finite float replaced by ``None`` (JSON has no NaN)."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_finite(v) for v in value]
    return value


def write_outputs(run: Run, result: RunResult) -> None:
    """Write ``plan.json`` and ``summary.json`` into ``run.out_dir`` (signals deferred,
    so an interruption cannot leave one without the other; a failed write leaves
    neither).

    Raises:
        OutputError: a file could not be written (a full disk); one line naming it.
    """
    if run.out_dir is None:
        raise ExecutionError("run has no output folder")
    recorded = run.recording is not None and run.recording.is_file()
    summary = {"robot": run.robot, "scenario": run.scenario, "planner": run.plan.planner,
               "driver": run.driver, "seed": run.seed, "rate_hz": run.rate,
               "planned_docks": run.plan.docks, "planned_undocks": run.plan.undocks,
               "planned_flows": run.plan.flows,
               "recording": run.recording.name if recorded and run.recording else None,
               **result.summary()}
    text = json.dumps(_finite(summary), indent=2, allow_nan=False) + "\n"
    with shielded():
        plan_path = run.out_dir / "plan.json"
        try:
            save_plan(run.plan, plan_path)
            atomic_write_text(run.out_dir / "summary.json", text)
        except OutputError:
            plan_path.unlink(missing_ok=True)  # both files or neither
            raise
