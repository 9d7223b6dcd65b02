"""The signal handlers: one Interrupted per installation, deferred inside a shield,
previous handlers restored."""

from __future__ import annotations

import os
import signal

import pytest

from msrr.core import interrupts
from msrr.core.interrupts import SIGNALS, Interrupted, handled, shielded


def _send(signum: int) -> None:
    """Signal this process; Python runs the handler before the next bytecode."""
    os.kill(os.getpid(), signum)


def test_first_signal_raises_a_second_stops_at_once_and_handlers_come_back(
        monkeypatch: pytest.MonkeyPatch) -> None:
    stopped: list[int] = []
    monkeypatch.setattr(interrupts, "stop_now", stopped.append)  # not this test process
    before = {s: signal.getsignal(s) for s in SIGNALS}
    with handled():
        with pytest.raises(Interrupted) as caught:
            _send(signal.SIGTERM)
        assert (caught.value.name, caught.value.exit_code) == ("SIGTERM", 143)
        _send(signal.SIGINT)  # the run is already stopping: now
    assert stopped == [signal.SIGINT]
    assert {s: signal.getsignal(s) for s in SIGNALS} == before


def test_a_second_signal_inside_a_shield_stops_at_once(monkeypatch: pytest.MonkeyPatch) -> None:
    stopped: list[int] = []
    monkeypatch.setattr(interrupts, "stop_now", stopped.append)
    with handled():
        with pytest.raises(Interrupted), shielded():
            _send(signal.SIGINT)
            assert stopped == []
            _send(signal.SIGTERM)
        assert stopped == [signal.SIGTERM]
    with handled():
        with shielded(raise_deferred=False):  # dropped: the run is already stopping
            _send(signal.SIGINT)
        _send(signal.SIGINT)  # still the second one
    assert stopped == [signal.SIGTERM, signal.SIGINT]


def test_a_shield_defers_the_signal_to_its_end() -> None:
    done = []
    with handled():
        with pytest.raises(Interrupted) as caught, shielded():
            _send(signal.SIGINT)
            done.append("finished")
        assert caught.value.exit_code == 130 and done == ["finished"]
    with handled(), shielded(raise_deferred=False):
        _send(signal.SIGINT)


def test_a_signal_inherited_as_ignored_stays_ignored() -> None:
    saved = signal.signal(signal.SIGINT, signal.SIG_IGN)  # as in a shell's background job
    try:
        with handled():
            assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
            assert signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL
    finally:
        signal.signal(signal.SIGINT, saved)
