"""``platform snapshot``: draw a still image of a run from its rerun recording."""

from __future__ import annotations

from pathlib import Path

import click

from ..console import console
from ..files import check_output_place
from ..timeline.snapshot import write_snapshot

__all__ = ["command"]


@click.command("snapshot")
@click.argument("recording", type=click.Path(path_type=Path))
@click.option("-o", "--output", type=click.Path(path_type=Path), required=True,
              help="PNG file to write.")
@click.option("--title", default="", help="Figure title [default: the recording's name].")
def command(recording: Path, output: Path, title: str) -> None:
    """Draw RECORDING (a run.rrd) to a PNG without a display.

    Top-down module footprints with ids, headings and docked connections at the start,
    before the first and the last topology change, and at the end; below, the number
    of connections and each module's distance to its goal over simulated time.
    Needs matplotlib (the dev extra).
    """
    check_output_place(output, option="--output")  # before reading and drawing
    path = write_snapshot(recording, output, title)
    console.print(f"wrote {path}")
