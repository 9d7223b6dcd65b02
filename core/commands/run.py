"""``platform run``: plan and execute a reconfiguration, record it to rerun."""

from __future__ import annotations

from pathlib import Path

import click
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from .. import plugins
from ..console import console, err_console, table
from ..events import ActionStatus, Run, RunResult, TopologyEvent
from ..hookspecs import hookimpl
from ..plan import Action
from ..run import RunRequest, execute_run, parse_driver_options, prepare_run, write_outputs

__all__ = ["command"]


class _ProgressListener:
    """An event listener (a plugin like any other) that drives a rich progress bar."""

    def __init__(self, progress: Progress, total: int):
        self.progress = progress
        self.task = progress.add_task("starting", total=total)

    @hookimpl
    def msrr_on_action(self, run: Run, action: Action, status: ActionStatus) -> None:
        self.progress.update(self.task, description=f"{action} [dim]{status}[/dim]")
        if status == ActionStatus.SUCCEEDED:
            self.progress.advance(self.task)

    @hookimpl
    def msrr_on_topology_change(self, run: Run, change: TopologyEvent) -> None:
        self.progress.console.print(f"  {change} at t={change.time:.1f} s")


def _summary(result: RunResult, planned_docks: int, planned_undocks: int) -> Table:
    rows: list[list[object]] = [
        ["actions", f"{result.actions_done}/{result.actions_total}"],
        ["docks", f"{result.docks} (planned {planned_docks})"],
        ["undocks", f"{result.undocks} (planned {planned_undocks})"],
        ["retries", result.retries],
        ["simulated time", f"{result.sim_time:.1f} s"],
        ["wall time", f"{result.wall_time:.1f} s"],
        ["success", "[green]yes[/green]" if result.success else "[red]no[/red]"],
    ]
    return table("Run summary", ["", "value"], rows)


@click.command("run")
@click.option("--robot", required=True, help="Robot name (see `platform robots`).")
@click.option("--scenario", default=None, help="Scenario name; default: the robot's default.")
@click.option("--from", "start", type=click.Path(path_type=Path), default=None,
              help="Start configuration file (with --to, instead of a scenario).")
@click.option("--to", "goal", type=click.Path(path_type=Path), default=None,
              help="Goal configuration file.")
@click.option("--planner", "planner_name", default=None,
              help="Planner name; default the robot's first registered planner.")
@click.option("--driver", "driver_name", default=None,
              help="Driver name; default the robot's first registered driver.")
@click.option("--seed", default=0, show_default=True, help="Seed of planning and recognition.")
@click.option("--out", type=click.Path(path_type=Path), default=None,
              help="Output folder [default: runs/<timestamp>-<robot>-<scenario>].")
@click.option("--no-log", is_flag=True, help="Do not write the rerun recording.")
@click.option("--gui", is_flag=True, help="Open the simulator's window (needs a display).")
@click.option("--rate", default=10.0, show_default=True, help="Control rate [Hz].")
@click.option("--timeout", "action_timeout", default=90.0, show_default=True,
              help="Driver time one action phase may take before a retry [s].")
@click.option("--driver-option", "driver_options", multiple=True, metavar="KEY=VALUE",
              help="Keyword option of the driver, repeatable (FreeSN mujoco: noise=0.035 "
                   "[rad], slip=0.05, drift=..., see docs/freesn.md).")
def command(robot: str, scenario: str | None, start: Path | None, goal: Path | None,
            planner_name: str | None, driver_name: str | None, seed: int, out: Path | None,
            no_log: bool, gui: bool, rate: float, action_timeout: float,
            driver_options: tuple[str, ...]) -> None:
    """Plan and execute a reconfiguration in simulation and record it.

    Writes DIR/run.rrd, DIR/plan.json and DIR/summary.json. Exits 1 with the failing
    action named if the plan cannot be finished.
    """
    request = RunRequest(robot=robot, scenario=scenario, start=start, goal=goal, seed=seed,
                         out=out, log=not no_log, gui=gui, rate=rate,
                         action_timeout=action_timeout, driver=driver_name,
                         planner=planner_name,
                         driver_options=parse_driver_options(driver_options))
    prepared = prepare_run(request)
    run, plan = prepared.run, prepared.run.plan
    console.print(f"[bold]{robot}[/bold] {run.scenario}: {plan.start.name or 'start'} -> "
                  f"{plan.goal.name or 'goal'}, {len(plan.actions)} actions by {plan.planner} "
                  f"({plan.undocks} undocks, {plan.docks} docks), driver {run.driver}")
    progress = Progress(TextColumn("{task.description}"), BarColumn(),
                        TextColumn("{task.completed}/{task.total} actions"),
                        TimeElapsedColumn(), console=console, transient=True)
    with progress, plugins.temporary(_ProgressListener(progress, len(plan.actions))):
        result = execute_run(prepared)
    write_outputs(run, result)
    console.print(_summary(result, plan.docks, plan.undocks))
    assert run.out_dir is not None
    console.print(f"wrote {run.out_dir / 'plan.json'}, {run.out_dir / 'summary.json'}")
    if run.recording is not None:
        console.print(f"open the recording with: [bold]rerun {run.recording}[/bold]")
    if not result.success:
        err_console.print(f"Error: {result.reason}", soft_wrap=True)
        raise SystemExit(1)
