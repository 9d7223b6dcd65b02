"""``platform snapshot``: draw a still image of a run from its rerun recording."""

from __future__ import annotations

from pathlib import Path

import click

__all__ = ["command"]


@click.command("snapshot")
@click.argument("recording", type=click.Path(path_type=Path))
@click.option("-o", "--output", type=click.Path(path_type=Path), required=True,
              help="PNG file to write.")
@click.option("--title", default="", help="Figure title [default: the recording's name].")
@click.option("--at", "at", type=float, default=None, metavar="SECONDS",
              help="Draw the one moment at this simulated time [s].")
@click.option("--action", "action", type=int, default=None, metavar="K",
              help="Draw the end of action K (from 1, as the plan numbers it), with its "
                   "target.")
def command(recording: Path, output: Path, title: str, at: float | None,
            action: int | None) -> None:
    """Draw a run's recording (RECORDING, a run.rrd) to a PNG, without a display.

    Top row: the robot seen from above at four moments (start, one and two thirds of
    the run, end), or at the one moment --at or --action chooses: each module's body
    (boxes, spheres, struts with their connectors) with its id and heading, the docked
    connections, and the running action's target dashed (goal poses, or its shape
    fitted onto the modules; at the end, the run's goal). Bottom row, over simulated
    time: the number of docked connections (docks, undocks and flows marked) and the
    error to the target (each moving module's distance [m], or the RMS strut angle
    [deg] for strut robots). The title names the robot and the scenario, the legend
    what this recording draws. A moment outside the recording is refused in one line.
    Needs matplotlib: pip install 'msrr-platform[plot]'.
    """
    from ...console import console
    from ...files import check_output_place
    from ...timeline.snapshot import write_snapshot

    check_output_place(output, option="--output")  # before reading and drawing
    path = write_snapshot(recording, output, title, at=at, action=action)
    console.print(f"wrote {path}")
