"""``platform run``: plan and execute a reconfiguration, record it to rerun.

Like every command module, it imports the run machinery (simulators, rerun, numpy) in
the command's body, not at module level, so ``platform run --help`` starts at once.
"""

from __future__ import annotations

import math
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import click
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from ... import plugins
from ...console import (
    check_display,
    console,
    err_console,
    plural,
    run_selection_options,
    table,
)
from ...errors import ConfigurationError, MsrrError, one_line
from ...hookspecs import hookimpl
from ...interrupts import Interrupted, handled, shielded

if TYPE_CHECKING:
    from ...events import (
        ActionStatus,
        BehaviorVerdict,
        FaultEvent,
        GoalVerdict,
        Run,
        RunResult,
        Tick,
        TopologyEvent,
    )
    from ...plan import Action, Plan
    from ..run import PreparedRun

__all__ = ["command"]


class _ProgressListener:
    """An event listener (a plugin like any other) that shows where the run is: a rich
    progress bar at a terminal; without one (a pipe, a log file), one line per action and
    one at least every :data:`PROGRESS_EVERY` seconds of wall time."""

    def __init__(self, progress: Progress | None, total: int):
        self.progress = progress
        self.total = total
        self.task = None if progress is None else progress.add_task("starting", total=total)
        self.started = self.said = time.monotonic()
        self.done = 0
        self.current = "starting"
        self.sim_time = 0.0
        self.finished = 0.0        # wall time [s] from the start to the last action done
        self.action_wall = 0.0     # wall time [s] from the start when this action began
        self.action_sim = 0.0      # simulated time [s] when this action began
        self.duration: float | None = None   # this action's behavior duration [s]

    def _say(self, text: str) -> None:
        if self.progress is not None:
            self.progress.console.print(text, markup=False)
        else:
            console.print(text, markup=False, soft_wrap=True)

    def _status(self) -> str:
        elapsed = time.monotonic() - self.started
        behind = None if self.duration is None else \
            self.duration - (self.sim_time - self.action_sim)
        ran = self.sim_time - self.action_sim   # this action's rate (no planning in it),
        wall_per_sim = (elapsed - self.action_wall) / ran if ran > 0 else \
            elapsed / self.sim_time if self.sim_time > 0 else None   # else the run's
        left = time_left(done=self.done, total=self.total, finished=self.finished,
                         in_action=elapsed - self.action_wall, behavior_left=behind,
                         wall_per_sim=wall_per_sim)
        return (f"action {min(self.done + 1, self.total)}/{self.total}: {self.current} "
                f"(simulated {self.sim_time:.1f} s, wall {elapsed:.0f} s{left})")

    @hookimpl
    def msrr_on_action(self, run: Run, action: Action, status: ActionStatus) -> None:
        self.current = str(action)
        if status == "succeeded":  # ActionStatus.SUCCEEDED, a str enum
            self.done += 1
            self.finished = time.monotonic() - self.started
        elif status == "started":
            self.action_wall, self.action_sim = time.monotonic() - self.started, self.sim_time
            self.duration = None if action.behavior is None else action.behavior.duration
        if self.progress is not None:
            self.progress.update(self.task, description=f"{action} ({status})")
            if status == "succeeded":
                self.progress.advance(self.task)
        elif status == "started":
            self._say(self._status())
            self.said = time.monotonic()

    @hookimpl
    def msrr_on_tick(self, run: Run, tick: Tick) -> None:
        self.sim_time = tick.time
        if self.progress is None and time.monotonic() - self.said >= PROGRESS_EVERY:
            self._say(self._status())
            self.said = time.monotonic()

    @hookimpl
    def msrr_on_topology_change(self, run: Run, change: TopologyEvent) -> None:
        self._say(f"  {change} at t={change.time:.1f} s")

    @hookimpl
    def msrr_on_fault(self, run: Run, fault: FaultEvent) -> None:
        self._say(f"  fault {fault}")


PROGRESS_EVERY = 10.0
"""Without a terminal, a progress line at least this often [s of wall time]."""


def time_left(*, done: int, total: int, finished: float, in_action: float,
              behavior_left: float | None, wall_per_sim: float | None) -> str:
    """How much wall time the run likely still takes, as the progress line says it: the
    action running now, then each one after it at the mean wall time of those done
    (``finished`` [s] over ``done``); empty when nothing is known yet.

    The running action's share is what its behavior has left of its duration
    (``behavior_left``, simulated [s]) at the run's wall time per simulated second, when
    it has a duration; otherwise the mean action's time less what it ran already
    (``in_action`` [s]). An action that has run longer than the mean has no estimate:
    then only the time after it is said.
    """
    mean = finished / done if done else None
    after = max(total - done - 1, 0)
    later = None if after and mean is None else (mean or 0.0) * after
    if behavior_left is not None and wall_per_sim is not None:
        current: float | None = max(behavior_left, 0.0) * wall_per_sim
    elif mean is not None and in_action <= mean:
        current = mean - in_action
    else:
        current = None
    if later is None:
        return ""
    if current is None:
        if mean is None:
            return ""
        return ", this action longer than the mean" + (
            f", about {later:.0f} s after it" if after else ", the last")
    return f", about {current + later:.0f} s left"


