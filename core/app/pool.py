"""The local process pool of batch work: a lost worker costs only its own task, and no
worker outlives the process that started it.

:class:`Pool` runs ``fn(item)`` for a batch's items on ``N`` worker processes of its own
(not :class:`concurrent.futures.ProcessPoolExecutor`, whose every pending task fails with
``BrokenProcessPool`` when one worker dies):

* **One task per worker at a time**, handed out by a dispatcher thread in the order given
  (longest first when the caller knows the costs), so the pool always knows which task a
  worker was running.
* **A lost worker** (killed, out of memory, a crash in a C extension) costs only the task
  it was running: a fresh worker replaces it and the task is queued again, first in line,
  up to ``retries`` times; after that it is reported as failed with the reason
  (``WorkerLost: the worker was killed by SIGKILL (3 attempts)``). A task that *raises*
  is not retried: a task is a pure function of its input, it would raise again.
* **Workers die with their parent.** They fork from ``multiprocessing``'s forkserver
  (never from this process: MuJoCo and PyBullet must not be forked once initialised),
  which imports the task function's modules once, so a worker is ready in milliseconds
  after the first second. On Linux the forkserver and every worker ask the kernel for
  SIGKILL when their parent ends (``PR_SET_PDEATHSIG``); everywhere, a thread in each
  worker exits once this process's end of a *lifeline* pipe closes. Killing this process
  with any signal, SIGKILL included, ends the workers and the forkserver at once, and
  with them the ``multiprocessing`` resource tracker (it exits when the last process
  holding its pipe is gone). Workers ignore SIGINT: Ctrl-C reaches the whole process
  group and the parent decides.
* **Start-up is not wasted.** Until the first worker is ready (about a second: a fresh
  interpreter imports the platform), this process runs the shortest tasks itself (the
  end of the order). A batch that is done before then never used a worker at all.
"""

from __future__ import annotations

import contextlib
import ctypes
import io
import multiprocessing
import multiprocessing.context
import os
import pickle
import queue
import signal
import sys
import threading
import time
import traceback
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from multiprocessing import forkserver
from multiprocessing.connection import Connection, wait
from multiprocessing.process import BaseProcess
from typing import Any

from threadpoolctl import threadpool_limits

from ..errors import MsrrError

__all__ = ["GUARD_VARIABLE", "RETRIES", "Outcome", "Pool", "PoolError", "call_task",
           "die_with_parent", "run_here"]

GUARD_VARIABLE = "MSRR_POOL_PARENT"
"""Environment variable: the pid of the process whose forkserver must end with it."""

RETRIES = 2
"""How many times a task whose worker was lost is run again (on another worker)."""

Outcome = tuple[bool, Any, float]
"""``(True, result, seconds)`` or ``(False, (error, traceback), seconds)``."""

_START_FAILURES = 3
"""Workers that may die before they are ready (an import that crashes) before the batch
gives up."""

_PR_SET_PDEATHSIG = 1


# --- a task, wherever it runs ----------------------------------------------------------

_one_thread = False


def call_task(fn: Callable[[Any], Any], item: Any) -> Outcome:
    """Run one task: ``(True, result, seconds)`` or ``(False, (error, traceback), seconds)``.
    Exceptions are caught here so a failure carries the traceback of where it ran.

    Every worker runs BLAS and OpenMP on one thread (set on its first task): the workers
    are the parallelism, and a task's arithmetic is then the same as in this process
    (:func:`run_here` runs under the same limit)."""
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


def run_here(fn: Callable[[Any], Any], item: Any) -> Outcome:
    """:func:`call_task` in this process, BLAS on one thread as in a worker (restored
    after)."""
    global _one_thread
    with threadpool_limits(limits=1):
        was, _one_thread = _one_thread, True
        try:
            return call_task(fn, item)
        finally:
            _one_thread = was


# --- the worker side -------------------------------------------------------------------

