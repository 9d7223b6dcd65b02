"""``platform library build/show/retrieve`` through click's runner."""

from __future__ import annotations

from click.testing import CliRunner

from msrr.core.cli import get_cli
from msrr.core.io import save_configuration
from msrr.core.library import load_library

from library_helpers import relabelled, source_files


def test_build_show_retrieve(tmp_path):
    runner = CliRunner()
    out = tmp_path / "S6N3.json"
    built = runner.invoke(get_cli(), ["library", "build", *map(str, source_files("S6N3")),
                                      "-o", str(out), "--cost", "distance"])
    assert built.exit_code == 0, built.output
    assert "S6N3: 4 groups" in built.output and out.exists()
    shown = runner.invoke(get_cli(), ["library", "show", str(out)])
    assert shown.exit_code == 0, shown.output
    for title in ("groups", "configurations", "behaviors", "action edges"):
        assert f"S6N3: {title}" in shown.output
    library = load_library(out)
    system = relabelled(library.sublibraries["S6N3"].configuration("fig20a").configuration,
                        "q", noise=0.02, seed=4)
    path = tmp_path / "system.json"
    save_configuration(system, path)
    got = runner.invoke(get_cli(), ["library", "retrieve", str(out), "--from", str(path),
                                    "--behavior", "wheeled-move"])
    assert got.exit_code == 0, got.output
    assert "wheeled-move commands" in got.output and "qe" in got.output


def test_bad_source_is_one_line_with_file_and_field(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"schema_version": 1, "robot": "freesn", "sequences": [{"name": "s", '
                   '"steps": [{"configuration": {"schema_version": 1, "robot": "freesn", '
                   '"modules": [{"id": "N1", "kind": "blob"}]}}]}]}')
    result = CliRunner().invoke(get_cli(), ["library", "build", str(bad), "-o",
                                            str(tmp_path / "x.json")])
    assert result.exit_code == 1
    assert str(bad) in result.output and "sequences[0].steps[0].configuration" in result.output
    assert "Traceback" not in result.output and not (tmp_path / "x.json").exists()