def _verdict(ok: bool) -> str:
    return "yes" if ok else "NO"


def _goal_row(goal: GoalVerdict) -> list[object]:
    where = "at the end" if goal.action_index is None else f"at t={goal.time:.1f} s"
    shape = ("; shape not measured (the driver reports no connection vectors and the robot "
             "declares no shape_tolerance)" if goal.shape is None else f"; shape {goal.shape}")
    text = (f"reached {where}: topology {_verdict(goal.topology)}{shape}; judged on "
            f"{goal.basis}" if goal.success else goal.reason)
    return [f"goal {goal.name}", text]


def _behavior_row(moved: BehaviorVerdict) -> list[object]:
    along = "" if moved.along is None else \
        f", {round(moved.along, 3) + 0.0:.3f} m along the commanded direction"
    covered = moved.along if moved.along is not None else moved.distance
    asked = "" if moved.asked is None else \
        f" ({covered / moved.asked:.0%} of the {moved.asked:.3f} m asked)"
    heading = "" if moved.heading_error is None else \
        f", heading error {math.degrees(moved.heading_error):.1f} deg"
    text = f"{moved.distance:.3f} m in {moved.duration:.1f} s{along}{asked}{heading}"
    return [f"behavior {moved.name}", f"{text}; {'passes' if moved.success else 'FAILS'}"]


def _summary(result: RunResult, planned_docks: int, planned_undocks: int,
             planned_flows: int = 0) -> Table:
    """The run's numbers: counts recognized from the modules' reports, the simulator's
    own count where it has one, and the judge's verdicts."""
    rows: list[list[object]] = [
        ["actions", f"{result.actions_done}/{result.actions_total}"
         + (f" ({result.actions_skipped} skipped: distance covered)"
            if result.actions_skipped else "")],
        ["docks recognized", f"{result.docks} (planned {planned_docks})"],
        ["undocks recognized", f"{result.undocks} (planned {planned_undocks})"],
        *([["flows recognized", f"{result.flows} (planned {planned_flows})"]]
          if planned_flows or result.flows else []),
        *([["simulator's own count", ", ".join(
            f"{n} {kind}s" for kind, n in result.simulator.items())
            + " (constraint switches; a docked weld kept across a flow counts once)"]]
          if result.simulator else []),
        ["retries", result.retries],
        ["ticks", result.ticks],
        ["simulated time", f"{result.sim_time:.1f} s"],
        ["wall time", f"{result.wall_time:.1f} s"],
        *(_goal_row(goal) for goal in result.targets),
        *([_goal_row(result.goal)]  # the run's goal, unless its last stage's row says it
          if result.goal is not None and result.goal not in result.targets else []),
        *(_behavior_row(moved) for moved in result.locomotion),
    ]
    if result.faults:
        rows.append(["faults", len(result.faults)])
    rows.extend(["settled, not reached", line] for line in result.settled)
    rows.extend(["broke, re-docked", line] for line in result.redocked)
    if result.timed_out_steps:
        rows.append(["gait steps ended on time, not reached", result.timed_out_steps])
    rows.append(["success", "yes" if result.success else "no"])
    return table("Run summary", ["", "value"], rows)


def _asked(plan: Plan) -> str:
    """What the user asked for, in order: ``start -> goal -> behavior -> goal``."""
    steps = [plan.start.name or "start"]
    for index, action in enumerate(plan.actions):
        call = action.behavior
        if call is not None and (index == 0 or plan.actions[index - 1].behavior is None
                                 or plan.actions[index - 1].behavior.name != call.name):
            steps.append(str(call))
        if action.reaches:
            steps.append(action.reaches)
    if len(steps) == 1:
        steps.append(plan.goal.name or "goal")
    return " -> ".join(steps)


@click.command("run")
@run_selection_options
@click.option("--planner", "planner_name", default=None,
              help="Planner name; default the robot's first registered planner.")
@click.option("--driver", "driver_name", default=None,
              help="Driver name; default the robot's first registered driver.")
@click.option("--seed", default=0, show_default=True,
              help="Seed of planning, recognition and injected faults (>= 0).")