def die_with_parent() -> None:
    """Ask the kernel to SIGKILL this process when its parent ends (Linux; elsewhere
    nothing), and end it now if the parent already ended before that."""
    if not sys.platform.startswith("linux"):
        return
    before = os.getppid()
    with contextlib.suppress(Exception):  # no libc or no prctl: the lifeline remains
        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
    if os.getppid() != before:  # the parent ended while the signal was armed
        os._exit(1)


def _die_with(lifeline: Connection) -> None:
    """End this worker when its parent (the forkserver) or the process that asked for it
    ends: :func:`die_with_parent`, and a thread that exits once that process's end of
    ``lifeline`` is closed (everywhere)."""
    die_with_parent()

    def watch() -> None:
        with contextlib.suppress(EOFError, OSError):
            lifeline.recv_bytes()  # the parent never writes: this returns at its end
        os._exit(1)

    threading.Thread(target=watch, name="msrr-lifeline", daemon=True).start()


def _worker(conn: Connection, lifeline: Connection, fn_bytes: bytes) -> None:
    """A pool worker: unpickle the task function, say ready, then run one task per
    message (8 bytes of index, then the pickled item) until an empty message or the end
    of the pipe."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _die_with(lifeline)
    broken: tuple[str, str] | None = None
    try:
        fn = pickle.loads(fn_bytes)
    except Exception as exc:  # the function does not load here: every task says so
        fn, broken = None, (f"{type(exc).__name__}: {exc}", traceback.format_exc())
    conn.send(("ready", os.getpid()))
    while True:
        try:
            data = conn.recv_bytes()
        except (EOFError, OSError):
            return
        if not data:
            return
        index = int.from_bytes(data[:8], "big")
        try:
            item = pickle.loads(data[8:])
        except Exception as exc:
            outcome: Outcome = (False, (f"{type(exc).__name__}: {exc}",
                                        traceback.format_exc()), 0.0)
        else:
            outcome = call_task(fn, item) if broken is None else (False, broken, 0.0)
        try:
            conn.send((index, outcome))
        except (EOFError, OSError):
            return
        except Exception as exc:  # the result does not pickle
            conn.send((index, (False, (f"the result could not be sent back: "
                                       f"{type(exc).__name__}: {exc}",
                                       traceback.format_exc()), outcome[2])))


# --- the parent side -------------------------------------------------------------------

class _Modules(pickle.Unpickler):
    """Reads a pickle back, noting the modules of its classes and functions."""

    def __init__(self, data: bytes):
        super().__init__(io.BytesIO(data))
        self.modules: set[str] = set()

    def find_class(self, module: str, name: str) -> Any:
        self.modules.add(module)
        return super().find_class(module, name)


def _context(fn_bytes: bytes) -> multiprocessing.context.BaseContext:
    """The forkserver (``spawn`` where there is none), started here if it is not running,
    told to import the task function's modules once for every worker and to end with
    this process (:mod:`msrr.core.app.forkserver_guard`)."""
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    reader = _Modules(fn_bytes)
    with contextlib.suppress(Exception):  # a module that does not load is the worker's to say
        reader.load()
    modules = sorted(m for m in reader.modules if m != "__main__" and m in sys.modules)
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(["__main__", "msrr.core.app.forkserver_guard",
                                    "msrr.core.app.pool", *modules])
    os.environ[GUARD_VARIABLE] = str(os.getpid())
    forkserver.ensure_running()  # from this thread: the forkserver's parent-death is its end
    return context


def _lost_reason(exitcode: int | None) -> str:
    if exitcode is not None and exitcode < 0:
        with contextlib.suppress(ValueError):
            return f"the worker was killed by {signal.Signals(-exitcode).name}"
    return f"the worker exited with status {exitcode}"


@dataclass(eq=False)
class _Worker:
    process: BaseProcess
    conn: Connection
    ready: bool = False
    task: int | None = None


class PoolError(MsrrError):
    """The pool itself failed (workers that cannot start): the batch cannot go on."""


class _Run:
    """One batch on the pool: the dispatcher thread and the queue of tasks."""

    def __init__(self, pool: Pool, fn: Callable[[Any], Any], items: Sequence[Any],
                 order: Sequence[int]):
        self.pool, self.fn, self.items = pool, fn, items
        try:
            self.fn_bytes = pickle.dumps(fn)
            self.broken: tuple[str, str] | None = None
        except Exception as exc:  # not importable by name (a lambda): every task says so
            self.fn_bytes = b""
            self.broken = (f"{type(exc).__name__}: {exc}", traceback.format_exc())
        self.queue: deque[int] = deque(order)
        self.lock = threading.Lock()
        self.out: queue.Queue[tuple[int, Outcome] | PoolError] = queue.Queue()
        self.stop = threading.Event()
        self.any_ready = threading.Event()
        self.attempts: dict[int, int] = {}
        self.workers: list[_Worker] = []
        self.start_failures = 0
        self.lifeline_r, self.lifeline_w = multiprocessing.Pipe(duplex=False)
        self.context: multiprocessing.context.BaseContext | None = None
        self.thread = threading.Thread(target=self._dispatch, name="msrr-pool", daemon=True)

    # the main thread -----------------------------------------------------------------

    def results(self) -> Iterator[tuple[int, Outcome]]:
        """``(index, outcome)`` as tasks finish; this thread runs the shortest tasks while
        no worker is ready yet."""
        remaining = len(self.items)
        finished = False
        try:
            if self.broken is not None:
                for index in range(remaining):
                    yield index, (False, self.broken, 0.0)
                finished = True
                return
            self.context = _context(self.fn_bytes)
            self.thread.start()
            while remaining:
                index_outcome = self._next()
                remaining -= 1
                yield index_outcome
            finished = True
        finally:
            self.close(cancel=not finished)

    def _next(self) -> tuple[int, Outcome]:
        while True:
            with contextlib.suppress(queue.Empty):
                return self._unpack(self.out.get_nowait())
            if self.pool.warm_up and not self.any_ready.is_set():
                with self.lock:
                    index = self.queue.pop() if self.queue else None
                if index is not None:
                    return index, run_here(self.fn, self.items[index])
            with contextlib.suppress(queue.Empty):
                return self._unpack(self.out.get(timeout=0.1))

    @staticmethod
    def _unpack(message: tuple[int, Outcome] | PoolError) -> tuple[int, Outcome]:
        if isinstance(message, PoolError):
            raise message
        return message

    def close(self, *, cancel: bool) -> None:
        """Stop the dispatcher and every worker (at once when ``cancel``)."""
        self.stop.set()
        for worker in list(self.workers):
            with contextlib.suppress(Exception):
                if cancel or worker.task is not None:
                    worker.process.kill()
                else:
                    worker.conn.send_bytes(b"")
        if self.thread.ident is not None:
            self.thread.join(timeout=10.0)
        for worker in list(self.workers):
            worker.process.join(timeout=2.0)
            if worker.process.is_alive():
                worker.process.kill()
                worker.process.join(timeout=2.0)
            with contextlib.suppress(Exception):
                worker.conn.close()
        self.lifeline_w.close()
        self.lifeline_r.close()

    # the dispatcher thread -----------------------------------------------------------

    def _dispatch(self) -> None:
        try:
            while not self.stop.is_set():
                self._top_up()
                busy = [w for w in self.workers if w.task is not None]
                with self.lock:
                    left = len(self.queue)
                if not left and not busy:
                    return  # every task handed out and answered (this thread may run the last)
                handles: list[Any] = [w.conn for w in self.workers]
                handles += [w.process.sentinel for w in self.workers]
                for handle in wait(handles, timeout=0.2):
                    self._handle(handle)
                for worker in [w for w in self.workers if w.ready and w.task is None]:
                    self._assign(worker)  # a task queued again while this one was idle
        except BaseException as exc:  # the pool itself failed: the batch stops, loudly
            self.out.put(PoolError(f"the process pool failed: {type(exc).__name__}: {exc}"))

    def _top_up(self) -> None:
        """Start workers until there are as many as tasks to run (at most the pool's)."""
        with self.lock:
            left = len(self.queue)
        busy = sum(w.task is not None for w in self.workers)
        context = self.context
        assert context is not None
        while len(self.workers) < min(self.pool.workers, left + busy) and not self.stop.is_set():
            here, there = context.Pipe()
            process = context.Process(target=_worker, args=(there, self.lifeline_r, self.fn_bytes),
                                      name="msrr-batch-worker", daemon=True)
            process.start()
            there.close()
            self.workers.append(_Worker(process, here))

    def _handle(self, handle: Any) -> None:
        worker = next((w for w in self.workers if handle in (w.conn, w.process.sentinel)), None)
        if worker is None:
            return
        try:
            if not worker.conn.poll():
                raise EOFError  # the sentinel: the process ended
            message = worker.conn.recv()
        except (EOFError, OSError):
            self._lost(worker)
            return
        if message[0] == "ready":
            worker.ready = True
            self.any_ready.set()
        else:
            index, outcome = message
            worker.task = None
            self.out.put((index, outcome))
        self._assign(worker)

    def _assign(self, worker: _Worker) -> None:
        """Hand ``worker`` the next task (the longest left), if any."""
        if not worker.process.is_alive():
            return  # its sentinel is next: :meth:`_lost`
        with self.lock:
            index = self.queue.popleft() if self.queue else None
        if index is None:
            return
        try:
            data = pickle.dumps(self.items[index])
        except Exception as exc:  # the item does not pickle: its task fails, here
            self.out.put((index, (False, (f"{type(exc).__name__}: {exc}",
                                          traceback.format_exc()), 0.0)))
            self._assign(worker)
            return
        worker.task = index
        try:
            worker.conn.send_bytes(index.to_bytes(8, "big") + data)
        except OSError:
            self._lost(worker)

    def _lost(self, worker: _Worker) -> None:
        """``worker`` ended: its task is queued again first in line, or fails after
        ``retries`` retries; a fresh worker replaces it (:meth:`_top_up`)."""
        self.workers.remove(worker)
        worker.process.join(timeout=5.0)
        with contextlib.suppress(Exception):
            worker.conn.close()
        why = _lost_reason(worker.process.exitcode)
        if not worker.ready:
            self.start_failures += 1
            if self.start_failures >= _START_FAILURES:
                raise RuntimeError(f"{self.start_failures} workers ended before they were "
                                   f"ready, the last one: {why}")
        index = worker.task
        if index is None:
            return
        self.attempts[index] = attempts = self.attempts.get(index, 0) + 1
        if attempts <= self.pool.retries:
            self.pool.retried.append((index, why))
            with self.lock:
                self.queue.appendleft(index)
            return
        tries = f"{attempts} attempt{'s' * (attempts > 1)}"
        self.out.put((index, (False, (f"WorkerLost: {why} ({tries})", ""), float("nan"))))


class Pool:
    """A pool of ``workers`` worker processes (see the module's description).

    Attributes:
        workers: the most worker processes running at once.
        retries: how many times a task whose worker was lost runs again.
        warm_up: run the shortest tasks in this process until a worker is ready.
        retried: ``(index, reason)`` of every task that was queued again.
    """

    def __init__(self, workers: int, *, retries: int = RETRIES, warm_up: bool = True):
        self.workers = max(1, workers)
        self.retries = max(0, retries)
        self.warm_up = warm_up
        self.retried: list[tuple[int, str]] = []

    def run(self, fn: Callable[[Any], Any], items: Sequence[Any], order: Sequence[int]
            ) -> Iterator[tuple[int, Outcome]]:
        """``(index, outcome)`` of every task as it finishes; ``order`` is the order tasks
        are handed out in. Closing the iterator early (an interruption) kills the workers.

        Raises:
            PoolError: the pool itself failed (workers that cannot start).
        """
        return _Run(self, fn, items, order).results()

    def close(self) -> None:
        """Nothing to release between batches: each :meth:`run` stops its workers."""
