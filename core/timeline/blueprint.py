"""The default viewer layout of a run recording."""

from __future__ import annotations

import rerun.blueprint as rrb

__all__ = ["build_blueprint"]


def build_blueprint() -> rrb.Blueprint:
    """3-D world and topology graphs on top; action, events and plots below."""
    return rrb.Blueprint(
        rrb.Vertical(
            rrb.Horizontal(
                rrb.Spatial3DView(name="World", origin="world"),
                rrb.Vertical(
                    rrb.GraphView(name="Current topology", origin="topology/current"),
                    rrb.GraphView(name="Target topology", origin="topology/target"),
                ),
                column_shares=[3, 2],
            ),
            rrb.Horizontal(
                rrb.Vertical(
                    rrb.TextDocumentView(name="Action", origin="action"),
                    rrb.TextLogView(name="Events", origin="events"),
                    row_shares=[1, 2],
                ),
                rrb.Tabs(
                    rrb.TimeSeriesView(name="Commands [m/s]", origin="commands"),
                    rrb.TimeSeriesView(name="Errors [m]", origin="errors"),
                    rrb.TextDocumentView(name="Plan", origin="plan"),
                    rrb.TextDocumentView(name="Mapping", origin="mapping"),
                ),
                column_shares=[2, 3],
            ),
            row_shares=[3, 2],
        ),
        collapse_panels=True,
    )
