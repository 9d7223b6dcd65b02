"""Batch work: one interface, run serially, on a local process pool or on a Ray cluster.

A batch is a pure function ``fn(item) -> result`` applied to a list of serialisable
items (a library's edges, a sweep's runs, a benchmark's instances). :func:`run_batch`
picks the backend from two options every batch command takes:

==================  =====================================================================
``--workers N``     ``1``: in this process (``serial``); ``N > 1``: a local process pool
                    of ``N`` workers (``pool``, :mod:`msrr.core.app.pool`); ``0``
                    (default): one worker per core
``--cluster ADDR``  Ray (``pip install "msrr-platform[cluster]"``): ``auto`` (the cluster
                    this machine belongs to), ``HOST:PORT`` (a head started with ``ray
                    start --head``), ``ray://host:10001`` (a remote cluster's client
                    port), or ``local`` (start a cluster of ``N`` CPUs here)
==================  =====================================================================

Guarantees, whichever backend runs the batch:

* results are returned in item order (index ``i`` holds ``fn(items[i])``), never in the
  order workers finished; a task that needs randomness takes its seed from its item
  (:func:`task_seed` derives one from a base seed and the task's key), never from the
  worker, so serial, pool and Ray give the same results;
* a task that raises is reported as a :class:`TaskFailure` with its key, its input and
  the traceback, and the other tasks' results are kept; a task whose worker was lost
  (killed, crashed) runs again on another worker, at most ``retries`` times, then is a
  :class:`TaskFailure` (``WorkerLost: ...``); the caller sees each result or failure as it
  arrives (``record``), to journal it (:mod:`msrr.core.app.journal`);
* the longest tasks (by the caller's ``cost``) start first; the pool's start-up is spent
  running the shortest tasks in this process, so a batch too small to pay for a pool
  runs here;
* progress is shown on the console (rich), one bar per batch;
* Ctrl-C, SIGTERM or SIGHUP cancels the tasks not yet started, stops the workers, prints
  one line and re-raises the interruption (``platform`` exits 130, 143 or 129); a pool's
  workers end with this process whatever kills it (SIGKILL included).
"""

from __future__ import annotations

import contextlib
import hashlib
import logging
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any, Generic, TypeVar

import click
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

from .. import interrupts
from ..console import console, err_console
from ..errors import ConfigurationError, MsrrError
from ..interrupts import Interrupted, shielded
from .pool import RETRIES, Outcome, Pool, PoolError, call_task, run_here

__all__ = ["BACKENDS", "RETRIES", "BatchError", "BatchResult", "TaskFailure", "available_cores",
           "backend_for", "batch_options", "exit_on_interrupt", "finishing", "ray_available",
           "retries_option", "run_batch", "task_seed"]

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
    """A task that raised, or whose worker was lost on every attempt.

    Attributes:
        index: the task's position in the batch.
        key: the task's key.
        input: ``repr`` of its input (cut to 300 characters).
        error: ``"<ExceptionType>: <message>"`` (``"WorkerLost: the worker was killed by
            SIGKILL (3 attempts)"`` for a lost worker).
        traceback: the worker's formatted traceback (empty for a lost worker).
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
        failures: the tasks that failed, by index.
        backend: ``serial``, ``pool`` or ``ray``.
        workers: worker processes (Ray: the cluster's CPUs).
        wall_time: wall-clock time of the whole batch [s], start-up included.
        task_times: wall-clock time of each task where it ran [s] (``nan`` if failed).
        retried: ``(key, reason)`` of every task run again because its worker was lost.
    """

    keys: list[str]
    results: list[R | None]
    failures: list[TaskFailure] = field(default_factory=list)
    backend: str = "serial"
    workers: int = 1
    wall_time: float = 0.0
    task_times: list[float] = field(default_factory=list)
    retried: list[tuple[str, str]] = field(default_factory=list)

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
        help="Run on Ray (pip install \"msrr-platform[cluster]\"): auto, HOST:PORT of a "
             "head started with `ray start --head`, ray://HOST:PORT, or local (a cluster "
             "of --workers CPUs here).")(command)
    return click.option(
        "--workers", type=click.IntRange(min=0), default=0, show_default=True,
        help="Worker processes: 1 runs in this process, 0 one per core.")(command)


