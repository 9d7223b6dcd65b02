"""The FreeSN libraries (paper sections 6-7, Figs. 14, 18-22): the shipped files rebuilt byte
for byte under several BLAS kernels, the S6N3 build of Fig. 14, retrieval of Figs. 19-22,
and the ``platform library`` commands on them."""

from __future__ import annotations

import itertools
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from msrr.core.actions import classify
from msrr.core.app.cli import get_cli
from msrr.core.configuration import Configuration
from msrr.core.io import save_configuration
from msrr.core.library import (
    RetrievalError,
    build_library,
    build_steps,
    load_library,
    load_sources,
    shortest_path,
)
from msrr.core.library.retrieve import retrieve
from msrr.core.plan import ActionType
from msrr.core.plugins import resolve

from msrr_test_support import brute_force_cost, check_sequence

FREESN = Path(__file__).resolve().parents[3] / "plugins" / "freesn"
NAMES = ["S6N3", "S4N5", "S12N6"]
FREESN_ROBOT = resolve("freesn")
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


# -- the S6N3 build (Fig. 14) and retrieval (Figs. 19-22) -------------------------------


def source_files(name: str) -> list[Path]:
    return sorted((FREESN / "library_sources" / name).glob("*.json"))


def relabelled(config: Configuration, prefix: str, *, noise: float, seed: int
               ) -> Configuration:
    """``config`` with every id renamed and every ``z`` perturbed by ``noise`` (std, unitless)."""
    rng = np.random.default_rng(seed)
    out = config.relabel({v: f"{prefix}{i}" for i, v in enumerate(reversed(config.vertices()))},
                         {e: f"{prefix}e{i}" for i, e in enumerate(reversed(config.edge_ids()))})
    z = {e.id: e.z + rng.normal(scale=noise, size=3) for e in out.edges()}
    return out.with_vectors(z={k: v / np.linalg.norm(v) for k, v in z.items()}, x={})


@pytest.fixture(scope="module")
def libraries():
    return {name: load_library(FREESN / "libraries" / f"{name}.json") for name in NAMES}


def system_from(library, key, seed=3, noise=0.03):
    _, config = library.find_configuration(key)
    return relabelled(config.configuration, "m", noise=noise, seed=seed)


def test_s6n3_build_merges_the_two_directions_of_fig20(libraries):
    sources = load_sources(source_files("S6N3"), resolve)
    (sub,) = libraries["S6N3"].sublibraries.values()
    assert list(sub.groups) == ["S6N3-1", "S6N3-2", "S6N3-3", "S6N3-4"]     # Fig. 14(f)
    assert len(sub.configurations) < build_steps(sources)
    assert len(sub.configuration("aim-S5").origins) == 2
    wheels = sub.behaviors["wheeled-move"]
    assert wheels.kind == "mapping" and wheels.parameters == ("speed", "yaw_rate")
    assert {c.module for c in wheels.commands} <= set(
        sub.configurations[wheels.start].configuration.modules())
    for edge in sub.edges:
        before = sub.configurations[edge.source].configuration
        after = sub.configurations[edge.target].configuration
        assert classify(before, after, edge.module_map(before)) is edge.action
        assert FREESN_ROBOT.rules.check_action(before, after) == []
    (never,) = build_library(sources, FREESN_ROBOT, merge_threshold=-1.0).sublibraries.values()
    assert len(never.configurations) == build_steps(sources)


@pytest.mark.parametrize("seed", [1, 2])
def test_retrieval_of_fig20_from_a_relabelled_perturbed_copy(libraries, seed):
    s6n3 = libraries["S6N3"]
    system = system_from(s6n3, "fig20a", seed=seed)
    result = retrieve(s6n3, system, FREESN_ROBOT, to="fig20d")
    assert result.start == "S6N3-1.1"
    assert result.steps[-1].library_id == s6n3.find_configuration("fig20d")[1].id
    check_sequence(system, result.steps, FREESN_ROBOT)
    assert {s.action for s in result.steps} >= {ActionType.MOVING, ActionType.CONNECTION}
    back = retrieve(s6n3, result.steps[-1].target, FREESN_ROBOT, to="fig20a")
    check_sequence(result.steps[-1].target, back.steps, FREESN_ROBOT)
    assert ActionType.DISCONNECTION in {s.action for s in back.steps}