@click.option("--out", default=None, metavar="DIR",
              help="Output folder [default: runs/<timestamp>-<robot>-<scenario>, never shared].")
@click.option("--force", is_flag=True, help="Replace a run already in --out.")
@click.option("--no-log", is_flag=True, help="Do not write the rerun recording.")
@click.option("--gui", is_flag=True, help="Open the simulator's window (needs a display).")
@click.option("--rate", default=10.0, show_default=True, help="Control rate [Hz], at most 1000.")
@click.option("--timeout", "action_timeout", default=90.0, show_default=True,
              help="Driver time one action phase may take before a retry [s], beyond "
                   "what its controller says it needs; finite.")
@click.option("--deadline", default=None, type=float,
              help="Driver time the whole run may take [s]; default (actions + 1) x --timeout "
                   "plus the behaviors' durations and the time the controller says its "
                   "phases need.")
@click.option("--wall-deadline", default=None, type=float,
              help="Wall time the run's execution may take [s]; default 600 + 20 x --deadline.")
@click.option("--stall", default=30.0, type=float, show_default=True,
              help="Wall time one call of the driver may take before the run stops [s] (a "
                   "driver that stops answering).")
@click.option("--faults", default="", metavar="SPEC",
              help="Inject faults, e.g. 'dropout:module=3,at=5;loss:p=0.05;latency:ticks=2;"
                   "dock-fail:count=1;noise:sigma=0.01;nan:at=3' (see docs/running.md).")
@click.option("--driver-option", "driver_options", multiple=True, metavar="KEY=VALUE",
              help="Keyword option of the driver, repeatable (FreeSN mujoco: noise=0.035 "
                   "[rad], slip=0.05); each driver's options, types and bounds: `platform "
                   "robots --options`.")
@click.option("--system", "system_file", default=None,
              metavar="FILE", help="Systems file of the modules for --driver link (implies it; "
                                   "see docs/hardware.md).")
@click.option("--behavior", default=None, metavar="NAME",
              help="Run a behavior of the robot's library after the goal (or from the start "
                   "without --to): the path to its start is retrieved, then it runs.")
@click.option("--param", "parameters", multiple=True, metavar="NAME=VALUE",
              help="A parameter of the behavior, repeatable (speed=0.05 [m/s], yaw_rate=0 "
                   "[rad/s]).")
@click.option("--duration", default=None, type=float,
              help="How long a mapping behavior runs [s of simulated time; default 30].")
@click.option("--loops", default=None, type=int,
              help="How many loops of a sequence behavior run [default 1; with --distance, "
                   "at most this many].")
@click.option("--distance", default=None, type=float,
              help="Stop the behavior once the system's centre moved this far [m].")
@click.option("--plan", "plan_file", type=click.Path(path_type=Path), default=None,
              metavar="FILE", help="Execute a saved plan (platform plan --json, or a run's "
                                   "plan.json) instead of planning; validated on load.")
