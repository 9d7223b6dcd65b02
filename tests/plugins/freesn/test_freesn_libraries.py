"""The shipped FreeSN libraries: rebuilt byte for byte under several BLAS kernels, and
retrieval from the CLI."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
from click.testing import CliRunner

from msrr.core.cli import get_cli
from msrr.core.io import save_configuration
from msrr.core.library import load_library

FREESN = Path(__file__).resolve().parents[3] / "plugins" / "freesn"
NAMES = ["S6N3", "S4N5", "S12N6"]
KERNELS = ["Haswell", "SkylakeX", "Sandybridge"]
"""OpenBLAS kernels this x86-64 CI CPU runs (``OPENBLAS_CORETYPE``; numpy's and scipy's
OpenBLAS both honour it, as ``threadpoolctl`` reports)."""

REBUILD = """
import sys
from pathlib import Path
from threadpoolctl import threadpool_info
from msrr.core.library import build_library, dump_library, load_library, load_sources
from msrr.core.plugins import resolve
kernels = {i.get("architecture") for i in threadpool_info() if i["internal_api"] == "openblas"}
print("kernel", *sorted(kernels))
for name in sys.argv[2:]:
    shipped = Path(sys.argv[1]) / "libraries" / f"{name}.json"
    built = load_library(shipped).build
    sources = load_sources(sorted((Path(sys.argv[1]) / "library_sources" / name).glob("*.json")),
                           resolve)
    text = dump_library(build_library(sources, resolve(sources.robot),
                                      merge_threshold=built["merge_threshold"],
                                      cost=built["cost"]))
    print(name, "identical" if text == shipped.read_text() else "differs")
"""


def test_shipped_libraries_rebuild_byte_for_byte_under_every_blas_kernel():
    """``docs/library.md``: the same sources give the same file on any machine."""
    runs = {kernel: subprocess.Popen(
        [sys.executable, "-c", REBUILD, str(FREESN), *NAMES], stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True, env={**os.environ, "OPENBLAS_CORETYPE": kernel,
                                                 "OPENBLAS_NUM_THREADS": "1"})
        for kernel in KERNELS}
    for kernel, run in runs.items():
        out, err = run.communicate(timeout=120)
        assert run.returncode == 0, err
        lines = out.splitlines()
        assert lines[0] == f"kernel {kernel}", f"OpenBLAS ignored OPENBLAS_CORETYPE: {lines[0]}"
        stale = [line.split()[0] for line in lines[1:] if not line.endswith("identical")]
        assert len(lines) == 1 + len(NAMES) and not stale, (
            f"under {kernel}, {stale} rebuild differently from the shipped files: rebuild "
            "with `platform library build plugins/freesn/library_sources/<NAME>/*.json "
            "-o plugins/freesn/libraries/<NAME>.json`")


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
