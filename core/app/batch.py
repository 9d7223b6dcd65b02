"""Batch work: one interface, run serially, on a local process pool or on a Ray cluster.

A batch is a pure function ``fn(item) -> result`` applied to a list of serialisable
items (a library's edges, a sweep's runs, a benchmark's instances). :func:`run_batch`
picks the backend from two options every batch command takes:

==================  =====================================================================
``--workers N``     ``1``: in this process (``serial``); ``N > 1``: a local process pool
                    of ``N`` workers (``pool``); ``0`` (default): one worker per core
``--cluster ADDR``  Ray (``pip install "msrr-platform[cluster]"``): ``auto`` (the cluster
                    this machine belongs to), ``ray://host:10001`` (a remote cluster's
                    client port), or ``local`` (start a cluster of ``N`` CPUs here)
==================  =====================================================================

Guarantees, whichever backend runs the batch:

* results are returned in item order (index ``i`` holds ``fn(items[i])``), never in the
  order workers finished; a task that needs randomness takes its seed from its item
  (:func:`task_seed` derives one from a base seed and the task's key), never from the
  worker, so serial, pool and Ray give the same results;
* a task that raises is reported as a :class:`TaskFailure` with its key, its input and
  the traceback, and the other tasks' results are kept;
* progress is shown on the console (rich), one bar per batch;
* Ctrl-C (or SIGTERM) cancels the tasks not yet started, stops the workers, prints one
  line and re-raises the interruption (``platform`` exits 130).

The pool starts its workers with the ``forkserver`` method (``spawn`` where there is
none): MuJoCo and PyBullet must not be forked after they were initialised. Workers
ignore SIGINT (the terminal sends it to the whole process group); the parent decides.
"""

from __future__ import annotations

import contextlib
import hashlib
import multiprocessing
import os
import signal
import time
import traceback
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from typing import Any, Generic, TypeVar

import click
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
)
from threadpoolctl import threadpool_limits

from ..console import console, err_console
from ..errors import ConfigurationError, MsrrError
from ..interrupts import Interrupted

__all__ = ["BACKENDS", "BatchError", "BatchResult", "TaskFailure", "available_cores",
           "backend_for", "batch_options", "exit_on_interrupt", "ray_available", "run_batch",
           "task_seed"]

T = TypeVar("T")
R = TypeVar("R")

BACKENDS = ("serial", "pool", "ray")
RAY_HINT = 'pip install "msrr-platform[cluster]"'
_INPUT_CHARS = 300


class BatchError(MsrrError):
    """A batch could not run, or some of its tasks failed (the message lists them)."""


def task_seed(base: int, key: str) -> int:
    """A task's seed in ``[0, 2**63)``: SHA-256 of ``"<base>/<key>"``.

    The same for a given base seed and task key on every machine and backend, and
    unrelated for different keys (no two tasks share a random stream by accident).
    """
    digest = hashlib.sha256(f"{int(base)}/{key}".encode()).digest()
    return int.from_bytes(digest[:8], "big") >> 1


