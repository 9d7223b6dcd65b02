"""Library files: round trip, refusal of broken files, atomic writes."""

from __future__ import annotations

import json
import os

import pytest
from click.testing import CliRunner

from msrr.core.app.cli import get_cli
from msrr.core.errors import OutputError
from msrr.core.library import LibraryError, dump_library, load_library, save_library


def test_round_trip_is_lossless(stick_lib, tmp_path):
    path = tmp_path / "lib.json"
    save_library(stick_lib, path)
    loaded = load_library(path)
    assert dump_library(loaded) == path.read_text()
    for sub in stick_lib.sublibraries.values():
        other = loaded.sublibraries[sub.name]
        assert list(other.configurations) == list(sub.configurations)
        for cid, config in sub.configurations.items():
            assert other.configurations[cid].configuration._canonical() == \
                config.configuration._canonical()
        assert [(e.source, e.target, e.action, e.cost, e.mapping) for e in other.edges] == \
            [(e.source, e.target, e.action, e.cost, e.mapping) for e in sub.edges]
        assert other.behaviors == sub.behaviors


def test_truncated_file_is_refused_with_its_path(stick_lib, tmp_path):
    path = tmp_path / "lib.json"
    text = dump_library(stick_lib)
    path.write_text(text[: len(text) // 2])
    with pytest.raises(LibraryError, match=str(path)):
        load_library(path)


@pytest.mark.parametrize(("edit", "field"), [
    (lambda d: d.update(schema_version=2), "schema_version"),
    (lambda d: d["sublibraries"][0]["edges"][0].update(target="nowhere"),
     "sublibraries[0].edges[0].target"),
    (lambda d: d["sublibraries"][0]["configurations"][1]["z"].update(R1=[1.0, 1.0, 0.0]),
     "sublibraries[0].configurations[1].z"),
    (lambda d: d["sublibraries"][0]["edges"][0].update(tree={"group": "H3R3-1", "name": "K9"}),
     "sublibraries[0].edges[0].tree"),
    (lambda d: d["sublibraries"][0]["behaviors"][0].update(start="H3R3-9.9"),
     "sublibraries[0].behaviors[0].start"),
    (lambda d: d["sublibraries"][0]["configurations"][0].update(group="H3R3-7"),
     "sublibraries[0].configurations[0].group"),
    (lambda d: d["sublibraries"][0]["behaviors"][0].update(drive_root="R3:end"),
     "sublibraries[0].behaviors[0].drive_root"),
])
def test_invalid_field_is_named(stick_lib, tmp_path, edit, field):
    data = json.loads(dump_library(stick_lib))
    edit(data)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    with pytest.raises(LibraryError) as caught:
        load_library(path)
    assert str(path) in str(caught.value) and field in str(caught.value)
    assert "\n" not in str(caught.value)


@pytest.mark.parametrize("failure, raised", [(KeyboardInterrupt, KeyboardInterrupt),
                                             (OSError, OutputError)])
def test_interrupted_write_leaves_the_original(stick_lib, tmp_path, monkeypatch, failure,
                                               raised):
    path = tmp_path / "lib.json"
    save_library(stick_lib, path)
    before = path.read_bytes()

    def interrupted(fd):
        raise failure("interrupted")

    monkeypatch.setattr(os, "fsync", interrupted)
    with pytest.raises(raised):  # an OSError (a full disk) as one line naming the file
        save_library(stick_lib, path)
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["lib.json"]
    load_library(path)


def test_cli_refuses_a_broken_library_in_one_line(tmp_path):
    path = tmp_path / "bad.json"
    path.write_text('{"schema_version": 1, "robot": "freesn"')
    result = CliRunner().invoke(get_cli(), ["library", "show", str(path)])
    assert result.exit_code == 1
    assert str(path) in result.output and "Traceback" not in result.output
