"""The console script handles SIGINT and SIGTERM from its first line: a signal while
the command line is still importing ends in one line and exit 130 / 143."""

from __future__ import annotations

import subprocess
import sys

import pytest

CHILD = """
import os, signal, sys, time
from msrr.core.app import launch

def load_slowly():  # a signal lands while the heavy imports run
    os.kill(os.getpid(), signal.{name})
    time.sleep(5)
    raise AssertionError("the signal was not handled")

launch._load_cli = load_slowly
launch.main()
"""


@pytest.mark.parametrize(("name", "code"), [("SIGINT", 130), ("SIGTERM", 143)])
def test_a_signal_during_start_up_is_one_line(name: str, code: int) -> None:
    done = subprocess.run([sys.executable, "-c", CHILD.format(name=name)],
                          capture_output=True, text=True, timeout=30)
    assert done.returncode == code, done.stderr
    assert done.stderr == f"Error: interrupted during start-up ({name})\n"


def test_the_entry_point_imports_only_the_standard_library_before_its_handlers() -> None:
    done = subprocess.run(
        [sys.executable, "-c", "import sys, msrr.core.app.launch; "
         "print(sorted(m for m in ('numpy', 'click', 'rich', 'pluggy', 'pydantic') "
         "if m in sys.modules))"], capture_output=True, text=True, timeout=30)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"
