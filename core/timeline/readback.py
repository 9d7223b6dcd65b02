"""Read a recording back with rerun's own tooling (``rerun rrd print``).

Used by tests and docs to check what a run wrote: which entity paths exist, how
many rows each has, and which timelines index them.
"""

from __future__ import annotations

import re
import subprocess
import sys
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

from ..errors import MsrrError

__all__ = ["RecordingSummary", "summarize_recording"]

_CHUNK = re.compile(r"^Chunk\(\S+\) with (\d+) rows \([^)]*\) - (\S+)")
_INDEX = re.compile(r"index_name: (\w+)")


@dataclass(frozen=True)
class RecordingSummary:
    """Entity paths with their row counts, and timeline names, of one ``.rrd`` file."""

    rows: dict[str, int]
    timelines: frozenset[str]

    def entities(self, prefix: str = "/") -> list[str]:
        """Entity paths starting with ``prefix``, sorted."""
        return sorted(p for p in self.rows if p.startswith(prefix))


def summarize_recording(path: str | Path) -> RecordingSummary:
    """Summarize ``path`` by parsing ``rerun rrd print -vv``.

    Raises:
        MsrrError: the file is missing or rerun cannot read it.
    """
    if not Path(path).is_file():
        raise MsrrError(f"{path}: no such recording")
    proc = subprocess.run([sys.executable, "-m", "rerun", "rrd", "print", "-vv", str(path)],
                          capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise MsrrError(f"{path}: rerun cannot read it: {proc.stderr.strip().splitlines()[-1:]}")
    rows: Counter[str] = Counter()
    timelines: set[str] = set()
    for line in proc.stdout.splitlines():
        match = _CHUNK.match(line)
        if match:
            rows[match.group(2)] += int(match.group(1))
        timelines.update(_INDEX.findall(line))
    return RecordingSummary(dict(rows), frozenset(timelines))
