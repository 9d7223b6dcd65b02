"""``platform library``: build, show and retrieve from behavior libraries (paper section 6)."""

from __future__ import annotations

from pathlib import Path

import click
from rich.markup import escape
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from ..console import MsrrGroup, console, table
from ..library import (
    DEFAULT_MERGE_THRESHOLD,
    Library,
    build_library,
    build_steps,
    load_library,
    load_sources,
    retrieve,
    save_library,
)
from ..matching import COST_DISTANCE, COST_KINDS
from ..plugins import load_configuration, resolve

__all__ = ["command"]


@click.group("library", cls=MsrrGroup)
def command() -> None:
    """Behavior libraries: build from sources, show, retrieve sequences (paper section 6)."""


@command.command("build")
@click.argument("sources", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("-o", "--output", required=True, type=click.Path(path_type=Path),
              help="Library file to write (atomically).")
@click.option("--merge-threshold", type=float, default=DEFAULT_MERGE_THRESHOLD, show_default=True,
              help="Largest motion cost at which two configurations are merged.")
@click.option("--cost", type=click.Choice(COST_KINDS), default=COST_DISTANCE, show_default=True,
              help="Motion cost: aligned distance (eq. 8; identical builds on every machine) "
                   "or full-body IK (eq. 6; reproducible on one BLAS kernel only).")
def build(sources: tuple[Path, ...], output: Path, merge_threshold: float, cost: str) -> None:
    """Build a library from SOURCES: designed groups and recorded sequences (Fig. 14)."""
    inputs = load_sources(sources, resolve)
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
               TimeElapsedColumn())
    with Progress(*columns, console=console, transient=True) as bar:
        task = bar.add_task(f"building {inputs.name}", total=build_steps(inputs))
        library = build_library(inputs, resolve(inputs.robot), merge_threshold=merge_threshold,
                                cost=cost,
                                progress=lambda _: bar.advance(task))
    save_library(library, output)
    for sub in library.sublibraries.values():
        console.print(f"{sub.name}: {len(sub.groups)} groups, {len(sub.configurations)} "
                      f"configurations, {len(sub.behaviors)} behaviors, {len(sub.edges)} edges")
    console.print(f"wrote {output}")


def _show(library: Library) -> None:
    console.print(escape(f"library {library.name} ({library.robot}): {library.description}"))
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
                              "yes" if b.loop else "", escape(b.description)]
                             for b in sub.behaviors.values()]))
        console.print(table(f"{sub.name}: action edges", ["source", "target", "action", "tree",
                                                          "cost", "mapping", "feasible"],
                            [[e.source, e.target, e.action.value, str(e.tree), f"{e.cost:.4g}",
                              "identity" if e.mapping is None else "mapped",
                              "unchecked" if e.feasible is None else str(e.feasible)]
                             for e in sub.edges]))


@command.command("show")
@click.argument("library", type=click.Path(path_type=Path))
def show(library: Path) -> None:
    """Show a LIBRARY file: sub-libraries, groups, configurations, behaviors, edges."""
    _show(load_library(library))


@command.command("retrieve")
@click.argument("library", type=click.Path(path_type=Path))
@click.option("--from", "system", required=True, type=click.Path(path_type=Path),
              help="The system configuration file (its own module ids).")
@click.option("--to", "target", help="Target library configuration id or name.")
@click.option("--behavior", help="Target behavior name.")
def retrieve_command(library: Path, system: Path, target: str | None,
                     behavior: str | None) -> None:
    """Retrieve the cheapest sequence from the system to a target (Fig. 15)."""
    lib = load_library(library)
    config = load_configuration(system)
    result = retrieve(lib, config, resolve(lib.robot), to=target, behavior=behavior)
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
