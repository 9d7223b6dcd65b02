"""SIGINT and SIGTERM as one exception, and a shield for clean-up that must finish.

:func:`install` makes both signals raise :class:`Interrupted` in the main thread (the
``platform`` entry point installs it first thing). :class:`Interrupted` is not a
:class:`KeyboardInterrupt`, so click does not turn it into a bare ``Aborted!``; the
code that catches it says what was interrupted and exits with :attr:`exit_code`
(130 for SIGINT, 143 for SIGTERM, the shell's ``128 + signal``). Only the first
signal raises; a second one (Ctrl-C again during the clean-up, or SIGTERM after it)
ends the process at once (:func:`stop_now`) with one line and ``128 + signal``: what
was written stays, a file half-written is still named ``*.part`` or ``.*.tmp``.

``with shielded():`` defers the first signal while a block runs (stopping the modules,
writing the run's files), then raises it.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType

__all__ = ["SIGNALS", "Interrupted", "handled", "install", "shielded", "stop_now"]

SIGNALS = (signal.SIGINT, signal.SIGTERM)


class Interrupted(BaseException):  # noqa: N818 -- it is an interruption, not an error
    """A signal asked the process to stop.

    Attributes:
        signum: the signal's number.
    """

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum

    @property
    def name(self) -> str:
        """``"SIGINT"`` or ``"SIGTERM"``."""
        return signal.Signals(self.signum).name

    @property
    def exit_code(self) -> int:
        """``128 + signum``: 130 for SIGINT, 143 for SIGTERM."""
        return 128 + self.signum


_pending: list[int] = []
_depth = 0
_fired = False  # one Interrupted per installation: the process is stopping after it


def stop_now(signum: int) -> None:
    """End the process at once on a second signal: one line, exit ``128 + signum``; no
    clean-up runs (the first signal's is what was too slow)."""
    name = signal.Signals(signum).name
    try:
        sys.stdout.flush()
        sys.stderr.write(f"Error: a second signal ({name}): stopped at once; what was "
                         "written is kept (a half-written file is named *.part or .*.tmp)\n")
        sys.stderr.flush()
    finally:
        os._exit(128 + signum)


def _handler(signum: int, frame: FrameType | None) -> None:
    global _fired
    if _fired or _pending:  # the process is already stopping: now, not later
        stop_now(signum)
        return
    if _depth:
        _pending.append(signum)
        return
    _fired = True
    raise Interrupted(signum)


def install() -> bool:
    """Make SIGINT and SIGTERM raise :class:`Interrupted`; ``False`` outside the main
    thread (where Python cannot install signal handlers), with nothing changed. A signal
    the process inherited as ignored (SIGINT of a shell's background job) stays ignored."""
    global _fired
    if threading.current_thread() is not threading.main_thread():
        return False
    _fired = False
    _pending.clear()
    for signum in SIGNALS:
        if signal.getsignal(signum) is not signal.SIG_IGN:  # a background job keeps ignoring
            signal.signal(signum, _handler)
    return True


@contextmanager
def handled() -> Iterator[None]:
    """:func:`install` for the block, the previous handlers restored after it (so a
    command run in-process, as tests do, leaves the caller's Ctrl-C alone)."""
    saved = {signum: signal.getsignal(signum) for signum in SIGNALS}
    installed = install()
    try:
        yield
    finally:
        if installed:
            for signum, handler in saved.items():
                signal.signal(signum, handler)


@contextmanager
def shielded(*, raise_deferred: bool = True) -> Iterator[None]:
    """Defer SIGINT and SIGTERM during the block; after it raise the first deferred one
    (or, with ``raise_deferred=False``, drop them: the run is already stopping)."""
    global _depth, _fired
    _depth += 1
    try:
        yield
    finally:
        _depth -= 1
    if not _depth and _pending:
        signum = _pending[0]
        _pending.clear()
        _fired = True  # a later signal is a second one, raised or not
        if raise_deferred:
            raise Interrupted(signum)
