"""``platform sweep``: one scenario (or a ``--from/--to`` pair) over many seeds and faults.

Each run is ``platform run`` without the recording (:func:`msrr.core.app.run.prepare_run`,
:func:`msrr.core.app.run.execute_run` in a temporary folder), one batch task per
(fault setting, seed) (:mod:`msrr.core.app.batch`). Run ``k`` of a setting uses seed
``--seed + k``, so any row can be replayed with ``platform run --seed S --faults F``,
and the table is the same serially, on the pool and on Ray. Writes ``sweep.csv``
(one row per run) and ``sweep.png`` (distributions; needs matplotlib).

Each row is appended to ``sweep.csv.journal`` as its run finishes
(:mod:`msrr.core.app.journal`); ``--resume`` continues an interrupted or failed sweep
from it, and ``sweep.csv`` is written from it, atomically, once every run has a row.
``--from``/``--to`` files travel by value with each task (:class:`InputFile`).
"""

from __future__ import annotations

import csv
import hashlib
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
from ..batch import (
    BatchError,
    TaskFailure,
    batch_options,
    exit_on_interrupt,
    finishing,
    retries_option,
    run_batch,
)

if TYPE_CHECKING:
    from collections.abc import Callable

    from ...events import BehaviorVerdict
    from ..journal import Journal
    from ..run import RunRequest

__all__ = ["InputFile", "SweepRow", "SweepTask", "command", "summarize", "sweep_csv",
           "sweep_run"]

MATPLOTLIB_HINT = "pip install 'msrr-platform[plot]'"


@dataclass(frozen=True)
class InputFile:
    """A configuration file travelling by value with a task (``--from``/``--to``): its
    name and text, written into the run's folder where the task runs, so a worker on
    another machine needs nothing from this one's disk."""

    name: str
    text: str

    @classmethod
    def read(cls, path: Path) -> InputFile:
        """The file at ``path`` (read here, once).

        Raises:
            ConfigurationError: it cannot be read.
        """
        try:
            return cls(path.name, path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError) as exc:
            raise ConfigurationError(f"cannot read: {exc}", source=str(path)) from None

    def write(self, folder: Path) -> Path:
        """Write the file into ``folder``; its path."""
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / self.name
        path.write_text(self.text, encoding="utf-8")
        return path

    @property
    def digest(self) -> str:
        """SHA-256 of the text (a journal names the file by it)."""
        return hashlib.sha256(self.text.encode("utf-8")).hexdigest()


@dataclass(frozen=True)
class SweepTask:
    """One run of a sweep (the fields of :class:`~msrr.core.app.run.RunRequest` it sets);
    ``--from``/``--to`` travel by value (:class:`InputFile`)."""

    robot: str
    scenario: str | None
    start: InputFile | None
    goal: InputFile | None
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

    def identity(self) -> dict[str, object]:
        """What makes two runs the same (for a journal): the fields, files by digest."""
        fields_ = {f.name: getattr(self, f.name) for f in fields(self)}
        fields_["start"] = None if self.start is None else self.start.digest
        fields_["goal"] = None if self.goal is None else self.goal.digest
        return fields_


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
        covered_min: the least fraction of its asked distance a behavior of the run
            covered along its commanded direction (on the judge's basis); ``nan``
            without a behavior that asks a distance and states a direction.
        heading_error_max_deg: the largest angle between a behavior's travel and its
            commanded direction [deg]; ``nan`` without one.
        covered_min_by, heading_error_max_by: the behavior (its call, as the judge names
            it) that covered least and the one that went farthest off; ``""`` without one.
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
    covered_min: float = math.nan
    heading_error_max_deg: float = math.nan
    covered_min_by: str = ""
    heading_error_max_by: str = ""


def _nan(value: float | None, scale: float = 1.0) -> float:
    return math.nan if value is None else round(value * scale, 6)


def _request(task: SweepTask, folder: str) -> RunRequest:
    """The ``platform run`` request of ``task``: no recording, into ``folder``."""
    from ..run import RunRequest  # the run machinery loads when a run starts, not at --help

    here = Path(folder)
    return RunRequest(robot=task.robot, scenario=task.scenario,
                      start=None if task.start is None else task.start.write(here / "from"),
                      goal=None if task.goal is None else task.goal.write(here / "to"),
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
                    faults_met=len(result.faults), **_locomotion(result.locomotion))


def _locomotion(verdicts: list[BehaviorVerdict]) -> dict[str, float | str]:
    """A run's worst behaviors: the least fraction of its asked distance covered along the
    commanded direction, and the largest heading error [deg] (``nan`` where none), each
    with the behavior it was (a run of two behaviors says which one strayed)."""
    covered = [(v.along / v.asked, v.name) for v in verdicts
               if v.along is not None and v.asked is not None and v.asked > 0]
    headings = [(v.heading_error, v.name) for v in verdicts
                if v.heading_error is not None]
    least = min(covered, key=lambda c: c[0], default=(None, ""))
    most = max(headings, key=lambda h: h[0], default=(None, ""))
    return {"covered_min": _nan(least[0]), "heading_error_max_deg": _nan(most[0], 180.0 / math.pi),
            "covered_min_by": least[1], "heading_error_max_by": most[1]}


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


def _by(group: list[SweepRow], value: str, by: str, worst: Callable, label: str) -> str:
    """``" (<label><behavior>)"``: the behavior of the runs' ``worst`` ``value`` (its name
    without its parameters), ``""`` when none is known."""
    known = [r for r in group if math.isfinite(getattr(r, value)) and getattr(r, by)]
    if not known:
        return ""
    name = getattr(worst(known, key=lambda r: getattr(r, value)), by).split("(")[0]
    return f" ({label}{name})"


def summarize(rows: list[SweepRow]) -> list[list[object]]:
    """Per fault setting: runs, success rate, final shape errors, simulated times, and the
    behaviors' distance covered (of the asked, worst per run) and heading errors
    (median / p90 / max, each naming the behavior of the worst run), and the most common
    failure."""
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
                    _spread([r.covered_min for r in group], 1.0, 2)
                    + _by(group, "covered_min", "covered_min_by", min, "least: "),
                    _spread([r.heading_error_max_deg for r in group], 1.0, 1)
                    + _by(group, "heading_error_max_deg", "heading_error_max_by", max, ""),
                    f"{common} ({reasons.count(common)})" if common else ""])
    return out


