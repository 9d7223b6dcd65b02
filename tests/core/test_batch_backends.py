"""The same library check and sweep serially, on the process pool and on Ray.

Two Ray clusters, each of 2 CPUs on this machine, no dashboard: one started in this
process (``ray.init``, the ``--cluster local`` path) and one started as a lab starts a
head (``ray start --head`` in a process of its own, on loopback, with the installed Ray's
default authentication), which ``platform`` reaches with ``--cluster 127.0.0.1:PORT``.
Without the ``cluster`` extra the Ray cases are skipped (they fail instead when
``MSRR_REQUIRE_RAY`` is set, as ``.ci/run`` does).
"""

from __future__ import annotations

import contextlib
import os
import pickle
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import pytest
from click.testing import CliRunner

from msrr.core.app.batch import ray_available
from msrr.core.app.cli import get_cli
from msrr.core.app.commands.sweep import InputFile, SweepTask
from msrr.core.app.feasibility import check_edges, default_runner
from msrr.core.errors import ExecutionError
from msrr.core.executor import ExecutorOptions
from msrr.core.library.check import edge_cases, load_check
from msrr.core.plugins import load_library

ROOT = Path(__file__).resolve().parents[2]
LIBRARY = ROOT / "plugins" / "freesn" / "libraries" / "S4N5.json"
EDGES = ("S4N5-1.1->S4N5-1.2", "S4N5-1.2->S4N5-1.3", "S4N5-2.2->S4N5-2.1")
SWEEP = ["sweep", "--robot", "mmrp", "--scenario", "series-t", "--driver", "kinematic",
         "--runs", "2", "--seed", "5", "--faults", "none", "--faults", "loss:p=0.2;latency:ticks=2"]


def _need_ray() -> None:
    if not ray_available():
        if os.environ.get("MSRR_REQUIRE_RAY"):  # .ci/run installs the extra
            pytest.fail("MSRR_REQUIRE_RAY is set but Ray is not installed")
        pytest.skip('Ray is not installed (pip install "msrr-platform[cluster]")')


@pytest.fixture(scope="module")
def ray_cluster():
    """A local Ray cluster of 2 CPUs in this process for this module (no dashboard)."""
    _need_ray()
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


class _RefusingDriver:
    """The real driver, refusing every command mid-run as a driver refuses a bad one."""

    def __init__(self, factory: object):
        self.factory, self.name = factory, "refusing"

    def __call__(self, **options: object) -> object:
        driver = self.factory(**options)  # type: ignore[operator]

        def refuse(*args: object, **kwargs: object) -> None:
            raise ExecutionError("commands for unknown module(s) ['X']")

        driver.send_action = refuse
        return driver


def test_an_error_the_platform_raises_in_a_run_is_a_failure_too():
    runner = default_runner("freesn", options=ExecutorOptions(action_timeout=10.0, retries=0))
    cases = [c for c in edge_cases(load_library(LIBRARY), runner.robot) if EDGES[0] in c.key]
    checks, batch = check_edges(cases, replace(runner, driver=_RefusingDriver(runner.driver)),
                                workers=1, progress=False)
    assert checks == [] and [f.error for f in batch.failures] == \
        ["ExecutionError: commands for unknown module(s) ['X']"]


def test_an_edge_that_raises_is_a_failure_never_an_infeasible_edge():
    runner = default_runner("freesn", options=ExecutorOptions(action_timeout=10.0, retries=0))
    cases = [c for c in edge_cases(load_library(LIBRARY), runner.robot) if EDGES[0] in c.key]
    broken = replace(runner, driver=_BrokenDriver())
    checks, batch = check_edges(cases, broken, workers=1, progress=False)
    assert checks == [] and batch.results == [None] * len(cases)  # no verdict at all
    assert [f.error for f in batch.failures] == ["RuntimeError: no simulator"] * len(cases)
    assert batch.failures[0].input == cases[0].key and "no simulator" in batch.failures[0].traceback


# --- a head started with `ray start`, as docs/scaling.md says -----------------------------

