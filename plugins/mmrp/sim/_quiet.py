"""Silence what C extensions print straight to the process's output streams."""

from __future__ import annotations

import ctypes
import os
import sys
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager, suppress

__all__ = ["quiet_output"]


@contextmanager
def _redirected(fd: int, target: int) -> Iterator[None]:
    try:
        saved = os.dup(fd)
    except OSError:  # no such descriptor (embedded interpreters): nothing to silence
        yield
        return
    os.dup2(target, fd)
    try:
        yield
    finally:
        with suppress(OSError, AttributeError):  # C stdio may buffer: flush while redirected
            ctypes.CDLL(None).fflush(None)
        os.dup2(saved, fd)
        os.close(saved)


@contextmanager
def quiet_output() -> Iterator[None]:
    """Send file descriptors 1 and 2 to /dev/null for the duration of the block."""
    sys.stdout.flush()
    sys.stderr.flush()
    with open(os.devnull, "wb") as null, ExitStack() as stack:
        for fd in (1, 2):
            stack.enter_context(_redirected(fd, null.fileno()))
        yield
