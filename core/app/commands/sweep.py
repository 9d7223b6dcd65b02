"""``platform sweep``: one scenario (or a ``--from/--to`` pair) over many seeds and faults.

Each run is ``platform run`` without the recording (:func:`msrr.core.app.run.prepare_run`,
:func:`msrr.core.app.run.execute_run` in a temporary folder), one batch task per
(fault setting, seed) (:mod:`msrr.core.app.batch`). Run ``k`` of a setting uses seed
``--seed + k``, so any row can be replayed with ``platform run --seed S --faults F``,
and the table is the same serially, on the pool and on Ray. Writes ``sweep.csv``
(one row per run) and ``sweep.png`` (distributions; needs matplotlib).
"""

from __future__ import annotations

import csv
import io
import math
import tempfile
from dataclasses import asdict, dataclass, fields
from datetime import datetime
from pathlib import Path
from typing import TYPE_CHECKING

import click

from ...console import (
    SEED,
    FiniteFloat,
    console,
    err_console,
    plural,
    run_selection_options,
    table,
)
from ...errors import ConfigurationError
from ..batch import batch_options, exit_on_interrupt, run_batch

if TYPE_CHECKING:
    from ..run import RunRequest

__all__ = ["SweepRow", "SweepTask", "command", "summarize", "sweep_csv", "sweep_run"]

MATPLOTLIB_HINT = "pip install 'msrr-platform[plot]'"


@dataclass(frozen=True)
class SweepTask:
    """One run of a sweep (the fields of :class:`~msrr.core.app.run.RunRequest` it sets)."""

    robot: str
    scenario: str | None
    start: str | None
    goal: str | None
    seed: int
    faults: str = ""
    driver: str | None = None
    planner: str | None = None
    rate: float = 10.0
    action_timeout: float = 90.0
    deadline: float | None = None
    driver_options: tuple[tuple[str, float | int | bool | str], ...] = ()

    @property
    def key(self) -> str:
        return f"{self.faults or 'none'}#seed{self.seed}"


@dataclass(frozen=True)
class SweepRow:
    """One run's outcome (a row of ``sweep.csv``); simulated time only, no wall time, so
    the table is a pure function of the inputs.

    Attributes:
        faults: the fault SPEC (``""``: none).
        seed: the run's seed.
        success: topology and (where declared) shape reached.
        reason: why not.
        actions_done, actions_total: actions finished and planned.
        docks, undocks, retries: as counted by the executor.
        sim_time_s: driver time at the end [s].
        position_rms_m, position_max_m, heading_max_rad: final pose errors against the
            goal layout (robots declaring a ``shape_tolerance``), else ``nan``.
        shape_error_deg: final RMS strut angle to the goal, ground truth where the driver
            has one, else recognized; ``nan`` when neither.
        faults_met: fault events during the run.
    """

    faults: str
    seed: int
    success: bool
    reason: str
    actions_done: int
    actions_total: int
    docks: int
    undocks: int
    retries: int
    sim_time_s: float
    position_rms_m: float
    position_max_m: float
    heading_max_rad: float
    shape_error_deg: float
    faults_met: int


def _nan(value: float | None, scale: float = 1.0) -> float:
    return math.nan if value is None else round(value * scale, 6)


def _request(task: SweepTask, folder: str) -> RunRequest:
    """The ``platform run`` request of ``task``: no recording, into ``folder``."""
    from ..run import RunRequest  # the run machinery loads when a run starts, not at --help

    return RunRequest(robot=task.robot, scenario=task.scenario,
                      start=None if task.start is None else Path(task.start),
                      goal=None if task.goal is None else Path(task.goal),
                      seed=task.seed, out=Path(folder) / "run", log=False, rate=task.rate,
                      action_timeout=task.action_timeout, driver=task.driver,
                      planner=task.planner, driver_options=task.driver_options,
                      faults=task.faults, deadline=task.deadline)


