"""Datagrams timed on arrival: the kernel's receive timestamp, not the time they are read.

On a loaded machine a process may read a datagram tens of milliseconds after it
arrived; the link's age check (:class:`~.protocol.Freshness`) must not count that as
network delay. Sockets opened here ask the kernel to stamp each datagram
(``SO_TIMESTAMPNS``, Linux); :func:`drain` turns the stamp into this process's monotonic
clock. Where the kernel cannot stamp, the time of reading stands in.
"""

from __future__ import annotations

import contextlib
import platform
import socket
import struct
import sys
import time
from typing import Any

__all__ = ["drain", "udp_socket"]

_GENERIC = {"x86_64", "aarch64", "arm64", "armv7l", "armv6l", "i686", "riscv64", "ppc64le"}
_TIMESTAMPNS = getattr(socket, "SO_TIMESTAMPNS",
                       35 if sys.platform == "linux" and platform.machine() in _GENERIC else None)
"""``SO_TIMESTAMPNS``: Python does not name it; 35 on the Linux architectures whose socket
options are the generic ones (elsewhere the time of reading stands in)."""
_SCM_TIMESTAMPNS = getattr(socket, "SCM_TIMESTAMPNS", _TIMESTAMPNS)
_TIMESPEC = struct.Struct("@qq")
_ANCILLARY = socket.CMSG_SPACE(_TIMESPEC.size)


def udp_socket(address: str, port: int = 0) -> socket.socket:
    """A non-blocking UDP socket bound to ``(address, port)`` that stamps arrivals."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        if _TIMESTAMPNS is not None:
            with contextlib.suppress(OSError):
                sock.setsockopt(socket.SOL_SOCKET, _TIMESTAMPNS, 1)
        sock.bind((address, port))
        sock.setblocking(False)
    except BaseException:
        sock.close()
        raise
    return sock


def drain(sock: socket.socket) -> list[tuple[bytes, Any, float]]:
    """Every datagram waiting on ``sock``: ``(data, sender address, arrival)``, arrival
    on :func:`time.monotonic`'s clock."""
    out = []
    while True:
        try:
            data, ancillary, _flags, address = sock.recvmsg(65536, _ANCILLARY)
        except (BlockingIOError, InterruptedError):
            break
        except OSError:
            break  # ICMP port unreachable of a peer that is gone
        now, real = time.monotonic(), time.time()
        arrival = now
        for level, kind, value in ancillary:
            if level == socket.SOL_SOCKET and kind == _SCM_TIMESTAMPNS and \
                    len(value) >= _TIMESPEC.size:
                seconds, nanoseconds = _TIMESPEC.unpack_from(value)
                arrival = now - max(0.0, real - (seconds + nanoseconds * 1e-9))
        out.append((data, address, arrival))
    return out
