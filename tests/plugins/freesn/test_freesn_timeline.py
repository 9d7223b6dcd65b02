"""FreeSN's views in the rerun timeline (``msrr_timeline_views``)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

from msrr.core import plugins

CONFIGS = Path(__file__).resolve().parents[3] / "plugins" / "freesn" / "configs" / "library"


def test_freesn_adds_one_connector_plot_per_strut_end_to_its_runs_only() -> None:
    start = plugins.load_configuration(CONFIGS / "S6N3-2.3.json")
    run = SimpleNamespace(robot="freesn", plan=SimpleNamespace(start=start))
    views = plugins.timeline_views(run)
    struts = [e.id for e in start.edges()]
    assert len(struts) == 6
    assert [(str(v.name), str(v.origin)) for v in views] == [
        ("Connector a targets", "commands"), ("Connector b targets", "commands")]
    for view, end in zip(views, "ab", strict=True):
        assert [str(q) for q in view.contents] == [f"$origin/{s}/{end}/**"
                                                         for s in struts]
    assert plugins.timeline_views(SimpleNamespace(robot="mmrp", plan=run.plan)) == []