def sweep_title(robot: str, name: str, runs: int, options: tuple[tuple[str, str], ...]) -> str:
    """The sweep's title, with the driver options every run had (its noise and slip: a
    plot or table read later says what it measured)."""
    given = f" with {' '.join(f'{k}={v}' for k, v in options)}" if options else ""
    return f"{robot} {name}{given}: {plural(runs, 'seed')}"


def setting_label(rows: list[SweepRow], setting: str) -> str:
    """A fault setting's label on the plot: its name and how many of its runs succeeded."""
    group = [r for r in rows if r.faults == setting]
    return f"{setting or 'none'}\n{sum(r.success for r in group)}/{len(group)} succeed"


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
    labels = [setting_label(rows, s) for s in settings]
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
    from ...files import atomic_write_bytes

    image = io.BytesIO()
    figure.savefig(image, format="png", dpi=100)
    plt.close(figure)
    atomic_write_bytes(path, image.getvalue())  # a full disk: one line, no half image
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
@click.option("--force", is_flag=True,
              help="Replace a sweep already in --out (and drop an unfinished one's journal).")
@click.option("--resume", is_flag=True,
              help="Continue the interrupted or failed sweep in --out from its journal "
                   "(sweep.csv.journal): only the runs without a result run.")
@retries_option
@batch_options
def command(robot: str, scenario: str | None, start: Path | None, goal: Path | None, runs: int,
            seed: int, fault_settings: tuple[str, ...], planner_name: str | None,
            driver_name: str | None, rate: float, action_timeout: float,
            driver_options: tuple[str, ...], out: Path | None, force: bool, resume: bool,
            retries: int, workers: int, cluster: str | None) -> None:
    """Run a scenario (or --from/--to) over many seeds and fault settings; print the
    success rate and the distributions of final shape errors and simulated times, write
    DIR/sweep.csv (one row per run) and DIR/sweep.png.

    Each finished run goes to DIR/sweep.csv.journal at once; sweep.csv is written,
    atomically, only when every run has a row. A run that failed (it raised, its worker
    was lost) is named, the command exits 1 without a table, and --resume runs what is
    missing."""
    from ..run import parse_driver_options

    settings = _settings(fault_settings)
    if (start is None) != (goal is None):
        raise ConfigurationError("give both --from and --to, or neither")
    if start is not None and scenario is not None:
        raise ConfigurationError("give --scenario or --from/--to, not both")
    if resume and out is None:
        raise ConfigurationError("give --out DIR, the folder of the sweep to continue",
                                 field="--resume")
    name = scenario or ("custom" if start is not None else "default")
    folder = out or Path("runs") / f"{datetime.now():%Y%m%d-%H%M%S}-sweep-{robot}-{name}"
    _check_folder(folder, force=force)
    options = parse_driver_options(driver_options)
    files = (None if start is None else InputFile.read(start),
             None if goal is None else InputFile.read(goal))
    tasks = [SweepTask(robot=robot, scenario=scenario, start=files[0], goal=files[1],
                       seed=seed + k, faults=setting, driver=driver_name,
                       planner=planner_name, rate=rate, action_timeout=action_timeout,
                       driver_options=options)
             for setting in settings for k in range(runs)]
    # the first run in this process: a bad robot, scenario, planner or file fails in one
    # line before the batch starts its workers
    for setting in dict.fromkeys(task.faults for task in tasks):  # each setting's modules
        prepare_check(next(task for task in tasks if task.faults == setting))
    rows, journal, how = _run_sweep(tasks, folder, resume=resume, retries=retries,
                                    workers=workers, cluster=cluster)
    title = sweep_title(robot, name, runs, options)
    with finishing(f"the sweep was written to {folder}"):
        _write(rows, folder, journal, f"{title} from {seed} per fault setting ({how})", title)


