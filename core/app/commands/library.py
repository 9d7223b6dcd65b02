"""``platform library``: build, show and retrieve from behavior libraries (paper section 6).

Each subcommand imports the library, matching and simulation code in its body, so
``platform library ... --help`` starts at once; the option vocabulary below is checked
against those modules' constants by ``tests/core/test_cli_startup.py``.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from ...console import COSTS, SEED, FiniteFloat, MsrrGroup, console, plural, styled, table
from ...errors import MsrrError
from ...plugins import load_configuration, load_library, resolve
from ..batch import BatchError, batch_options, exit_on_interrupt, finishing, retries_option
from ..journal import journal_path

if TYPE_CHECKING:
    from ...library import Library

__all__ = ["MERGE_THRESHOLD", "command"]

MERGE_THRESHOLD = 1e-5
"""``--merge-threshold`` default: :data:`msrr.core.library.build.DEFAULT_MERGE_THRESHOLD`."""


@click.group("library", cls=MsrrGroup)
def command() -> None:
    """Behavior libraries: build from sources, show, retrieve sequences (paper section 6)."""


@command.command("build",
                 short_help="Build a library from designed groups and recorded sequences.")
@click.argument("sources", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("-o", "--output", required=True, type=click.Path(path_type=Path),
              help="Library file to write (atomically).")
@click.option("--merge-threshold", type=FiniteFloat(0.0, 100.0), default=MERGE_THRESHOLD,
              show_default=True, help="Largest motion cost at which two configurations are "
              "merged, in [0, 100].")
@click.option("--cost", type=click.Choice(COSTS), default="distance", show_default=True,
              help="Motion cost: aligned distance (eq. 8; identical builds on every machine) "
                   "or full-body IK (eq. 6; reproducible on one BLAS kernel only).")
def build(sources: tuple[Path, ...], output: Path, merge_threshold: float, cost: str) -> None:
    """Build a library from SOURCES: designed groups and recorded sequences (Fig. 14); a
    folder stands for its JSON files in name order."""
    from ...files import check_output_place
    from ...library import build_library, build_steps, load_sources, save_library

    check_output_place(output, option="--output")
    inputs = load_sources(sources, resolve)
    columns = (TextColumn("{task.description}", markup=False), BarColumn(), MofNCompleteColumn(),
               TimeElapsedColumn())
    with Progress(*columns, console=console, transient=True) as bar:
        task = bar.add_task(f"building {inputs.name}", total=build_steps(inputs))
        library = build_library(inputs, resolve(inputs.robot), merge_threshold=merge_threshold,
                                cost=cost,
                                progress=lambda _: bar.advance(task))
    save_library(library, output)
    for sub in library.sublibraries.values():
        console.print(f"{sub.name}: {plural(len(sub.groups), 'group')}, "
                      f"{plural(len(sub.configurations), 'configuration')}, "
                      f"{plural(len(sub.behaviors), 'behavior')}, {plural(len(sub.edges), 'edge')}")
    console.print(f"wrote {output}")


def _show(library: Library) -> None:
    console.print(f"library {library.name} ({library.robot}): {library.description}")
    for sub in library.sublibraries.values():
        console.print(table(f"{sub.name}: groups", ["group", "name", "vertices", "edges",
                                                    "trees", "configurations"],
                            [[g.id, g.name, len(g.reference), len(g.reference.edges()),
                              ", ".join(g.trees),
                              sum(1 for c in sub.configurations.values() if c.group == g.id)]
                             for g in sub.groups.values()]))
        console.print(table(f"{sub.name}: configurations", ["id", "group", "names", "origins"],
                            [[c.id, c.group, ", ".join(c.names), len(c.origins)]
                             for c in sub.configurations.values()]))
        console.print(table(f"{sub.name}: behaviors", ["name", "kind", "start", "steps / commands",
                                                       "loop", "description"],
                            [[b.name, b.kind, b.start,
                              " → ".join(b.steps) if b.kind == "sequence"
                              else f"{len(b.commands)} commands of {', '.join(b.parameters)}",
                              "yes" if b.loop else "", b.description]
                             for b in sub.behaviors.values()]))
        console.print(table(f"{sub.name}: action edges", ["source", "target", "action", "tree",
                                                          "cost", "mapping", "feasible"],
                            [[e.source, e.target, e.action.value, str(e.tree), f"{e.cost:.4g}",
                              "identity" if e.mapping is None else "mapped",
                              "unchecked" if e.feasible is None else str(e.feasible)]
                             for e in sub.edges]))


@command.command("show",
                 short_help="Show a library: groups, configurations, behaviors, edges.")
@click.argument("library", type=click.Path(path_type=Path))
def show(library: Path) -> None:
    """Show a LIBRARY file: sub-libraries, groups, configurations, behaviors, edges.

    Feasibility flags come from the check file beside it (``<LIB>.check.json``) when it
    is a check of this very file."""
    from ...library.check import apply_sidecar, check_path

    lib = load_library(library)
    if apply_sidecar(lib, library) == "stale":
        console.print(styled(f"{check_path(library)} checks another build of {library}; run "
                             "`platform library check` again", "yellow"))
    _show(lib)


@command.command("check",
                 short_help="Run every action edge in simulation; write the check file.")
@click.argument("library", type=click.Path(path_type=Path))
@click.option("-o", "--output", type=click.Path(path_type=Path),
              help="Check file to write (atomically); default <LIB>.check.json beside it.")
@click.option("--seed", type=SEED, default=0, show_default=True, help="Seed of the simulation.")
@click.option("--timeout", "action_timeout", type=FiniteFloat(0.0, 3600.0, open_low=True),
              default=30.0, show_default=True,
              help="Simulated time one phase may take [s], in (0, 3600].")
@click.option("--noise", type=FiniteFloat(0.0, 90.0), default=0.0, show_default=True,
              help="Recognizer noise (std of every reported angle) [deg], in [0, 90].")
@click.option("--slip", type=FiniteFloat(0.0, 1.0), default=0.0, show_default=True,
              help="Odometry heading error per radian rolled [rad/rad], in [0, 1].")
@click.option("--edge", "only", multiple=True, help="Check only edges whose key contains this.")
@click.option("--driver-option", "extra", multiple=True, metavar="KEY=VALUE",
              help="Keyword option of the driver, repeatable (as for `platform run`).")
@click.option("--resume", is_flag=True,
              help="Continue an interrupted or failed check from its journal "
                   "(<OUTPUT>.journal): only the edges without a result run.")
@retries_option
@batch_options
def check_command(library: Path, output: Path | None, seed: int, action_timeout: float,
                  noise: float, slip: float, only: tuple[str, ...], extra: tuple[str, ...],
                  resume: bool, retries: int, workers: int, cluster: str | None) -> None:
    """Run every action edge of LIBRARY in simulation from its source configuration and
    record per edge: feasible, the reason when not, the simulated time (paper 6.2).

    One simulation per edge, on every core (--workers) or a Ray cluster (--cluster);
    the check file is the same whichever runs it. Each finished edge goes to a journal
    beside the check file at once; the check file is written, atomically, only when
    every edge has a verdict. An edge whose run failed (a crash, a lost worker) is never
    recorded as infeasible: the command names it, exits 1 and leaves the check file as it
    was; --resume runs what is missing."""
    from ...library.check import check_path

    check = _CheckRun.prepare(library, output or check_path(library), seed=seed,
                              action_timeout=action_timeout, noise=noise, slip=slip, only=only,
                              extra=extra)
    check.run(resume=resume, retries=retries, workers=workers, cluster=cluster)
    check.write()


class _CheckRun:
    """One ``platform library check``: what is checked, its journal, the verdicts."""

    def __init__(self, library: Library, target: Path, header: dict[str, Any],
                 cases: list[Any], runner: Any):
        self.library, self.target, self.header = library, target, header
        self.cases, self.runner = cases, runner
        self.results: dict[str, Any] = {}
        self.journal: Any = None
        self.journal_path = journal_path(target)

    @classmethod
    def prepare(cls, library: Path, target: Path, *, seed: int, action_timeout: float,
                noise: float, slip: float, only: tuple[str, ...], extra: tuple[str, ...] = ()
                ) -> _CheckRun:
        """Load the library and resolve the robot; refuse a bad output place or a driver
        option the driver does not take."""
        from ...driver import check_driver_options
        from ...executor import ExecutorOptions
        from ...files import check_output_place
        from ...library.check import edge_cases, library_digest
        from ..feasibility import default_runner
        from ..run import parse_driver_options

        lib = load_library(library)
        check_output_place(target, option="--output")
        driver_options: tuple[tuple[str, Any], ...] = ()
        if noise:
            driver_options += (("noise", math.radians(noise)),)
        if slip:
            driver_options += (("slip", slip),)
        runner = default_runner(lib.robot, options=ExecutorOptions(   # as EdgeRunner's
            action_timeout=action_timeout, retries=0, stall_window=0.0), seed=seed)
        runner = replace(runner, driver_options=driver_options + check_driver_options(
            runner.driver, parse_driver_options(extra)))
        cases = [c for c in edge_cases(lib, runner.robot)
                 if not only or any(o in c.key for o in only)]
        options = {"rate_hz": runner.options.rate, "action_timeout_s": action_timeout,
                   "timeout_per_rad_s": runner.timeout_per_rad, "noise_deg": noise, "slip": slip,
                   **dict(runner.driver_options[len(driver_options):])}
        header = {"library": lib.name, "library_sha256": library_digest(library),
                  "robot": lib.robot, "driver": runner.driver.name, "seed": seed,
                  "options": options}
        return cls(lib, target, header, cases, runner)

    def run(self, *, resume: bool, retries: int, workers: int, cluster: str | None) -> None:
        """Run the edges the journal has no verdict for, journaling each as it arrives.

        Raises:
            BatchError: an edge's run failed (the check file is left as it was).
        """
        from ...library.check import EdgeCheck, load_check
        from ..feasibility import check_edges
        from ..journal import Journal

        identity = {**self.header, "edges": [c.key for c in self.cases]}
        had_journal = self.journal_path.exists()
        journal = Journal.open(self.journal_path, identity, kind="library check", resume=resume)
        if resume:
            console.print(f"resuming: {journal.resumed} of {plural(len(self.cases), 'edge')} "
                          f"from {journal.path}" if had_journal else
                          f"no journal at {journal.path}: checking every edge", markup=False)
        todo = [c for c in self.cases if c.key not in journal.results]
        previous = None  # an earlier check only orders the work: its longest edges first
        with contextlib.suppress(MsrrError, OSError):
            previous = load_check(self.target) if self.target.is_file() else None

        def record(index: int, outcome: Any) -> None:
            if isinstance(outcome, EdgeCheck):
                journal.add(todo[index].key, outcome.model_dump(mode="json"))
            else:
                journal.error(todo[index].key, outcome.error)

        def note() -> str:
            return (f"; {len(journal.results)} of {len(self.cases)} edges kept in "
                    f"{journal.path}: continue with --resume")

        try:
            with exit_on_interrupt():
                _, batch = check_edges(todo, self.runner, workers=workers, cluster=cluster,
                                       previous=previous, retries=retries, record=record,
                                       interrupt_note=note)
        finally:
            journal.close()
        for key, why in batch.retried:
            console.print(styled(f"edge {key}: {why}; ran it again", "yellow"), markup=False)
        if batch.failures:
            self._refuse(batch.failures, journal)
        self.results = dict(journal.results)
        self.journal = journal

    def _refuse(self, failures: list[Any], journal: Any) -> None:
        for failure in failures:
            console.print(styled(f"edge {failure.key} failed: {failure.error}", "red"),
                          markup=False)
        names = ", ".join(f.key for f in failures[:3]) + (" ..." if len(failures) > 3 else "")
        raise BatchError(f"{len(failures)} of {plural(len(self.cases), 'edge')} failed to run "
                         f"({names}), not recorded as infeasible; {self.target} is unchanged; "
                         f"the {len(journal.results)} finished are in {journal.path}: run again "
                         "with --resume")

    def write(self) -> None:
        """Write the check file from the journal (atomically), then remove the journal."""
        from ...library.check import CheckFile, EdgeCheck, save_check

        checks = [EdgeCheck.model_validate(self.results[c.key]) for c in self.cases]
        check = CheckFile(**self.header, edges=checks)
        with finishing(f"{self.target} was written"):
            save_check(check, self.target)
            self.journal.finish()
            console.print(table(f"{self.library.name}: feasibility",
                                ["edge", "action", "feasible", "sim time [s]",
                                 "shape error [deg]", "reason"],
                                [[c.edge, c.action, "yes" if c.feasible else "no",
                                  f"{c.sim_time:.1f}",
                                  "" if c.shape_error_deg is None else f"{c.shape_error_deg:.2f}",
                                  c.reason] for c in checks]))
            done = sum(c.feasible for c in checks)
            console.print(f"{done}/{plural(len(checks), 'edge')} feasible; wrote {self.target}",
                          markup=False)


@command.command("retrieve",
                 short_help="Retrieve the cheapest sequence from a system to a target.")
@click.argument("library", type=click.Path(path_type=Path))
@click.option("--from", "system", required=True, type=click.Path(path_type=Path),
              help="The system configuration file (its own module ids).")
@click.option("--to", "target", help="Target library configuration id or name.")
@click.option("--behavior", help="Target behavior name.")
def retrieve_command(library: Path, system: Path, target: str | None,
                     behavior: str | None) -> None:
    """Retrieve the cheapest sequence from the system to a target (Fig. 15)."""
    from ...library import RetrievalError
    from ...library.retrieve import retrieve

    lib = load_library(library)
    config = load_configuration(system)
    try:
        result = retrieve(lib, config, resolve(lib.robot), to=target, behavior=behavior)
    except MsrrError as exc:  # about the library and the system: name both
        if str(library) in str(exc):
            raise
        raise RetrievalError(f"{library} from {system}: {exc}") from None
    actions = result.actions(config)
    console.print(f"matched {result.start} of {result.sublibrary} ({lib.build.get('cost')} cost "
                  f"{result.match_cost:.4g}); mapping system → library: "
                  + ", ".join(f"{k}→{v}" for k, v in sorted(result.mapping.nodes.items())
                              if not config.is_virtual(k)))
    rows = []
    for i, (step, action) in enumerate(zip([*result.steps, *result.behavior_steps], actions,
                                           strict=True)):
        part = "behavior" if i >= len(result.steps) else ""
        changes = ", ".join(f"{c} ({c.edge_id})" for c in action.changes)
        rows.append([i, step.library_id, step.action.value, changes, str(step.tree_ref),
                     f"{step.cost:.4g}", part])
    console.print(table("Retrieved sequence (system ids)",
                        ["step", "library config", "action", "changes", "tree", "cost", ""],
                        rows))
    console.print(f"total motion cost {result.cost:.4g}; ends at {result.steps[-1].library_id}")
    if result.commands:
        console.print(table(f"behavior {result.behavior.name} commands (system ids)",
                            ["module", "connector", "command", "gains"],
                            [[c.module, c.connector or "", c.command,
                              ", ".join(f"{g:+.4g}·{p}" for p, g in c.gains)]
                             for c in result.commands]))