def available_cores() -> int:
    """Cores this process may run on (its CPU affinity), at least 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # no sched_getaffinity (macOS, Windows)
        return max(1, os.cpu_count() or 1)


def ray_available() -> bool:
    """Whether the ``cluster`` extra (Ray) is installed."""
    try:
        import ray  # noqa: F401
    except ImportError:
        return False
    return True


def backend_for(workers: int = 0, cluster: str | None = None) -> str:
    """The backend ``--workers``/``--cluster`` select: ``ray`` with a cluster, ``serial``
    for one worker, else ``pool``.

    Raises:
        ConfigurationError: ``workers`` is negative.
    """
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 0:
        raise ConfigurationError(f"must be a whole number >= 0 (0: every core), got {workers!r}",
                                 field="--workers")
    if cluster:
        return "ray"
    return "serial" if workers == 1 else "pool"


@dataclass(frozen=True)
class TaskFailure:
    """A task that raised.

    Attributes:
        index: the task's position in the batch.
        key: the task's key.
        input: ``repr`` of its input (cut to 300 characters).
        error: ``"<ExceptionType>: <message>"``.
        traceback: the worker's formatted traceback.
    """

    index: int
    key: str
    input: str
    error: str
    traceback: str = ""

    def __str__(self) -> str:
        return f"task {self.key}: {self.error} (input {self.input})"


@dataclass
class BatchResult(Generic[R]):
    """The outcome of a batch, in task order.

    Attributes:
        keys: every task's key.
        results: ``fn(items[i])`` at index ``i``; ``None`` where the task failed.
        failures: the tasks that raised, by index.
        backend: ``serial``, ``pool`` or ``ray``.
        workers: worker processes (Ray: the cluster's CPUs).
        wall_time: wall-clock time of the whole batch [s], start-up included.
        task_times: wall-clock time of each task in its worker [s] (``nan`` if failed).
    """

    keys: list[str]
    results: list[R | None]
    failures: list[TaskFailure] = field(default_factory=list)
    backend: str = "serial"
    workers: int = 1
    wall_time: float = 0.0
    task_times: list[float] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        """No task failed."""
        return not self.failures

    def values(self) -> list[R]:
        """Every result, in task order.

        Raises:
            BatchError: a task failed (every failure named with its input).
        """
        if self.failures:
            lines = "; ".join(str(f) for f in self.failures[:5])
            more = f" and {len(self.failures) - 5} more" if len(self.failures) > 5 else ""
            raise BatchError(f"{len(self.failures)} of {len(self.keys)} tasks failed: "
                             f"{lines}{more}")
        return list(self.results)  # type: ignore[arg-type]  # no failure: no None left


def batch_options(command: Callable[..., Any]) -> Callable[..., Any]:
    """``--workers N`` and ``--cluster ADDRESS`` of a batch command (keyword arguments
    ``workers`` and ``cluster``)."""
    command = click.option(
        "--cluster", default=None, metavar="ADDRESS",
        help="Run on Ray (pip install \"msrr-platform[cluster]\"): auto, ray://HOST:PORT, "
             "or local (a cluster of --workers CPUs here).")(command)
    return click.option(
        "--workers", type=click.IntRange(min=0), default=0, show_default=True,
        help="Worker processes: 1 runs in this process, 0 one per core.")(command)


@contextlib.contextmanager
def exit_on_interrupt() -> Iterator[None]:
    """A command's batch: an interruption (already reported by :func:`run_batch` in one
    line) exits 130 (SIGINT) or 143 (SIGTERM) without a second line."""
    try:
        yield
    except Interrupted as exc:
        raise SystemExit(exc.exit_code) from None
    except KeyboardInterrupt:
        raise SystemExit(130) from None


# --- the worker side -------------------------------------------------------------------

_one_thread = False


def _call(fn: Callable[[Any], Any], item: Any) -> tuple[bool, Any, float]:
    """Run one task; ``(True, result, seconds)`` or ``(False, (error, traceback), seconds)``.
    Exceptions are caught here so a failure carries the worker's traceback.

    Every worker runs BLAS and OpenMP on one thread (set on its first task): the workers
    are the parallelism, and a task's arithmetic is then the same as in the serial
    backend (which runs its tasks under the same limit)."""
    global _one_thread
    if not _one_thread:
        threadpool_limits(limits=1)
        _one_thread = True
    start = time.perf_counter()
    try:
        value = fn(item)
    except Exception as exc:  # any task's bug is reported, never lost
        return False, (f"{type(exc).__name__}: {exc}", traceback.format_exc()), \
            time.perf_counter() - start
    return True, value, time.perf_counter() - start


def _pool_worker_init() -> None:
    """Pool workers ignore SIGINT: Ctrl-C reaches the whole process group, and the parent
    cancels the batch and stops the workers itself."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


# --- backends: each yields (index, outcome) as tasks finish -------------------------------

_Outcome = tuple[bool, Any, float]


def _serial(fn: Callable[[Any], Any], items: Sequence[Any]) -> Iterator[tuple[int, _Outcome]]:
    """The tasks in this process, BLAS on one thread as in a worker (restored after)."""
    global _one_thread
    for index, item in enumerate(items):
        with threadpool_limits(limits=1):
            was, _one_thread = _one_thread, True
            try:
                outcome = _call(fn, item)
            finally:
                _one_thread = was
        yield index, outcome


def _pool_context() -> multiprocessing.context.BaseContext:
    methods = multiprocessing.get_all_start_methods()
    return multiprocessing.get_context("forkserver" if "forkserver" in methods else "spawn")


