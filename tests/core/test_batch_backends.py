"""The same library check and sweep serially, on the process pool and on a local Ray cluster.

The Ray cluster (2 CPUs, this machine only, no dashboard) starts once for this module, the
only one that uses it; without the ``cluster`` extra the Ray cases are skipped (they fail
instead when ``MSRR_REQUIRE_RAY`` is set, as ``.ci/run`` does).
"""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path

import pytest
from click.testing import CliRunner

from msrr.core.app.batch import ray_available
from msrr.core.app.cli import get_cli
from msrr.core.app.feasibility import check_edges, default_runner
from msrr.core.executor import ExecutorOptions
from msrr.core.library.check import edge_cases, load_check
from msrr.core.plugins import load_library

ROOT = Path(__file__).resolve().parents[2]
LIBRARY = ROOT / "plugins" / "freesn" / "libraries" / "S4N5.json"
EDGES = ("S4N5-1.1->S4N5-1.2", "S4N5-1.2->S4N5-1.3", "S4N5-2.2->S4N5-2.1")
SWEEP = ["sweep", "--robot", "mmrp", "--scenario", "series-t", "--driver", "kinematic",
         "--runs", "2", "--seed", "5", "--faults", "none", "--faults", "loss:p=0.2;latency:ticks=2"]


@pytest.fixture(scope="module")
def ray_cluster():
    """A local Ray cluster of 2 CPUs for this module (loopback only, no dashboard)."""
    if not ray_available():
        if os.environ.get("MSRR_REQUIRE_RAY"):  # .ci/run installs the extra
            pytest.fail("MSRR_REQUIRE_RAY is set but Ray is not installed")
        pytest.skip('Ray is not installed (pip install "msrr-platform[cluster]")')
    import ray
    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False,
             logging_level="ERROR", _node_ip_address="127.0.0.1")
    yield ray
    ray.shutdown()


BACKENDS = [pytest.param(["--workers", "2"], id="pool"),
            pytest.param(["--cluster", "local"], id="ray")]


@pytest.fixture(params=BACKENDS)
def parallel(request: pytest.FixtureRequest) -> list[str]:
    """The options of a parallel backend; Ray's start the module's cluster first."""
    if "--cluster" in request.param:
        request.getfixturevalue("ray_cluster")
    return request.param


@pytest.fixture(scope="module")
def serial_check():
    """The S4N5 edges checked in this process (the reference)."""
    runner = default_runner("freesn", options=ExecutorOptions(action_timeout=10.0, retries=0),
                            seed=3)
    cases = [c for c in edge_cases(load_library(LIBRARY), runner.robot)
             if any(e in c.key for e in EDGES)]
    checks, batch = check_edges(cases, runner, workers=1, progress=False)
    assert batch.backend == "serial" and len(checks) == len(EDGES)
    return checks


def test_library_check_is_the_same_on_every_backend(tmp_path, serial_check, parallel):
    library = tmp_path / "S4N5.json"
    library.write_bytes(LIBRARY.read_bytes())
    args = ["library", "check", str(library), "--seed", "3", "--timeout", "10"]
    for edge in EDGES:
        args += ["--edge", edge]
    result = CliRunner().invoke(get_cli(), args + parallel)
    assert result.exit_code == 0, result.output
    check = load_check(tmp_path / "S4N5.check.json")
    assert check.edges == serial_check
    assert all(c.feasible and c.sim_time > 0 for c in check.edges)


@pytest.fixture(scope="module")
def serial_sweep(tmp_path_factory):
    out = tmp_path_factory.mktemp("sweep") / "serial"
    result = CliRunner().invoke(get_cli(), [*SWEEP, "--workers", "1", "--out", str(out)])
    assert result.exit_code == 0, result.output
    return (out / "sweep.csv").read_text()


def test_sweep_table_is_the_same_on_every_backend(tmp_path, serial_sweep, parallel):
    result = CliRunner().invoke(get_cli(), [*SWEEP, *parallel, "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "sweep.csv").read_text() == serial_sweep
    lines = serial_sweep.splitlines()
    assert len(lines) == 5 and [line.split(",")[1] for line in lines[1:]] == ["5", "6", "5", "6"]


class _BrokenDriver:
    """A driver factory whose simulator cannot start (a bug, not an infeasible edge)."""

    name = "broken"

    def __call__(self, **options: object) -> None:
        raise RuntimeError("no simulator")


def test_an_edge_that_raises_is_a_failure_never_an_infeasible_edge():
    runner = default_runner("freesn", options=ExecutorOptions(action_timeout=10.0, retries=0))
    cases = [c for c in edge_cases(load_library(LIBRARY), runner.robot) if EDGES[0] in c.key]
    broken = replace(runner, driver=_BrokenDriver())
    checks, batch = check_edges(cases, broken, workers=1, progress=False)
    assert checks == [] and batch.results == [None] * len(cases)  # no verdict at all
    assert [f.error for f in batch.failures] == ["RuntimeError: no simulator"] * len(cases)
    assert batch.failures[0].input == cases[0].key and "no simulator" in batch.failures[0].traceback