def sweep_run(task: SweepTask) -> SweepRow:
    """Plan and execute one run of a sweep (no recording; the run's folder is temporary)."""
    from ..run import execute_run, prepare_run

    with tempfile.TemporaryDirectory(prefix="msrr-sweep-") as folder:
        result = execute_run(prepare_run(_request(task, folder)))
    shape = None if result.goal is None else result.goal.shape
    poses = shape if shape is not None and shape.metric == "poses" else None
    error = shape.error if shape is not None and shape.metric == "skeletal" else None
    return SweepRow(faults=task.faults, seed=task.seed, success=result.success,
                    reason=result.reason, actions_done=result.actions_done,
                    actions_total=result.actions_total, docks=result.docks,
                    undocks=result.undocks, retries=result.retries,
                    sim_time_s=round(result.sim_time, 6),
                    position_rms_m=_nan(None if poses is None else poses.rms),
                    position_max_m=_nan(None if poses is None else poses.error),
                    heading_max_rad=_nan(None if poses is None else poses.heading),
                    shape_error_deg=_nan(error, 180.0 / math.pi),
                    faults_met=len(result.faults))


def sweep_csv(rows: list[SweepRow]) -> str:
    """``sweep.csv``'s text: a header of :class:`SweepRow`'s fields, one line per run."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow([f.name for f in fields(SweepRow)])
    for row in rows:
        writer.writerow(["" if isinstance(v, float) and math.isnan(v) else v
                         for v in asdict(row).values()])
    return out.getvalue()


def _spread(values: list[float], scale: float, digits: int) -> str:
    """``"median / p90 / max"`` of the finite values, or ``"-"``."""
    import numpy as np

    finite = np.array([v for v in values if math.isfinite(v)])
    if not finite.size:
        return "-"
    median, p90, top = (float(x) * scale for x in np.percentile(finite, [50, 90, 100]))
    return f"{median:.{digits}f} / {p90:.{digits}f} / {top:.{digits}f}"


def summarize(rows: list[SweepRow]) -> list[list[object]]:
    """Per fault setting: runs, success rate, final shape errors and simulated times
    (median / p90 / max), and the most common failure."""
    out: list[list[object]] = []
    for setting in dict.fromkeys(r.faults for r in rows):
        group = [r for r in rows if r.faults == setting]
        wins = sum(r.success for r in group)
        reasons = [r.reason.split(":")[0] for r in group if not r.success]
        common = max(dict.fromkeys(reasons), key=reasons.count) if reasons else ""
        out.append([setting or "none", len(group), f"{wins}/{len(group)} "
                    f"({100.0 * wins / len(group):.0f}%)",
                    _spread([r.position_rms_m for r in group], 1000.0, 2),
                    _spread([r.shape_error_deg for r in group], 1.0, 2),
                    _spread([r.sim_time_s for r in group], 1.0, 1),
                    f"{common} ({reasons.count(common)})" if common else ""])
    return out


def _plot(rows: list[SweepRow], path: Path, title: str) -> str:
    """Write ``sweep.png``: final position RMS error (or strut angle) and simulated time per
    fault setting; the line to print."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return f"no plot: matplotlib is missing; {MATPLOTLIB_HINT}"
    settings = list(dict.fromkeys(r.faults for r in rows))
    labels = [s or "none" for s in settings]
    use_position = any(math.isfinite(r.position_rms_m) for r in rows)
    error_name = "final position RMS error [mm]" if use_position else "final shape error [deg]"

    def column(setting: str, name: str) -> list[float]:
        scale = 1000.0 if name == "position_rms_m" else 1.0
        values = [getattr(r, name) * scale for r in rows if r.faults == setting]
        return [v for v in values if math.isfinite(v)] or [math.nan]

    figure, (left, right) = plt.subplots(1, 2, figsize=(10, 4))
    error_field = "position_rms_m" if use_position else "shape_error_deg"
    left.boxplot([column(s, error_field) for s in settings], tick_labels=labels)
    left.set_ylabel(error_name)
    right.boxplot([column(s, "sim_time_s") for s in settings], tick_labels=labels)
    right.set_ylabel("simulated time [s]")
    for axis in (left, right):
        axis.set_xlabel("faults")
        axis.tick_params(axis="x", labelrotation=20)
    figure.suptitle(title)
    figure.tight_layout()
    figure.savefig(path, dpi=100)
    plt.close(figure)
    return f"wrote {path}"


@click.command("sweep")
@run_selection_options
@click.option("--runs", type=click.IntRange(1, 100_000), default=10, show_default=True,
              help="Runs per fault setting: seeds --seed, --seed + 1, ...")
@click.option("--seed", type=SEED, default=0, show_default=True, help="First seed.")
@click.option("--faults", "fault_settings", multiple=True, metavar="SPEC",
              help="A fault setting (as `platform run --faults`), repeatable; 'none' or '' "
                   "for a fault-free setting. Default: fault-free only.")