def retries_option(command: Callable[..., Any]) -> Callable[..., Any]:
    """``--retries N`` of a batch command (keyword argument ``retries``)."""
    return click.option(
        "--retries", type=click.IntRange(0, 10), default=RETRIES, show_default=True,
        help="Times a task whose worker was lost (killed, crashed) runs again on another "
             "worker before it counts as failed.")(command)


@contextlib.contextmanager
def exit_on_interrupt() -> Iterator[None]:
    """A command's batch: an interruption (already reported by :func:`run_batch` in one
    line) exits 130 (SIGINT), 143 (SIGTERM) or 129 (SIGHUP) without a second line."""
    try:
        yield
    except Interrupted as exc:
        raise SystemExit(exc.exit_code) from None
    except KeyboardInterrupt:
        raise SystemExit(130) from None


@contextlib.contextmanager
def finishing(what: str) -> Iterator[None]:
    """A command writes its outputs and last lines in the block.

    SIGINT and SIGTERM wait for the end of the block (no output is left half-written),
    then end the command with one line, ``Error: interrupted (SIGINT) after <what>``, and
    130 (143). After the block the command is done: when the platform's handlers are
    installed (``platform``, not a test's in-process call) both signals are ignored from
    then on, so one that lands while the interpreter exits does not kill it without a
    word (status -2): the command exits 0, its outputs complete.

    Args:
        what: what is done if a signal ends the block (``"sweep.csv was written"``).
    """
    try:
        with shielded():
            yield
    except Interrupted as exc:
        err_console.print(f"Error: interrupted ({exc.name}) after {what}", markup=False)
        raise SystemExit(exc.exit_code) from None
    if threading.current_thread() is threading.main_thread():
        for signum in interrupts.SIGNALS:
            if signal.getsignal(signum) is getattr(interrupts, "_handler", None):
                signal.signal(signum, signal.SIG_IGN)


# --- backends: each yields (index, outcome) as tasks finish -------------------------------

def _serial(fn: Callable[[Any], Any], items: Sequence[Any], order: Sequence[int]
            ) -> Iterator[tuple[int, Outcome]]:
    """The tasks in this process, in ``order``."""
    for index in order:
        yield index, run_here(fn, items[index])


_RAY_AUTH_LOGGER = "ray._private.authentication.authentication_token_setup"


def _ray_token_auth() -> None:
    """Connecting to a running cluster: use the token this machine has (``RAY_AUTH_TOKEN``,
    ``RAY_AUTH_TOKEN_PATH`` or ``~/.ray/auth_token``) unless ``RAY_AUTH_MODE`` says
    otherwise -- what the installed Ray does itself for ``auto`` but not for an explicit
    address, where a head started with ``ray start --head`` (token auth on once a token
    exists) would refuse this process with ``InvalidAuthToken``."""
    if os.environ.get("RAY_AUTH_MODE") is not None:
        return
    try:
        from ray._private.authentication.authentication_token_setup import (
            maybe_enable_token_auth_if_token_available,
        )
    except ImportError:  # a Ray without token authentication
        return
    log = logging.getLogger(_RAY_AUTH_LOGGER)
    level = log.level
    log.setLevel(logging.ERROR)  # not Ray's "enabled for this cluster": this is a client
    try:
        maybe_enable_token_auth_if_token_available(warn_if_disabled=False)
    finally:
        log.setLevel(level)


