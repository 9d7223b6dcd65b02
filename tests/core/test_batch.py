"""core/app/batch.py on the serial and pool backends (Ray: test_batch_backends.py)."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from functools import partial
from pathlib import Path

import pytest
from batch_tasks import (
    alive,
    command_line,
    descendants,
    lose_worker_always,
    lose_worker_once,
    pid_of,
)

from msrr.core.app import batch
from msrr.core.app.batch import BatchError, backend_for, run_batch, task_seed
from msrr.core.app.pool import Pool
from msrr.core.errors import ConfigurationError
from msrr.core.faults import parse_faults

HERE = Path(__file__).resolve().parent
SPECS = ["loss:p=0.1", "dropout:module=3,at=5", "bogus", "latency:ticks=2", "noise:sigma=2",
         "nan:at=1", "loss:p=2", "dock-fail"]


def test_task_seed_is_a_function_of_base_and_key():
    assert task_seed(0, "a") == task_seed(0, "a")
    seeds = {task_seed(base, key) for base in range(5) for key in "abcdefgh"}
    assert len(seeds) == 40 and all(0 <= s < 2 ** 63 for s in seeds)
    # a function of the text only (no hash randomisation, no worker): pinned
    assert task_seed(7, "edge-3") == 7429554660490620997


def test_backend_is_chosen_by_workers_and_cluster():
    assert backend_for(1) == "serial" and backend_for(0) == "pool" and backend_for(4) == "pool"
    assert backend_for(1, "auto") == "ray"
    with pytest.raises(ConfigurationError, match="--workers"):
        backend_for(-1)


def _expected(specs):
    out, failed = [], []
    for i, spec in enumerate(specs):
        try:
            out.append(parse_faults(spec))
        except ConfigurationError as exc:
            out.append(None)
            failed.append((i, f"ConfigurationError: {exc}"))
    return out, failed


@pytest.mark.parametrize("backend", ["serial", "pool"])
def test_results_in_task_order_and_failures_keep_the_others(backend):
    expected, failed = _expected(SPECS)
    assert [i for i, _ in failed] == [2, 6]  # bogus and loss:p=2 are refused
    # the cost hint starts the last tasks first on the pool: the results stay in task order
    result = run_batch(parse_faults, SPECS, keys=[f"spec{i}" for i in range(len(SPECS))],
                       workers=2, backend=backend, progress=False, cost=range(len(SPECS)))
    assert result.backend == backend and result.workers == (2 if backend == "pool" else 1)
    assert result.results == expected
    assert [(f.index, f.error) for f in result.failures] == failed
    failure = result.failures[0]
    assert failure.key == f"spec{failure.index}" and failure.input == repr(SPECS[failure.index])
    assert "parse_faults" in failure.traceback
    assert f"task spec{failure.index}" in str(failure)
    with pytest.raises(BatchError, match="2 of 8 tasks failed"):
        result.values()


def test_partial_functions_and_one_worker_run_here():
    seeds = run_batch(partial(task_seed, 11), ["a", "b", "c"], workers=1, progress=False)
    assert seeds.backend == "serial" and seeds.values() == [task_seed(11, k) for k in "abc"]
    # a pool of one task would have one worker: this process runs it
    assert run_batch(partial(task_seed, 11), ["a"], workers=2, progress=False).backend == "serial"


def test_keys_must_match_the_tasks():
    with pytest.raises(BatchError, match="2 keys for 3 tasks"):
        run_batch(parse_faults, ["", "", ""], keys=["a", "b"], workers=1)
    with pytest.raises(BatchError, match="1 costs for 3 tasks"):
        run_batch(parse_faults, ["", "", ""], cost=[1.0], workers=1)


def test_ray_missing_is_one_line_with_the_install_command(monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)
    assert not batch.ray_available()
    with pytest.raises(BatchError, match=r"needs Ray: pip install \"msrr-platform\[cluster\]\""):
        run_batch(parse_faults, ["loss:p=0.1"], cluster="auto", progress=False)


SCRIPT = """
import sys
sys.path.insert(0, {here!r})
from batch_tasks import mark_and_sleep
from msrr.core.app.batch import exit_on_interrupt, run_batch
from msrr.core.interrupts import install
if __name__ == "__main__":
    install()
    with exit_on_interrupt():
        run_batch(mark_and_sleep, [{folder!r} + f"/task{{i}}" for i in range(6)], workers=2,
                  backend="pool", label="sleeps")
