"""The shipped FreeSN libraries: rebuilt from their sources, and retrieval from the CLI."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from msrr.core.cli import get_cli
from msrr.core.io import save_configuration
from msrr.core.library import build_library, dump_library, load_library, load_sources

FREESN = Path(__file__).resolve().parents[3] / "plugins" / "freesn"
NAMES = ["S6N3", "S4N5", "S12N6"]


@pytest.mark.parametrize("name", NAMES)
def test_shipped_library_is_exactly_what_its_sources_build(name):
    shipped = FREESN / "libraries" / f"{name}.json"
    library = load_library(shipped)
    sources = load_sources(sorted((FREESN / "library_sources" / name).glob("*.json")))
    rebuilt = build_library(sources, merge_threshold=library.build["merge_threshold"],
                            cost=library.build["cost"])
    mismatch = _first_difference(json.loads(dump_library(rebuilt)), json.loads(shipped.read_text()))
    assert mismatch is None, (
        f"{shipped} is stale at {mismatch}: rebuild it with `platform library build "
        f"plugins/freesn/library_sources/{name}/*.json -o {shipped}`")


def _first_difference(a, b, where: str = "") -> str | None:
    """Where two JSON documents differ; numbers may differ by IK round-off (1e-4 relative)."""
    if isinstance(a, dict) and isinstance(b, dict):
        if a.keys() != b.keys():
            return f"{where or '(top)'} keys {sorted(a.keys() ^ b.keys())}"
        return next((d for k in a if (d := _first_difference(a[k], b[k], f"{where}.{k}"))), None)
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return f"{where} length {len(a)} != {len(b)}"
        return next((d for i, (x, y) in enumerate(zip(a, b, strict=True))
                     if (d := _first_difference(x, y, f"{where}[{i}]"))), None)
    if isinstance(a, float | int) and isinstance(b, float | int) and not isinstance(a, bool):
        return None if math.isclose(a, b, rel_tol=1e-4, abs_tol=1e-7) else f"{where}: {a} != {b}"
    return None if a == b else f"{where}: {a!r} != {b!r}"


def test_shipped_libraries_cover_the_paper_figures():
    s6n3 = load_library(FREESN / "libraries" / "S6N3.json").sublibraries["S6N3"]
    assert len(s6n3.groups) == 4                                   # Fig. 14(f)
    assert {"fig20a", "fig20d"} <= {n for c in s6n3.configurations.values() for n in c.names}
    s12n6 = load_library(FREESN / "libraries" / "S12N6.json").sublibraries["S12N6"]
    names = {g.name for g in s12n6.groups.values()}
    assert {"octahedron", "hexagonal-star", "tree"} <= names        # Figs. 21-22
    assert {"wheeled-move", "node-wheels"} <= set(s12n6.behaviors)  # Fig. 18, 22
    s4n5 = load_library(FREESN / "libraries" / "S4N5.json").sublibraries["S4N5"]
    assert s4n5.behaviors["squirm"].loop and s4n5.behaviors["crawl"].loop   # Fig. 19
    assert s4n5.behaviors["node-wheels"].kind == "mapping"                  # Fig. 18(a)-(c)


def test_cli_retrieves_fig20d_from_a_relabelled_triangle_with_three_legs(tmp_path):
    library = load_library(FREESN / "libraries" / "S6N3.json")
    reference = library.sublibraries["S6N3"].configuration("fig20a").configuration
    renames = {"N1": "B", "N2": "C", "N3": "A"}
    system = reference.relabel(renames, {f"S{i}": f"strut{7 - i}" for i in range(1, 7)})
    rng = np.random.default_rng(5)
    z = {e.id: (e.z + rng.normal(scale=0.03, size=3)) for e in system.edges()}
    system = system.with_vectors(z={k: v / np.linalg.norm(v) for k, v in z.items()}, x={})
    path = tmp_path / "system.json"
    save_configuration(system, path)
    result = CliRunner().invoke(get_cli(), ["library", "retrieve",
                                            str(FREESN / "libraries" / "S6N3.json"),
                                            "--from", str(path), "--to", "fig20d"])
    assert result.exit_code == 0, result.output
    target = library.sublibraries["S6N3"].configuration("fig20d").id
    assert f"ends at {target}" in result.output
    assert "connection" in result.output and "strut" in result.output
