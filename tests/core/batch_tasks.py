"""Task functions for the batch tests, importable by worker processes. Not a test module."""

from __future__ import annotations

import os
import time
from pathlib import Path


def mark_and_sleep(marker: str) -> int:
    """Write this worker's pid into ``marker``, then sleep a minute (to be cancelled)."""
    Path(marker).write_text(str(os.getpid()))
    time.sleep(60.0)
    return os.getpid()