"""


def test_ctrl_c_cancels_the_pool_in_one_line(tmp_path):
    script = tmp_path / "batch_script.py"
    script.write_text(SCRIPT.format(here=str(HERE), folder=str(tmp_path)))
    process = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    try:
        # this process started the shortest task while its workers started, then both
        # workers took one (at most a minute)
        for _ in range(600):
            markers = sorted(tmp_path.glob("task*"))
            if len(markers) == 3 and all(m.read_text() for m in markers):
                break
            assert process.poll() is None, process.communicate()
            time.sleep(0.1)
        pids = [int(m.read_text()) for m in sorted(tmp_path.glob("task*"))]
        process.send_signal(2)  # SIGINT
        _, err = process.communicate(timeout=30)  # the tasks would sleep 60 s
    finally:
        process.kill()
    assert process.returncode == 130
    assert err.strip().splitlines() == ["Error: interrupted (SIGINT): 0/6 sleeps done, the rest "
                                        "cancelled"]
    assert len(pids) == 3 and len(list(tmp_path.glob("task*"))) == 3  # the rest never ran
    assert (tmp_path / "task5").read_text() == str(process.pid)  # the shortest: here
    for pid in pids:  # the workers were stopped, not left sleeping
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)


# --- lost workers, small batches, parent death, late signals -----------------------------

def test_a_lost_worker_costs_only_its_task_and_the_task_runs_again(tmp_path):
    parent = os.getpid()
    items = [(str(tmp_path / "lost"), 10, parent)] + [(str(tmp_path / f"m{i}"), i, -1)
                                                     for i in range(1, 4)]
    for item in items[1:]:
        Path(item[0]).write_text("not this one")
    pool = Pool(2, retries=1, warm_up=False)
    outcomes = dict(pool.run(lose_worker_once, items, range(4)))
    assert {i: (ok, value) for i, (ok, value, _) in outcomes.items()} == \
        {0: (True, 10), 1: (True, 1), 2: (True, 2), 3: (True, 3)}
    assert pool.retried == [(0, "the worker was killed by SIGKILL")]
    killed = int((tmp_path / "lost").read_text())
    assert not alive(killed) and killed != parent


def test_a_task_whose_worker_is_always_lost_fails_with_the_reason():
    parent = os.getpid()
    pool = Pool(2, retries=1, warm_up=False)
    # the other worker is idle long before the task is queued again: it takes it
    outcomes = dict(pool.run(lose_worker_always, [(7, parent, 0.3), (8, None, 0.0)], [0, 1]))
    ok, (error, trace), _ = outcomes[0]
    assert not ok and error == "WorkerLost: the worker was killed by SIGKILL (2 attempts)"
    assert outcomes[1][:2] == (True, 8)
    # through run_batch: a TaskFailure like any other, never a result (the tasks this
    # process ran while the workers started are results: it is their parent)
    result = run_batch(lose_worker_always, [(i, parent, 0.0) for i in range(6)], workers=2,
                       backend="pool", progress=False, retries=0)
    failed = {f.index: f.error for f in result.failures}
    for index, value in enumerate(result.results):
        assert (value, failed.get(index)) in ((index, None), (None, "WorkerLost: the worker "
                                                              "was killed by SIGKILL (1 attempt)"))


def test_a_batch_too_small_for_a_pool_runs_here():
    result = run_batch(pid_of, ["a", "b", "c"], workers=2, backend="pool", progress=False)
    assert result.backend == "pool" and result.values() == [os.getpid()] * 3


KILL_SCRIPT = """
import sys
sys.path.insert(0, {here!r})
from batch_tasks import mark_and_sleep
from msrr.core.app.batch import run_batch
if __name__ == "__main__":
    run_batch(mark_and_sleep, [{folder!r} + f"/task{{i}}" for i in range(6)], workers=2,
              backend="pool", label="sleeps")
"""


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads /proc")
def test_sigkill_of_the_parent_leaves_no_process_of_it(tmp_path):
    script = tmp_path / "kill_script.py"
    script.write_text(KILL_SCRIPT.format(here=str(HERE), folder=str(tmp_path)))
    process = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL)
    try:
        for _ in range(600):  # this process and both workers sleep in a task
            markers = sorted(tmp_path.glob("task*"))
            if len(markers) == 3 and all(m.read_text() for m in markers):
                break
            assert process.poll() is None
            time.sleep(0.1)
        started = descendants(process.pid)
        assert len(started) >= 4  # the forkserver, two workers, the resource tracker
        process.kill()
        process.wait(timeout=10)
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline and any(alive(p) for p in started):
            time.sleep(0.1)
        assert [command_line(p) for p in started if alive(p)] == []
    finally:
        process.kill()


FINISH_SCRIPT = """
import os, signal, sys, time
from msrr.core.app.batch import finishing
from msrr.core.interrupts import install
if __name__ == "__main__":
    install()
    with finishing("out.txt was written"):
        if sys.argv[1] == "inside":
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.2)
        print("written", flush=True)
    os.kill(os.getpid(), signal.SIGINT)  # the command is done: this changes nothing
    time.sleep(0.2)
    print("done", flush=True)
"""


@pytest.mark.parametrize(("where", "code", "out", "err"), [
    ("inside", 130, ["written"], ["Error: interrupted (SIGINT) after out.txt was written"]),
    ("after", 0, ["written", "done"], []),
])
def test_a_signal_while_finishing_waits_and_one_after_changes_nothing(tmp_path, where, code,
                                                                       out, err):
    script = tmp_path / "finish_script.py"
    script.write_text(FINISH_SCRIPT)
    done = subprocess.run([sys.executable, str(script), where], capture_output=True, text=True,
                          timeout=60)
    assert (done.returncode, done.stdout.split(), done.stderr.strip().splitlines()) == \
        (code, out, err)


def test_progress_without_a_terminal_is_lines_with_counts_and_an_estimate(
        capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    clock = iter(range(0, 1000, 6))  # six seconds of wall time pass between looks
    monkeypatch.setattr(batch.time, "monotonic", lambda: float(next(clock)))
    run_batch(partial(task_seed, 3), [str(i) for i in range(5)], workers=1, label="runs")
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == "runs (serial, 1 worker): 5 to do"
    assert any(" done" in line and "s left" in line for line in lines[1:-1])
    assert lines[-1].startswith("runs (serial, 1 worker): 5/5 done, ") and "left" not in lines[-1]