@click.option("--planner", "planner_name", default=None, help="Planner name.")
@click.option("--driver", "driver_name", default=None, help="Driver name.")
@click.option("--rate", type=FiniteFloat(0.0, 1000.0, open_low=True), default=10.0,
              show_default=True, help="Control rate [Hz].")
@click.option("--timeout", "action_timeout", type=FiniteFloat(0.0, 3600.0, open_low=True),
              default=90.0, show_default=True, help="Driver time one action phase may take [s].")
@click.option("--driver-option", "driver_options", multiple=True, metavar="KEY=VALUE",
              help="Keyword option of the driver, repeatable (as `platform run`).")
@click.option("--out", type=click.Path(path_type=Path), default=None, metavar="DIR",
              help="Folder for sweep.csv and sweep.png [default: runs/<timestamp>-sweep-...].")
@click.option("--force", is_flag=True, help="Replace a sweep already in --out.")
@batch_options
def command(robot: str, scenario: str | None, start: Path | None, goal: Path | None, runs: int,
            seed: int, fault_settings: tuple[str, ...], planner_name: str | None,
            driver_name: str | None, rate: float, action_timeout: float,
            driver_options: tuple[str, ...], out: Path | None, force: bool, workers: int,
            cluster: str | None) -> None:
    """Run a scenario (or --from/--to) over many seeds and fault settings; print the
    success rate and the distributions of final shape errors and simulated times, write
    DIR/sweep.csv (one row per run) and DIR/sweep.png."""
    if (start is None) != (goal is None):
        raise ConfigurationError("give both --from and --to, or neither")
    if start is not None and scenario is not None:
        raise ConfigurationError("give --scenario or --from/--to, not both")
    from ...faults import parse_faults
    from ...files import atomic_write_text, check_output_place
    from ..run import parse_driver_options

    settings = [("" if s.strip().lower() in ("", "none") else s.strip())
                for s in (fault_settings or ("",))]
    for setting in settings:
        if setting:
            parse_faults(setting)  # a bad SPEC fails here, in one line, before any run
    name = scenario or ("custom" if start is not None else "default")
    folder = out or Path("runs") / f"{datetime.now():%Y%m%d-%H%M%S}-sweep-{robot}-{name}"
    check_output_place(folder, option="--out", folder=True)
    table_path, plot_path = folder / "sweep.csv", folder / "sweep.png"
    if table_path.exists() and not force:
        raise ConfigurationError("holds a sweep (sweep.csv); use --force to replace it",
                                 field="--out", source=str(folder))
    options = parse_driver_options(driver_options)
    tasks = [SweepTask(robot=robot, scenario=scenario,
                       start=None if start is None else str(start.resolve()),
                       goal=None if goal is None else str(goal.resolve()), seed=seed + k,
                       faults=setting, driver=driver_name, planner=planner_name, rate=rate,
                       action_timeout=action_timeout, driver_options=options)
             for setting in settings for k in range(runs)]
    # the first run in this process: a bad robot, scenario, planner or file fails in one
    # line before the batch starts its workers
    prepare_check(tasks[0])
    with exit_on_interrupt():
        batch = run_batch(sweep_run, tasks, keys=[t.key for t in tasks], workers=workers,
                          cluster=cluster, label="runs", describe=lambda t: t.key)
    for failure in batch.failures:
        err_console.print(f"run {failure.key} raised {failure.error}", markup=False)
    rows = [r for r in batch.results if r is not None]
    folder.mkdir(parents=True, exist_ok=True)
    atomic_write_text(table_path, sweep_csv(rows))
    console.print(table(f"{robot} {name}: {plural(runs, 'seed')} from {seed} per fault setting "
                        f"({batch.backend}, {plural(batch.workers, 'worker')}, {batch.wall_time:.1f} s)",
                        ["faults", "runs", "success", "position RMS [mm] med/p90/max",
                         "shape error [deg] med/p90/max", "sim time [s] med/p90/max",
                         "most common failure"], summarize(rows)))
    console.print(f"wrote {table_path}", markup=False)
    console.print(_plot(rows, plot_path, f"{robot} {name}: {plural(runs, 'seed')}"), markup=False)
    if batch.failures:
        raise SystemExit(1)


def prepare_check(task: SweepTask) -> None:
    """Prepare (plan, without running) ``task`` here: the options, files and names are
    checked once, before the workers start."""
    from ..run import prepare_run

    with tempfile.TemporaryDirectory(prefix="msrr-sweep-") as folder:
        prepare_run(_request(task, folder))