def command(robot: str, scenario: str | None, start: Path | None, goal: Path | None,
            planner_name: str | None, driver_name: str | None, seed: int, out: str | None,
            force: bool, no_log: bool, gui: bool, rate: float, action_timeout: float,
            deadline: float | None, wall_deadline: float | None, stall: float, faults: str, driver_options: tuple[str, ...],
            system_file: str | None, behavior: str | None, parameters: tuple[str, ...],
            duration: float | None, loops: int | None, distance: float | None,
            plan_file: Path | None) -> None:
    """Plan and execute a reconfiguration in simulation and record it.

    Writes DIR/run.rrd, DIR/plan.json and DIR/summary.json, also when the run fails,
    meets a fault or is interrupted. Exits 1 with the failing action named if the plan
    cannot be finished, 130 on SIGINT (Ctrl-C) and 143 on SIGTERM.
    """
    if gui:
        check_display("--gui")  # before any work: one line, not a simulator's traceback
    from ..run import (
        RunRequest,
        interrupted_result,
        parse_driver_options,
        parse_parameters,
        prepare_run,
    )

    with handled():
        try:
            if out is not None and not out.strip():
                raise ConfigurationError("is empty; give a folder", field="--out")
            if system_file is not None:
                if not system_file.strip():
                    raise ConfigurationError("is empty; give the systems file of the modules",
                                             field="--system")
                if driver_name not in (None, "link"):
                    raise ConfigurationError(f"is the link driver's systems file; --driver "
                                             f"{driver_name} takes none (leave --driver out, "
                                             "or give --driver link)", field="--system")
                driver_name = "link"
            request = RunRequest(robot=robot, scenario=scenario, start=start, goal=goal, seed=seed,
                                 out=None if out is None else Path(out), log=not no_log, gui=gui,
                                 rate=rate, action_timeout=action_timeout, driver=driver_name,
                                 planner=planner_name,
                                 driver_options=parse_driver_options(driver_options)
                                 + ((("system", Path(system_file)),) if system_file else ()),
                                 force=force, faults=faults, deadline=deadline,
                                 wall_deadline=wall_deadline, stall=stall, plan=plan_file,
                                 behavior=behavior, parameters=parse_parameters(parameters),
                                 duration=duration, loops=loops, distance=distance)
            prepared = prepare_run(request)
        except (Interrupted, KeyboardInterrupt) as exc:
            code = exc.exit_code if isinstance(exc, Interrupted) else 130
            name = exc.name if isinstance(exc, Interrupted) else "SIGINT"
            err_console.print(f"Error: interrupted ({name}) during start-up, before the plan was "
                              "made; nothing was run", markup=False)
            raise SystemExit(code) from None
        try:
            result = _execute(prepared)
        except (Interrupted, KeyboardInterrupt) as exc:
            result = getattr(exc, "result", None) or interrupted_result(prepared, exc)
            with shielded(raise_deferred=False):
                problems = _write(prepared, result)
                wrote = "; ".join(problems) if problems else f"wrote {prepared.run.out_dir}"
                err_console.print(f"Error: {one_line(f'{result.reason}; {wrote}')}",
                                  markup=False, soft_wrap=True)
            raise SystemExit(exc.exit_code if isinstance(exc, Interrupted) else 130) from None
        run = prepared.run
        problems = _write(prepared, result)
        console.print(_summary(result, run.plan.docks, run.plan.undocks, run.plan.flows))
        assert run.out_dir is not None
        if (run.out_dir / "summary.json").is_file():
            console.print(f"wrote {run.out_dir / 'plan.json'}, {run.out_dir / 'summary.json'}",
                          markup=False)
        if run.recording is not None and run.recording.is_file():
            console.print(f"open the recording with: rerun {run.recording}", markup=False)
        if problems or not result.success:
            reason = [] if result.success else [result.reason]
            err_console.print(f"Error: {one_line('; '.join(reason + problems))}",
                              soft_wrap=True, markup=False)
            raise SystemExit(1)


def _write(prepared: PreparedRun, result: RunResult) -> list[str]:
    """Write ``plan.json`` and ``summary.json``; every file that could not be written
    (the recording's failure included), one line each."""
    from ..run import write_outputs

    problems = list(prepared.problems)
    try:
        write_outputs(prepared.run, result)
    except MsrrError as exc:  # a full disk: neither file is left
        problems.append(str(exc))
    return problems


def _execute(prepared: PreparedRun) -> RunResult:
    from ..run import execute_run

    run, plan = prepared.run, prepared.run.plan
    for note in prepared.notes:
        err_console.print(f"note: {note}", markup=False)
    console.print(f"{run.robot} {run.scenario}: {_asked(plan)}; "
                  f"{plural(len(plan.actions), 'action')} by {plan.planner} "
                  f"({plural(plan.undocks, 'undock')}, {plural(plan.docks, 'dock')}"
                  + (f"; {plural(plan.flows, 'flow')}" if plan.flows else "")
                  + f"), driver {run.driver}"
                  + (f", faults {'; '.join(map(str, prepared.faults))}" if prepared.faults else ""),
                  markup=False)
    last_resort = _stuck(prepared)
    if not console.is_terminal:  # a pipe or a log: plain lines, never a minute of silence
        with plugins.temporary(_ProgressListener(None, len(plan.actions))):
            return execute_run(prepared, last_resort=last_resort)
    progress = Progress(TextColumn("{task.description}", markup=False), BarColumn(),
                        TextColumn("{task.completed}/{task.total} actions"),
                        TimeElapsedColumn(), console=console, transient=True)
    with progress, plugins.temporary(_ProgressListener(progress, len(plan.actions))):
        return execute_run(prepared, last_resort=last_resort)


def _stuck(prepared: PreparedRun) -> Callable[[RunResult], None]:
    """The last resort of a run whose driver never lets go of the main thread (called
    from the watchdog's thread): write the files, say so in one line, end the process."""
    def end(result: RunResult) -> None:
        try:
            problems = _write(prepared, result)
            wrote = "; ".join(problems) if problems else f"wrote {prepared.run.out_dir}"
            sys.stdout.flush()
            sys.stderr.write(f"Error: {one_line(f'{result.reason}; {wrote}')}\n")
            sys.stderr.flush()
        finally:
            os._exit(1)
    return end