_REAPER = r"""
import os, select, signal, sys
parent = int(sys.argv[1])
def stat(pid):
    return open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
def descendants():
    children = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                fields = stat(entry)
            except OSError:
                continue
            children.setdefault(int(fields[1]), []).append((int(entry), fields[19]))
    found, todo = {}, [parent]
    while todo:
        for pid, started in children.get(todo.pop(), []):
            if pid != os.getpid():
                found[pid] = started
                todo.append(pid)
    return found
seen = {}
while True:
    seen.update(descendants())
    if select.select([sys.stdin], [], [], 0.5)[0]:
        if sys.stdin.readline():
            sys.exit(0)
        break
for pid, started in seen.items():
    try:
        if stat(pid)[19] == started:
            os.kill(pid, signal.SIGKILL)
    except OSError:
        pass
"""
"""The reaper of a ``local`` Ray cluster (Linux): it notes every descendant of the process
that started it, twice a second, and SIGKILLs those still alive when that process ends
without saying ``done`` (a SIGKILL): Ray's own fate-sharing stops its GCS, raylet and
workers, but leaves its dashboard and runtime-env agents running for a minute or more."""


def _start_reaper() -> subprocess.Popen[bytes] | None:
    if not os.path.isdir("/proc"):
        return None
    return subprocess.Popen([sys.executable, "-c", _REAPER, str(os.getpid())],
                            stdin=subprocess.PIPE, start_new_session=True)


def _stop_reaper(reaper: subprocess.Popen[bytes] | None) -> None:
    if reaper is None or reaper.stdin is None:
        return
    with contextlib.suppress(OSError):
        reaper.stdin.write(b"done\n")
        reaper.stdin.close()
    with contextlib.suppress(subprocess.TimeoutExpired):
        reaper.wait(timeout=5.0)


class _Ray:
    """Tasks as Ray remote calls of one CPU each; a cluster started here is shut down.

    A task's function and input travel by value with it (nothing is read from this
    machine's disk on the workers); a task whose worker dies is retried by Ray up to
    ``retries`` times. Ray's services listen on every interface of the machines they run
    on (Ray has no setting to keep them on loopback); token authentication, on by
    default for a ``local`` cluster, is what keeps others out."""

    def __init__(self, cluster: str, workers: int, retries: int):
        try:
            import ray
        except ImportError:
            raise BatchError(f"--cluster {cluster} needs Ray: {RAY_HINT}") from None
        self.ray = ray
        self.owned = not ray.is_initialized()
        self.reaper: subprocess.Popen[bytes] | None = None
        if self.owned:
            settings: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False,
                                        "logging_level": "WARNING", "configure_logging": True}
            try:
                if cluster == "local":
                    ray.init(address="local", num_cpus=workers or available_cores(), **settings)
                    self.reaper = _start_reaper()
                else:
                    _ray_token_auth()
                    ray.init(address=cluster, **settings)
            except Exception as exc:  # Ray's own errors: no cluster there, bad address
                raise BatchError(f"--cluster {cluster}: cannot connect to Ray: "
                                 f"{type(exc).__name__}: {exc}") from None
        self.workers = max(1, int(ray.cluster_resources().get("CPU", 1)))
        self.remote = ray.remote(num_cpus=1, max_retries=retries, retry_exceptions=False)(
            call_task)

    def run(self, fn: Callable[[Any], Any], items: Sequence[Any], order: Sequence[int]
            ) -> Iterator[tuple[int, Outcome]]:
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
                    except Exception as exc:  # the worker died on every attempt
                        first = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
                        outcome = (False, (f"WorkerLost: {type(exc).__name__}: {first}", ""),
                                   float("nan"))
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
            _stop_reaper(self.reaper)


# --- the one entry point ---------------------------------------------------------------

@dataclass
class _Plan:
    """What :func:`run_batch` runs: the keys, the order, the backend and its size."""

    keys: list[str]
    order: list[int]
    backend: str
    workers: int


def _plan(count: int, keys: Sequence[str] | None, cost: Sequence[float] | None,
          workers: int, cluster: str | None, backend: str | None) -> _Plan:
    """Check the options; the tasks' order (longest first by ``cost``) and the backend."""
    names = [str(i) for i in range(count)] if keys is None else [str(k) for k in keys]
    if len(names) != count:
        raise BatchError(f"{len(names)} keys for {count} tasks")
    if cost is not None and len(cost) != count:
        raise BatchError(f"{len(cost)} costs for {count} tasks")
    order = list(range(count)) if cost is None else \
        sorted(range(count), key=lambda i: (-cost[i], i))
    name = backend or backend_for(workers, cluster)
    if name not in BACKENDS:
        raise BatchError(f"unknown backend {name!r}; expected one of {', '.join(BACKENDS)}")
    if name != "ray" and isinstance(workers, int) and workers < 0:
        backend_for(workers)  # raises
    size = workers or available_cores()
    if name == "pool" and min(size, count) <= 1:
        name, size = "serial", 1  # a pool of one worker: this process does the work
    elif name == "serial":
        size = 1
    return _Plan(names, order, name, min(size, count) if name == "pool" else size)


