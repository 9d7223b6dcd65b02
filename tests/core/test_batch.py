"""core/app/batch.py on the serial and pool backends (Ray: test_batch_backends.py)."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from functools import partial
from pathlib import Path

import pytest

from msrr.core.app import batch
from msrr.core.app.batch import BatchError, backend_for, run_batch, task_seed
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
        for _ in range(600):  # both workers have started a task (at most a minute)
            markers = sorted(tmp_path.glob("task*"))
            if len(markers) == 2 and all(m.read_text() for m in markers):
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
    assert len(pids) == 2 and len(list(tmp_path.glob("task*"))) == 2  # the rest never ran
    for pid in pids:  # the workers were stopped, not left sleeping
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)