def _settings(fault_settings: tuple[str, ...]) -> list[str]:
    """The fault settings, each once (``"none"`` is ``""``); a bad SPEC fails here."""
    from ...faults import parse_faults

    settings = list(dict.fromkeys("" if s.strip().lower() in ("", "none") else s.strip()
                                  for s in (fault_settings or ("",))))
    for setting in settings:
        if setting:
            parse_faults(setting)  # a bad SPEC fails here, in one line, before any run
    return settings


def _check_folder(folder: Path, *, force: bool) -> None:
    """Refuse a folder that cannot take the sweep, or holds a finished one (without
    ``force``); with ``force``, drop an unfinished one's journal."""
    from ...files import check_output_place
    from ..journal import journal_path

    check_output_place(folder, option="--out", folder=True)
    table_path = folder / "sweep.csv"
    if force:
        journal_path(table_path).unlink(missing_ok=True)
    elif table_path.exists() and not journal_path(table_path).exists():
        raise ConfigurationError("holds a sweep (sweep.csv); use --force to replace it",
                                 field="--out", source=str(folder))


def _run_sweep(tasks: list[SweepTask], folder: Path, *, resume: bool, retries: int,
               workers: int, cluster: str | None) -> tuple[list[SweepRow], Journal, str]:
    """Run the tasks the journal has no row for, journaling each row as it arrives; every
    row in task order, and how the batch ran.

    Raises:
        BatchError: a run failed (no table is written; the journal keeps the others).
    """
    from ..journal import Journal, journal_path

    path = journal_path(folder / "sweep.csv")
    had_journal = path.exists()
    journal = Journal.open(path, {"runs": [t.identity() for t in tasks]}, kind="sweep",
                           resume=resume)
    if resume:
        console.print(f"resuming: {journal.resumed} of {plural(len(tasks), 'run')} from "
                      f"{path}" if had_journal else f"no journal at {path}: running every run",
                      markup=False)
    todo = [t for t in tasks if t.key not in journal.results]

    def record(index: int, outcome: SweepRow | TaskFailure) -> None:
        if isinstance(outcome, SweepRow):
            journal.add(todo[index].key, asdict(outcome))
        else:
            journal.error(todo[index].key, outcome.error)

    def note() -> str:
        return (f"; {len(journal.results)} of {len(tasks)} runs kept in {path}: continue "
                f"with --resume --out {folder}")

    try:
        with exit_on_interrupt():
            batch = run_batch(sweep_run, todo, keys=[t.key for t in todo], workers=workers,
                              cluster=cluster, label="runs", describe=lambda t: t.key,
                              retries=retries, record=record, interrupt_note=note)
    finally:
        journal.close()
    for key, why in batch.retried:
        err_console.print(f"run {key}: {why}; ran it again", markup=False)
    if batch.failures:
        for failure in batch.failures:
            err_console.print(f"run {failure.key} failed: {failure.error}", markup=False)
        names = ", ".join(f.key for f in batch.failures[:3])
        raise BatchError(f"{len(batch.failures)} of {plural(len(tasks), 'run')} failed "
                         f"({names}{' ...' if len(batch.failures) > 3 else ''}); no table "
                         f"written; the {len(journal.results)} finished are in {path}: run "
                         f"again with --resume --out {folder}")
    rows = [SweepRow(**journal.results[t.key]) for t in tasks]
    how = f"{batch.backend}, {plural(batch.workers, 'worker')}, {batch.wall_time:.1f} s"
    return rows, journal, how


def _write(rows: list[SweepRow], folder: Path, journal: Journal, header: str,
           title: str) -> None:
    """Write ``sweep.csv`` (atomically) and drop the journal, print the summary, draw
    ``sweep.png``."""
    from ...files import atomic_write_text

    table_path = folder / "sweep.csv"
    atomic_write_text(table_path, sweep_csv(rows))
    journal.finish()
    console.print(table(header, ["faults", "runs", "success", "position RMS [mm] med/p90/max",
                                 "shape error [deg] med/p90/max", "sim time [s] med/p90/max",
                                 "distance covered / asked med/p90/max",
                                 "heading error [deg] med/p90/max", "most common failure"],
                          summarize(rows)))
    console.print(f"wrote {table_path}", markup=False)
    console.print(_plot(rows, folder / "sweep.png", title), markup=False)


def prepare_check(task: SweepTask) -> None:
    """Prepare (plan, without running) ``task`` here: the options, files and names are
    checked once, before the workers start."""
    from ..run import prepare_run

    with tempfile.TemporaryDirectory(prefix="msrr-sweep-") as folder:
        prepare_run(_request(task, folder))