@contextlib.contextmanager
def _hangup_interrupts() -> Iterator[None]:
    """During a batch, SIGHUP (the terminal closed) ends it like SIGTERM when the
    platform's handlers are installed: the workers stop, the journal is kept."""
    handler = getattr(interrupts, "_handler", None)
    hup = getattr(signal, "SIGHUP", None)
    if (hup is None or threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is not handler
            or signal.getsignal(hup) is not signal.SIG_DFL):
        yield
        return
    signal.signal(hup, handler)
    try:
        yield
    finally:
        signal.signal(hup, signal.SIG_DFL)


@dataclass
class _Tally:
    """Results and failures as they arrive."""

    results: list[Any]
    times: list[float]
    failures: list[TaskFailure] = field(default_factory=list)
    done: int = 0


def _collect(tally: _Tally, stream: Iterator[tuple[int, Outcome]], items: Sequence[Any],
             plan: _Plan, label: str, progress: bool, describe: Callable[[Any], str] | None,
             record: Callable[[int, Any], None] | None) -> None:
    """Take the outcomes into ``tally`` as they finish, with the progress bar and
    ``record``."""
    columns = (TextColumn("{task.description}", markup=False), BarColumn(),
               MofNCompleteColumn(), TextColumn("{task.fields[failed]}"), TimeElapsedColumn(),
               TextColumn("left"), TimeRemainingColumn())
    count = plan.workers
    description = f"{label} ({plan.backend}, {count} worker{'s' * (count > 1)})"
    lines = _Lines(description, len(items)) if progress and not console.is_terminal else None
    with Progress(*columns, console=console, transient=True,
                  disable=not progress or not console.is_terminal) as bar:
        task = bar.add_task(description, total=len(items), failed="")
        for index, (ok, value, seconds) in stream:
            tally.done += 1
            tally.times[index] = seconds
            if ok:
                tally.results[index] = value
                outcome: Any = value
            else:
                error, trace = value
                text = (describe or repr)(items[index])
                outcome = TaskFailure(index, plan.keys[index], text[:_INPUT_CHARS], error, trace)
                tally.failures.append(outcome)
            if record is not None:
                record(index, outcome)
            bar.update(task, advance=1,
                       failed=f"{len(tally.failures)} failed" if tally.failures else "")
            if lines is not None:
                lines.update(tally.done, len(tally.failures))


class _Lines:
    """Progress without a terminal (a pipe, a log): a line at least every
    :data:`PROGRESS_EVERY` seconds and at the end, with the count and an estimate."""

    def __init__(self, description: str, total: int):
        self.description, self.total = description, total
        self.started = self.said = time.monotonic()
        console.print(f"{description}: {total} to do", markup=False, soft_wrap=True)

    def update(self, done: int, failed: int) -> None:
        now = time.monotonic()
        if now - self.said < PROGRESS_EVERY and done < self.total:
            return
        self.said = now
        elapsed = now - self.started
        left = f", about {elapsed / done * (self.total - done):.0f} s left" \
            if done < self.total else ""
        console.print(f"{self.description}: {done}/{self.total} done"
                      + (f", {failed} failed" if failed else "")
                      + f", {elapsed:.0f} s{left}", markup=False, soft_wrap=True)


PROGRESS_EVERY = 10.0
"""Without a terminal, a progress line at least this often [s of wall time]."""


