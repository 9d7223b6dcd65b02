"""The watchdog of a run's driver: a driver call that does not return ends the run.

The run's deadlines are checked by :class:`~msrr.core.faults.GuardedDriver` between
driver calls (driver time, and wall time with ``wall_deadline``); a call that blocks
(a ``step`` waiting on a module that never answers) would never get back to them. The
:class:`Watchdog` thread watches the guard's :attr:`~msrr.core.faults.GuardedDriver.busy`
call and, when it has run longer than ``stall`` seconds of wall time (a call that ends
past the wall deadline is stopped at the next step, by the guard), interrupts the main
thread with ``SIGALRM``; the handler raises
:class:`DriverStalled` inside the driver call (a blocking wait returns at a signal), so
the run stops as for any driver error: modules told to stop, one line, the three files.
Should the main thread still be inside the driver ``grace`` seconds later (the driver
swallowed the error, or spins in native code), the watchdog calls ``last_resort`` with
the reason: ``platform run`` writes the files from there and ends the process.

Signals reach the main thread only: elsewhere (a run in a worker thread) the watchdog
does not interrupt, and only ``last_resort`` (if given) acts.
"""

from __future__ import annotations

import signal
import threading
import time
from collections.abc import Callable
from types import FrameType, TracebackType
from typing import Protocol

from .errors import ExecutionError

__all__ = ["DRIVER_STALL", "GRACE", "DriverStalled", "Watchdog"]

DRIVER_STALL = 30.0
"""Wall time one driver call may take by default [s] (``--stall``)."""

GRACE = 5.0
"""Wall time the main thread has to leave a stalled driver once told to [s]."""


class DriverStalled(ExecutionError):
    """A driver call did not return within its wall time."""


class _Busy(Protocol):
    name: str
    stopped: str

    @property
    def busy(self) -> tuple[str, float] | None: ...


class Watchdog:
    """Watches ``guard.busy`` while the ``with`` block runs (see the module doc).

    Args:
        guard: the run's guard (its ``busy``: the call in progress and since when, on
            :func:`time.monotonic`; its ``stopped`` is set to the reason when the watchdog
            fires).
        stall: wall time one call may take [s].
        last_resort: called in the watchdog's thread with the reason when the main thread
            did not leave the driver ``grace`` seconds after it was told to; ``None``: wait.
        grace: see :data:`GRACE`.
        poll: how often the thread looks [s].

    Attributes:
        reason: why the watchdog fired (``""``: it did not).
    """

    def __init__(self, guard: _Busy, *, stall: float = DRIVER_STALL,
                 last_resort: Callable[[str], None] | None = None, grace: float = GRACE,
                 poll: float = 0.05):
        self.guard = guard
        self.stall = stall
        self.last_resort = last_resort
        self.grace = grace
        self.poll = poll
        self.reason = ""
        self._done = threading.Event()
        self._thread = threading.Thread(target=self._watch, name="msrr-watchdog", daemon=True)
        self._main = threading.main_thread().ident
        self._signals = threading.current_thread() is threading.main_thread()
        self._saved: object = None

    def __enter__(self) -> Watchdog:
        if self._signals:
            self._saved = signal.signal(signal.SIGALRM, self._handler)
        self._thread.start()
        return self

    def __exit__(self, kind: type[BaseException] | None, value: BaseException | None,
                 traceback: TracebackType | None) -> None:
        self._done.set()
        self._thread.join(timeout=1.0)
        if self._signals:
            signal.signal(signal.SIGALRM, self._saved or signal.SIG_DFL)  # type: ignore[arg-type]

    def _handler(self, signum: int, frame: FrameType | None) -> None:
        if self.reason and self.guard.busy is not None:  # only inside the driver's call
            raise DriverStalled(self.reason)

    def _expired(self, now: float) -> str:
        busy = self.guard.busy
        if busy is None:
            return ""
        call, since = busy
        if now - since > self.stall:
            return (f"driver {self.guard.name!r} did not return from {call} within "
                    f"{self.stall:g} s of wall time (--stall)")
        return ""

    def _watch(self) -> None:
        fired = alarmed = 0.0
        while not self._done.wait(self.poll):
            now = time.monotonic()
            if not self.reason:
                self.reason = self._expired(now)
                if not self.reason:
                    continue
                self.guard.stopped = self.reason  # no further call but the clean-up's
                fired = now
            if self.guard.busy is not None and now - alarmed >= 1.0 and self._signals:
                alarmed = now
                signal.pthread_kill(self._main, signal.SIGALRM)  # type: ignore[arg-type]
            if now - fired > self.grace and self.last_resort is not None:
                self.last_resort(self.reason)
                return
