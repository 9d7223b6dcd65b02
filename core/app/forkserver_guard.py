"""Imported by the forkserver of a batch pool (:mod:`msrr.core.app.pool`), first in its
list of modules to preload: the forkserver then ends with the process that started it.

The forkserver is the parent of every pool worker; :func:`msrr.core.app.pool.die_with_parent`
makes the kernel kill it when its own parent -- the process named by
:data:`msrr.core.app.pool.GUARD_VARIABLE` -- ends (Linux), so a SIGKILL of that process
takes the forkserver and, through theirs, the workers with it. Imported anywhere else
(the variable names another parent), it does nothing.
"""

from __future__ import annotations

import os

from .pool import GUARD_VARIABLE, die_with_parent

if os.environ.get(GUARD_VARIABLE) == str(os.getppid()):
    die_with_parent()