def _open(plan: _Plan, fn: Callable[[Any], Any], items: Sequence[Any], cluster: str | None,
          workers: int, retries: int) -> tuple[Iterator[tuple[int, Outcome]],
                                                 Pool | _Ray | None]:
    """The stream of outcomes of the plan's backend, and what runs it (to close)."""
    if plan.backend == "pool":
        pool = Pool(plan.workers, retries=retries)
        return pool.run(fn, items, plan.order), pool
    if plan.backend == "ray":
        ray = _Ray(cluster or "local", workers, retries)
        plan.workers = ray.workers
        return ray.run(fn, items, plan.order), ray
    return _serial(fn, items, plan.order), None


def run_batch(fn: Callable[[T], R], items: Sequence[T], *, keys: Sequence[str] | None = None,
              workers: int = 0, cluster: str | None = None, backend: str | None = None,
              label: str = "tasks", progress: bool = True,
              describe: Callable[[T], str] | None = None,
              cost: Sequence[float] | None = None, retries: int = RETRIES,
              record: Callable[[int, R | TaskFailure], None] | None = None,
              interrupt_note: Callable[[], str] | None = None) -> BatchResult[R]:
    """Apply ``fn`` to every item, on the backend ``workers``/``cluster`` select.

    Args:
        fn: a pure function of one item, importable by name (module level, or a
            ``functools.partial`` of one) so worker processes can receive it.
        items: the tasks' inputs (picklable).
        keys: one name per task (for progress, failures and seeds); default ``"0"``, ``"1"``, ...
        workers: ``1`` serial, ``N > 1`` a pool of ``N``, ``0`` one per core; with
            ``cluster``: the CPUs of a ``local`` Ray cluster.
        cluster: Ray address (``auto``, ``HOST:PORT``, ``ray://host:port``, ``local``), or ``None``.
        backend: force ``serial``, ``pool`` or ``ray`` (tests, benchmarks); default
            :func:`backend_for`.
        label: what the tasks are, for the progress bar (``"edges"``, ``"runs"``).
        progress: show a progress bar.
        describe: text of a task for its failure report (default ``repr``).
        cost: an estimate of each task's duration (any unit, e.g. an earlier run's time);
            the longest start first, so a long task does not start last and leave the
            other workers idle. It changes when tasks run, never what they return nor the
            order of the results.
        retries: how many times a task whose worker was lost runs again (pool and Ray).
        record: called in this process with ``(index, result or TaskFailure)`` as each
            task finishes (to journal it).
        interrupt_note: text added to the interruption's line (where the finished
            results are kept).

    Returns:
        the results in item order, and the failures.

    Raises:
        BatchError: bad options, Ray asked for and not installed or not reachable, or the
            pool failed (workers that die before they start).
        Interrupted, KeyboardInterrupt: after cancelling the rest and one line.
    """
    plan = _plan(len(items), keys, cost, workers, cluster, backend)
    start = time.perf_counter()
    stream, runner = _open(plan, fn, items, cluster, workers, retries)
    tally = _Tally([None] * len(items), [float("nan")] * len(items))
    try:
        with _hangup_interrupts():
            _collect(tally, stream, items, plan, label, progress, describe, record)
    except (Interrupted, KeyboardInterrupt) as exc:
        with contextlib.suppress(Exception):
            stream.close()  # type: ignore[attr-defined]  # cancels the rest, stops the workers
        signame = exc.name if isinstance(exc, Interrupted) else "SIGINT"
        note = interrupt_note() if interrupt_note is not None else ""
        err_console.print(f"Error: interrupted ({signame}): {tally.done}/{len(items)} {label} done, "
                          f"the rest cancelled{note}", markup=False)
        raise
    except PoolError as exc:
        raise BatchError(str(exc)) from None
    finally:
        with contextlib.suppress(Exception):
            stream.close()  # type: ignore[attr-defined]  # ended early (record raised): stop it
        if runner is not None:
            with contextlib.suppress(Exception):
                runner.close()
    tally.failures.sort(key=lambda f: f.index)
    retried = [(plan.keys[i], why) for i, why in getattr(runner, "retried", [])]
    return BatchResult(plan.keys, tally.results, tally.failures, plan.backend, plan.workers,
                       time.perf_counter() - start, tally.times, retried)