PLATFORM = [sys.executable, "-c", "import sys; from msrr.core.app.launch import main; "
            "sys.argv[0] = 'platform'; main()"]


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@pytest.fixture(scope="module")
def ray_head():
    """``ray start --head`` on loopback, 2 CPUs, in a session of its own: the address and
    the environment of a machine that has the cluster's token (``RAY_AUTH_TOKEN_PATH``;
    ``RAY_AUTH_MODE`` unset, so the installed Ray turns token authentication on by
    itself). Stopped by its process group at the end."""
    _need_ray()
    place = Path(tempfile.mkdtemp(prefix="msrr-ray-", dir="/tmp"))  # Ray's sockets: short paths
    (place / "token").write_text(secrets.token_hex(32))
    env = {k: v for k, v in os.environ.items() if k not in ("RAY_AUTH_MODE", "RAY_ADDRESS")}
    env["RAY_AUTH_TOKEN_PATH"] = str(place / "token")
    port = _free_port()
    log = (place / "head.log").open("w")
    head = subprocess.Popen(
        [str(Path(sys.executable).with_name("ray")), "start", "--head", "--node-ip-address",
         "127.0.0.1", "--port", str(port), "--num-cpus", "2", "--include-dashboard", "false",
         "--disable-usage-stats", "--temp-dir", str(place / "ray"), "--block"],
        env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        deadline = time.monotonic() + 90.0
        while "Ray runtime started" not in (place / "head.log").read_text():
            assert head.poll() is None, (place / "head.log").read_text()
            assert time.monotonic() < deadline, "the head did not start in 90 s"
            time.sleep(0.2)
        text = (place / "head.log").read_text()
        assert "Token authentication is enabled" in text  # Ray's default, a token being there
        yield f"127.0.0.1:{port}", env
    finally:
        for signum, wait in ((signal.SIGTERM, 2.0), (signal.SIGKILL, 10.0)):
            if head.poll() is None or _group_alive(head.pid):
                with contextlib.suppress(OSError):
                    os.killpg(head.pid, signum)
                with contextlib.suppress(subprocess.TimeoutExpired):
                    head.wait(timeout=wait)
        log.close()
        shutil.rmtree(place, ignore_errors=True)


def _group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except OSError:
        return False
    return True


def _run(args: list[str], cwd: Path, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*PLATFORM, *args], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=300)


def test_a_check_and_a_sweep_on_a_head_started_with_ray_start(tmp_path, ray_head, serial_check,
                                                             serial_sweep):
    address, env = ray_head
    (tmp_path / "S4N5.json").write_bytes(LIBRARY.read_bytes())
    args = ["library", "check", "S4N5.json", "--seed", "3", "--timeout", "10",
            "--cluster", address]
    for edge in EDGES:
        args += ["--edge", edge]
    done = _run(args, tmp_path, env)
    assert done.returncode == 0, done.stdout + done.stderr
    assert load_check(tmp_path / "S4N5.check.json").edges == serial_check
    done = _run([*SWEEP, "--cluster", address, "--out", "sweep"], tmp_path, env)
    assert done.returncode == 0, done.stdout + done.stderr
    assert (tmp_path / "sweep" / "sweep.csv").read_text() == serial_sweep


def test_from_and_to_travel_by_value(tmp_path, ray_head):
    """Relative --from/--to paths: Ray's workers run in folders of their own, so only
    files sent with the task can be read there."""
    address, env = ray_head
    configs = ROOT / "plugins" / "mmrp" / "configs"
    for name in ("series.json", "t.json"):
        (tmp_path / name).write_bytes((configs / name).read_bytes())
    pair = ["sweep", "--robot", "mmrp", "--from", "series.json", "--to", "t.json", "--driver",
            "kinematic", "--runs", "2"]
    done = _run([*pair, "--cluster", address, "--out", "on-ray"], tmp_path, env)
    assert done.returncode == 0, done.stdout + done.stderr
    here = _run([*pair, "--workers", "1", "--out", "here"], tmp_path, env)
    assert here.returncode == 0, here.stdout + here.stderr
    table = (tmp_path / "on-ray" / "sweep.csv").read_text()
    assert table == (tmp_path / "here" / "sweep.csv").read_text() and ",True," in table
    task = SweepTask(robot="mmrp", scenario=None, start=InputFile.read(tmp_path / "series.json"),
                     goal=InputFile.read(tmp_path / "t.json"), seed=0)
    assert str(tmp_path).encode() not in pickle.dumps(task)  # no local path travels


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads /proc")
def test_sigkill_of_a_command_with_a_local_ray_cluster_leaves_no_process_of_it(tmp_path):
    _need_ray()
    from batch_tasks import alive, command_line, descendants

    process = subprocess.Popen([*PLATFORM, *SWEEP[:-2], "--runs", "2000", "--cluster", "local",
                                "--workers", "2", "--out", "sweep"], cwd=tmp_path,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120.0
        while not (tmp_path / "sweep" / "sweep.csv.journal").exists() \
                or (tmp_path / "sweep" / "sweep.csv.journal").read_text().count("\n") < 3:
            assert process.poll() is None and time.monotonic() < deadline
            time.sleep(0.1)
        started = descendants(process.pid)
        assert any("raylet" in command_line(p) for p in started)
        process.kill()
        process.wait(timeout=10)
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline and any(alive(p) for p in started):
            time.sleep(0.1)
        assert [command_line(p)[:80] for p in started if alive(p)] == []
    finally:
        process.kill()
