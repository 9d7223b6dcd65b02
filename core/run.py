"""Orchestration of ``platform run``: scenario -> plan -> execute -> files.

:func:`prepare_run` loads and checks the two configurations, resolves the robot's
driver, controller, recognizer and planner once (a :class:`PreparedRun`) and plans;
:func:`execute_run` runs that on a fresh driver; :func:`write_outputs` writes the
files. Planning happens before anything is written, so an unreachable goal (different
module counts, an illegal face pair) fails with a one-line error and leaves no
folder and no half recording. A run writes into its folder:

* ``run.rrd`` -- the rerun recording (via the timeline plugin), unless ``log=False``;
* ``plan.json`` -- the executed plan (:func:`msrr.core.plan.save_plan`);
* ``summary.json`` -- the :class:`~msrr.core.events.RunResult` numbers.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

from . import plugins
from .capabilities import Controller, DriverFactory, Recognizer
from .errors import ConfigurationError, ExecutionError, MsrrError, UnknownNameError
from .events import Run, RunResult
from .executor import Executor, ExecutorOptions
from .files import atomic_write_text
from .plan import Plan, save_plan
from .scenario import Scenario

__all__ = ["PreparedRun", "RunRequest", "default_out_dir", "execute_run", "parse_driver_options", "prepare_run",
           "resolve_scenario", "write_outputs"]


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
        driver_options: extra keyword options of the driver factory (``noise``, ``slip``).
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
    driver_options: tuple[tuple[str, float | int | bool | str], ...] = ()


def resolve_scenario(robot: str, name: str | None) -> Scenario:
    """The scenario ``name`` of ``robot``, or its default one."""
    found = plugins.scenarios(robot)
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


def parse_driver_options(items: tuple[str, ...] | list[str]
                         ) -> tuple[tuple[str, float | int | bool | str], ...]:
    """``("noise=0.035", "slip=0.05")`` -> ``(("noise", 0.035), ("slip", 0.05))``: numbers
    and ``true``/``false`` are converted, anything else stays a string.

    Raises:
        ConfigurationError: an item without ``=``.
    """
    out: list[tuple[str, float | int | bool | str]] = []
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not key:
            raise ConfigurationError(f"driver option {item!r} is not KEY=VALUE")
        value: float | int | bool | str = text
        if text.lower() in ("true", "false"):
            value = text.lower() == "true"
        else:
            for kind in (int, float):
                try:
                    value = kind(text)
                    break
                except ValueError:
                    continue
        out.append((key.strip(), value))
    return tuple(out)


def default_out_dir(robot: str, scenario: str, root: Path = Path("runs")) -> Path:
    """``runs/<YYYYmmdd-HHMMSS>-<robot>-<scenario>``."""
    return root / f"{datetime.now():%Y%m%d-%H%M%S}-{robot}-{scenario}"


@dataclass(frozen=True)
class PreparedRun:
    """A planned run and the capabilities that will execute it, each resolved once.

    Attributes:
        run: the event payload (robot, scenario, plan, output paths).
        driver: factory of the driver, called as ``driver(gui=..., seed=...)``.
        recognizer: the robot's recognizer.
        controller: the robot's controller.
        options: rate and action timeout of the executor.
        gui: open the simulator's window.
        driver_options: extra keyword options of the driver factory.
    """

    run: Run
    driver: DriverFactory
    recognizer: Recognizer
    controller: Controller
    options: ExecutorOptions
    gui: bool = False
    driver_options: tuple[tuple[str, float | int | bool | str], ...] = ()


def prepare_run(request: RunRequest) -> PreparedRun:
    """Load the configurations, resolve the capabilities and plan; nothing is written.

    Raises:
        ConfigurationError: a file is missing or invalid.
        PlanningError: the goal cannot be reached.
        UnknownNameError: unknown scenario, planner or driver, or the robot has no
            recognizer or controller.
    """
    spec = plugins.robot(request.robot)
    if (request.start is None) != (request.goal is None):
        raise ConfigurationError("give both --from and --to, or neither")
    if request.start is not None and request.goal is not None:
        if request.scenario is not None:
            raise ConfigurationError("give --scenario or --from/--to, not both")
        name, start_path, goal_path = "custom", request.start, request.goal
    else:
        scenario = resolve_scenario(request.robot, request.scenario)
        name, start_path, goal_path = scenario.name, scenario.start, scenario.goal
    start = plugins.load_configuration(start_path)
    goal = plugins.load_configuration(goal_path)
    for config, path in ((start, start_path), (goal, goal_path)):
        if config.robot != request.robot:
            raise ConfigurationError(f"is a {config.robot!r} configuration, not "
                                     f"{request.robot!r}", source=str(path))
    factory = plugins.drivers.get(request.robot, request.driver)
    # a driver may name the recognizer and controller that read and command it (the
    # generic kinematic driver does); otherwise the robot's first ones
    companions = getattr(factory, "companions", {})
    controller = plugins.controllers.get(request.robot, companions.get("controller"))
    recognizer = plugins.recognizers.get(request.robot, companions.get("recognizer"))
    planner = plugins.planners.get(request.robot, request.planner)
    options = ExecutorOptions(rate=request.rate, action_timeout=request.action_timeout)
    plan: Plan = planner.plan(start, goal, seed=request.seed)
    out = request.out or default_out_dir(request.robot, name)
    run = Run(robot=request.robot, scenario=name, plan=plan, spec=spec, driver=factory.name,
              rate=request.rate, seed=request.seed, out_dir=out,
              recording=out / "run.rrd" if request.log else None)
    return PreparedRun(run, factory, recognizer, controller, options, request.gui,
                       request.driver_options)


def execute_run(prepared: PreparedRun) -> RunResult:
    """Execute ``prepared.run.plan`` on a fresh driver; fires every run event.

    The run always ends with ``msrr_on_run_end`` (also when interrupted), so
    listeners close their files.
    """
    run = prepared.run
    with prepared.driver(gui=prepared.gui, seed=run.seed,
                         **dict(prepared.driver_options)) as driver:
        driver.reset(run.plan.start)
        executor = Executor(run, driver, prepared.recognizer, prepared.controller,
                            prepared.options)
        plugins.emit.run_start(run)
        result = RunResult(success=False, reason="interrupted",
                           actions_total=len(run.plan.actions))
        try:
            result = executor.execute()
        except MsrrError as exc:
            result.reason = str(exc)
            raise
        except BaseException as exc:
            result.reason = f"interrupted: {type(exc).__name__}"
            raise
        finally:
            plugins.emit.run_end(run, result)
    return result


def write_outputs(run: Run, result: RunResult) -> None:
    """Write ``plan.json`` and ``summary.json`` into ``run.out_dir``."""
    if run.out_dir is None:
        raise ExecutionError("run has no output folder")
    save_plan(run.plan, run.out_dir / "plan.json")
    summary = {"robot": run.robot, "scenario": run.scenario, "planner": run.plan.planner,
               "driver": run.driver, "seed": run.seed, "rate_hz": run.rate,
               "planned_docks": run.plan.docks, "planned_undocks": run.plan.undocks,
               "recording": None if run.recording is None else run.recording.name,
               **result.summary()}
    atomic_write_text(run.out_dir / "summary.json", json.dumps(summary, indent=2) + "\n")