class _Pool:
    """A process pool whose workers are stopped (not awaited) when the batch is cancelled."""

    def __init__(self, workers: int):
        self.workers = workers
        self.executor = ProcessPoolExecutor(max_workers=workers, mp_context=_pool_context(),
                                            initializer=_pool_worker_init)

    def run(self, fn: Callable[[Any], Any], items: Sequence[Any], order: Sequence[int]
            ) -> Iterator[tuple[int, _Outcome]]:
        futures: dict[Future[_Outcome], int] = {
            self.executor.submit(_call, fn, items[i]): i for i in order}
        pending = set(futures)
        finished = False
        try:
            while pending:
                done, pending = wait(pending, return_when=FIRST_COMPLETED)
                for future in sorted(done, key=futures.__getitem__):
                    try:
                        outcome = future.result()
                    except Exception as exc:  # the worker died or the item did not pickle
                        outcome = (False, (f"{type(exc).__name__}: {exc}",
                                           traceback.format_exc()), float("nan"))
                    yield futures[future], outcome
            finished = True
        finally:
            if not finished:
                self.cancel(pending)

    def cancel(self, pending: set[Future[_Outcome]]) -> None:
        """Cancel the tasks not started and stop the workers running the others."""
        for future in pending:
            future.cancel()
        # the running tasks would go on to their end; their workers are stopped instead
        processes = list(getattr(self.executor, "_processes", {}).values())
        self.executor.shutdown(wait=False, cancel_futures=True)
        for process in processes:
            with contextlib.suppress(Exception):
                process.terminate()
        for process in processes:
            with contextlib.suppress(Exception):
                process.join(timeout=5.0)

    def close(self) -> None:
        self.executor.shutdown(wait=True, cancel_futures=True)


class _Ray:
    """Tasks as Ray remote calls of one CPU each; a cluster started here is shut down."""

    def __init__(self, cluster: str, workers: int):
        try:
            import ray
        except ImportError:
            raise BatchError(f"--cluster {cluster} needs Ray: {RAY_HINT}") from None
        self.ray = ray
        self.owned = not ray.is_initialized()
        if self.owned:
            settings: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False,
                                        "logging_level": "WARNING", "configure_logging": True}
            try:
                if cluster == "local":
                    # a cluster of this machine alone: loopback only
                    ray.init(address="local", num_cpus=workers or available_cores(),
                             _node_ip_address="127.0.0.1", **settings)
                else:
                    ray.init(address=cluster, **settings)
            except Exception as exc:  # Ray's own errors: no cluster there, bad address
                raise BatchError(f"--cluster {cluster}: cannot connect to Ray: "
                                 f"{type(exc).__name__}: {exc}") from None
        self.workers = max(1, int(ray.cluster_resources().get("CPU", 1)))
        self.remote = ray.remote(num_cpus=1, max_retries=0)(_call)

    def run(self, fn: Callable[[Any], Any], items: Sequence[Any], order: Sequence[int]
            ) -> Iterator[tuple[int, _Outcome]]:
        ray = self.ray
        fn_ref = ray.put(fn)
        refs = {self.remote.remote(fn_ref, items[i]): i for i in order}
        pending = list(refs)
        finished = False
        try:
            while pending:
                done, pending = ray.wait(pending, num_returns=1)
                for ref in done:
                    try:
                        outcome = ray.get(ref)
                    except Exception as exc:  # the worker died
                        outcome = (False, (f"{type(exc).__name__}: {exc}", ""), float("nan"))
                    yield refs[ref], outcome
            finished = True
        finally:
            if not finished:
                for ref in pending:
                    with contextlib.suppress(Exception):
                        ray.cancel(ref, force=True)

    def close(self) -> None:
        if self.owned:
            self.ray.shutdown()


# --- the one entry point ---------------------------------------------------------------

