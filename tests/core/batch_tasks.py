"""Task functions for the batch tests, importable by worker processes. Not a test module."""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path


def mark_and_sleep(marker: str) -> int:
    """Write this worker's pid into ``marker``, then sleep a minute (to be cancelled)."""
    Path(marker).write_text(str(os.getpid()))
    time.sleep(60.0)
    return os.getpid()


def lose_worker_once(item: tuple[str, int, int]) -> int:
    """``(marker, value, parent)``: in a worker (not ``parent``), SIGKILL this worker the
    first time (the marker remembers), then return ``value``."""
    marker, value, parent = item
    if os.getpid() != parent and not Path(marker).exists():
        Path(marker).write_text(str(os.getpid()))
        os.kill(os.getpid(), signal.SIGKILL)
    return value


def lose_worker_always(item: tuple[int, int | None, float]) -> int:
    """``(value, parent, delay)``: in a worker (not ``parent``), SIGKILL this worker every
    time, ``delay`` seconds in; never with ``parent`` ``None``."""
    value, parent, delay = item
    time.sleep(delay)
    if parent is not None and os.getpid() != parent:
        os.kill(os.getpid(), signal.SIGKILL)
    return value


def pid_of(_: object) -> int:
    """The process a task ran in."""
    return os.getpid()


# --- process helpers of the tests (Linux /proc) -------------------------------------------

def _stat(pid: int) -> list[str]:
    """The fields of ``/proc/PID/stat`` after the command name (state, ppid, ...)."""
    return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()


def descendants(pid: int) -> list[int]:
    """Every living descendant of ``pid`` (children, their children, ...)."""
    children: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                children.setdefault(int(_stat(int(entry.name))[1]), []).append(int(entry.name))
            except (OSError, IndexError):
                continue
    found, todo = [], [pid]
    while todo:
        for child in children.get(todo.pop(), []):
            found.append(child)
            todo.append(child)
    return found


def alive(pid: int) -> bool:
    """``pid`` exists and is not a zombie."""
    try:
        return _stat(pid)[0] != "Z"
    except (OSError, IndexError):
        return False


def command_line(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()
    except OSError:
        return ""


def cpu_seconds(pid: int) -> float:
    """CPU time ``pid`` used (user + system) [s]."""
    try:
        fields = _stat(pid)
    except (OSError, IndexError):
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def pool_workers(pid: int) -> list[int]:
    """The batch-pool workers of the process ``pid`` (the children of its forkserver)."""
    servers = []
    for child in descendants(pid):
        try:
            parent = int(_stat(child)[1])
        except (OSError, IndexError):
            continue
        if "multiprocessing.forkserver" in command_line(child) \
                and "multiprocessing.forkserver" not in command_line(parent):
            servers.append(child)
    return [w for s in servers for w in descendants(s)]