@pytest.mark.parametrize("name", ["S6N3", "S12N6"])
def test_shortest_path_matches_brute_force(libraries, name):
    (sub,) = libraries[name].sublibraries.values()
    graph = sub.graph()
    for start, target in itertools.permutations(sub.configurations, 2):
        expected = brute_force_cost(sub, start, target)
        if expected is None:
            with pytest.raises(RetrievalError):
                shortest_path(sub, start, target)
            continue
        path = shortest_path(sub, start, target)
        assert sum(graph[u][v]["cost"] for u, v in itertools.pairwise(path)) == \
            pytest.approx(expected)


def test_fig22_parallel_reconfiguration_and_unreachable_groups(libraries):
    s12n6 = libraries["S12N6"]
    system = system_from(s12n6, "fig22a", noise=0.02)
    with pytest.raises(RetrievalError, match=r"reachable groups: S12N6-1 \(octahedron\), "
                       r"S12N6-4 \(open-face\), S12N6-5 \(open-face-and-edge\)"):
        retrieve(s12n6, system, FREESN_ROBOT, to="fig21a")
    result = retrieve(s12n6, system, FREESN_ROBOT, behavior="node-wheels")
    check_sequence(system, result.steps, FREESN_ROBOT)
    assert ActionType.PARALLEL_DISCONNECTION in {s.action for s in result.steps}
    assert {c.module for c in result.commands} <= set(system.modules())


def test_fig19_looping_crawl_comes_back_to_its_start(libraries):
    s4n5 = libraries["S4N5"]
    system = system_from(s4n5, "star-flat")
    result = retrieve(s4n5, system, FREESN_ROBOT, behavior="crawl")
    check_sequence(system, [*result.steps, *result.behavior_steps], FREESN_ROBOT)
    assert result.behavior_steps[-1].library_id == result.behavior.start
    assert len(result.behavior_steps) == 2   # crawl-low, back to standup
    with pytest.raises(RetrievalError, match="reachable groups: S4N5-1"):
        retrieve(s4n5, system, FREESN_ROBOT, to="squirm-up")


def test_cli_build_show_retrieve(tmp_path):
    runner = CliRunner()
    out = tmp_path / "S6N3.json"
    built = runner.invoke(get_cli(), ["library", "build", *map(str, source_files("S6N3")),
                                      "-o", str(out)])
    assert built.exit_code == 0, built.output
    assert "S6N3: 4 groups" in built.output
    assert out.read_text() == (FREESN / "libraries" / "S6N3.json").read_text()
    shown = runner.invoke(get_cli(), ["library", "show", str(out)])
    assert shown.exit_code == 0, shown.output
    for title in ("groups", "configurations", "behaviors", "action edges"):
        assert f"S6N3: {title}" in shown.output
    system = system_from(load_library(out), "fig20a", seed=4, noise=0.02)
    path = tmp_path / "system.json"
    save_configuration(system, path)
    got = runner.invoke(get_cli(), ["library", "retrieve", str(out), "--from", str(path),
                                    "--behavior", "wheeled-move"])
    assert got.exit_code == 0, got.output
    assert "wheeled-move commands" in got.output and "me" in got.output


def test_cli_bad_source_is_one_line_with_file_and_field(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"schema_version": 1, "robot": "freesn", "sequences": [{"name": "s", '
                   '"steps": [{"configuration": {"schema_version": 1, "robot": "freesn", '
                   '"modules": [{"id": "N1", "kind": "blob"}]}}]}]}')
    result = CliRunner().invoke(get_cli(), ["library", "build", str(bad), "-o",
                                            str(tmp_path / "x.json")])
    assert result.exit_code == 1
    assert str(bad) in result.output and "sequences[0].steps[0].configuration" in result.output
    assert "Traceback" not in result.output and not (tmp_path / "x.json").exists()