def run_batch(fn: Callable[[T], R], items: Sequence[T], *, keys: Sequence[str] | None = None,
              workers: int = 0, cluster: str | None = None, backend: str | None = None,
              label: str = "tasks", progress: bool = True,
              describe: Callable[[T], str] | None = None,
              cost: Sequence[float] | None = None) -> BatchResult[R]:
    """Apply ``fn`` to every item, on the backend ``workers``/``cluster`` select.

    Args:
        fn: a pure function of one item, importable by name (module level, or a
            ``functools.partial`` of one) so worker processes can receive it.
        items: the tasks' inputs (picklable).
        keys: one name per task (for progress, failures and seeds); default ``"0"``, ``"1"``, ...
        workers: ``1`` serial, ``N > 1`` a pool of ``N``, ``0`` one per core; with
            ``cluster``: the CPUs of a ``local`` Ray cluster.
        cluster: Ray address (``auto``, ``ray://host:port``, ``local``), or ``None``.
        backend: force ``serial``, ``pool`` or ``ray`` (tests, benchmarks); default
            :func:`backend_for`.
        label: what the tasks are, for the progress bar (``"edges"``, ``"runs"``).
        progress: show a progress bar.
        describe: text of a task for its failure report (default ``repr``).
        cost: an estimate of each task's duration (any unit, e.g. an earlier run's time);
            the pool and Ray start the longest first, so a long task does not start last
            and leave the other workers idle. It changes when tasks run, never what they
            return nor the order of the results.

    Returns:
        the results in item order, and the failures.

    Raises:
        BatchError: bad options, or Ray asked for and not installed or not reachable.
        Interrupted, KeyboardInterrupt: after cancelling the rest and one line.
    """
    keys = [str(i) for i in range(len(items))] if keys is None else [str(k) for k in keys]
    if len(keys) != len(items):
        raise BatchError(f"{len(keys)} keys for {len(items)} tasks")
    if cost is not None and len(cost) != len(items):
        raise BatchError(f"{len(cost)} costs for {len(items)} tasks")
    order = list(range(len(items))) if cost is None else \
        sorted(range(len(items)), key=lambda i: (-cost[i], i))
    name = backend or backend_for(workers, cluster)
    if name not in BACKENDS:
        raise BatchError(f"unknown backend {name!r}; expected one of {', '.join(BACKENDS)}")
    if name != "ray" and isinstance(workers, int) and workers < 0:
        backend_for(workers)  # raises
    count = workers or available_cores()
    start = time.perf_counter()
    results: list[Any] = [None] * len(items)
    times = [float("nan")] * len(items)
    failures: list[TaskFailure] = []
    runner: _Pool | _Ray | None = None
    if name == "pool" and min(count, len(items)) > 1:
        runner = _Pool(min(count, len(items)))
        stream = runner.run(fn, items, order)
    elif name == "ray":
        runner = _Ray(cluster or "local", workers)
        count = runner.workers
        stream = runner.run(fn, items, order)
    else:  # serial, or a pool that would have one worker: this process does the work
        name, count = "serial", 1
        stream = _serial(fn, items)
    columns = (TextColumn("{task.description}", markup=False), BarColumn(), MofNCompleteColumn(),
               TextColumn("{task.fields[failed]}"), TimeElapsedColumn())
    done = 0
    try:
        with Progress(*columns, console=console, transient=True,
                      disable=not progress or not console.is_terminal) as bar:
            task = bar.add_task(f"{label} ({name}, {count} worker{'s' * (count > 1)})",
                                total=len(items), failed="")
            for index, (ok, value, seconds) in stream:
                done += 1
                times[index] = seconds
                if ok:
                    results[index] = value
                else:
                    error, trace = value
                    text = (describe or repr)(items[index])
                    failures.append(TaskFailure(index, keys[index], text[:_INPUT_CHARS], error,
                                                trace))
                bar.update(task, advance=1,
                           failed=f"{len(failures)} failed" if failures else "")
    except (Interrupted, KeyboardInterrupt) as exc:
        signame = exc.name if isinstance(exc, Interrupted) else "SIGINT"
        with contextlib.suppress(Exception):
            stream.close()  # cancels what is pending and stops the workers
        if runner is not None:
            with contextlib.suppress(Exception):
                runner.close()
            runner = None
        err_console.print(f"Error: interrupted ({signame}): {done}/{len(items)} {label} done, "
                          "the rest cancelled", markup=False)
        raise
    finally:
        if runner is not None:
            runner.close()
    failures.sort(key=lambda f: f.index)
    return BatchResult(keys, results, failures, name, count, time.perf_counter() - start, times)
