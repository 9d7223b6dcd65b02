"""The link protocol's pieces: the CBOR subset against RFC 8949's examples, frames and
their checks (tag, replay, age, foreign system), the systems file and its key, a
module's handshake and watchdog. No socket is opened here."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from msrr.core.driver import ModuleCommand
from msrr.core.errors import ConfigurationError
from msrr.core.link import (
    Endpoint,
    FrameType,
    KeyRef,
    LinkDriver,
    ModuleEntry,
    ModuleLink,
    Refused,
    SystemFile,
    load_key,
    load_system,
    parse_link_faults,
    write_key,
    write_system,
)
from msrr.core.link.cbor import CborError, Decoder, dumps, loads
from msrr.core.link.protocol import HEADER, TAG_SIZE, command_from_payload, command_payload

KEY = bytes(range(32))


@dataclass(frozen=True)
class Reading:
    """A record a report may carry (this test module is allow-listed as a package)."""

    kind: str
    tilt: np.ndarray
    events: tuple[str, ...] = ()


@pytest.mark.parametrize(("value", "hex_"), [
    (0, "00"), (23, "17"), (24, "1818"), (100, "1864"), (1000, "1903e8"),
    (1000000, "1a000f4240"), (1000000000000, "1b000000e8d4a51000"), (-1, "20"),
    (-1000, "3903e7"), (100000.0, "fa47c35000"), (1.1, "fb3ff199999999999a"),
    (-4.1, "fbc010666666666666"), (False, "f4"), (True, "f5"), (None, "f6"), ("", "60"),
    ("a", "6161"), ("\u00fc", "62c3bc"), (b"\x01\x02\x03\x04", "4401020304"),
    ((1, 2, 3), "83010203"), ({"a": 1, "b": (2, 3)}, "a26161016162820203"),
])
def test_cbor_matches_the_examples_of_rfc_8949_appendix_a(value: object, hex_: str) -> None:
    assert dumps(value).hex() == hex_
    assert loads(bytes.fromhex(hex_)) == value


def test_cbor_round_trips_arrays_and_allow_listed_records_only() -> None:
    rotation = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]) * 0.3
    value = {"1": {"T": ("2", "B"), "L": None}, "r": Reading("strut", rotation, ("dock",)),
             "v": np.array([1.0, 2.5, -3.25]), "n": -7}
    back = Decoder((__name__.split(".")[0],)).loads(dumps(value))
    assert back["1"] == {"T": ("2", "B"), "L": None} and back["n"] == -7
    assert isinstance(back["r"], Reading) and back["r"].events == ("dock",)
    np.testing.assert_allclose(back["r"].tilt, rotation, atol=1e-7)  # float32 on the wire
    np.testing.assert_array_equal(back["v"], [1.0, 2.5, -3.25])
    with pytest.raises(CborError, match="not allowed"):
        Decoder(("msrr",)).loads(dumps(value))  # this test's package is not the robot's
    forged = dumps({"x": 1}).replace(b"\xa1", b"\xd8\x1b\x82\x6eos.path:join\xa0", 1)[:-3]
    with pytest.raises(CborError):
        Decoder(("msrr",)).loads(forged)
    for bad in (b"\x18", b"\x62a", b"\x9f", b"\x01\x02", b"\xff"):
        with pytest.raises(CborError):
            loads(bad)


def _host(window: float = 1.0, key: bytes = KEY) -> Endpoint:
    return Endpoint(key, 7, 0, window=window)


def _module(window: float = 1.0, key: bytes = KEY) -> Endpoint:
    return Endpoint(key, 7, 3, window=window)


def test_frames_are_authenticated_and_replays_stale_and_foreign_frames_counted() -> None:
    host, module = _host(), _module()
    frame = host.encode(FrameType.COMMAND, 3, session=11, link=22, clock=1.0,
                        payload=command_payload(ModuleCommand(wheels={"left": 0.1})))
    assert len(frame) == HEADER.size + len(dumps({"w": {"left": 0.1}})) + TAG_SIZE
    got = module.accept(frame, 1.05, session=11, link=22)
    assert (got.seq, got.clock, got.sender) == (1, 1000, 0)
    assert command_from_payload(got.payload) == ModuleCommand(wheels={"left": 0.1})
    with pytest.raises(Refused, match="replayed"):
        module.accept(frame, 1.1, session=11, link=22)  # the same datagram again
    tampered = bytearray(host.encode(FrameType.COMMAND, 3, session=11, link=22, clock=1.1,
                                     payload={}))
    tampered[HEADER.size - 1] ^= 1
    with pytest.raises(Refused, match="bad_tag"):
        module.accept(bytes(tampered), 1.15, session=11, link=22)
    intruder = _host(key=bytes(32)).encode(FrameType.COMMAND, 3, session=11, link=22,
                                           clock=1.2, payload={})
    with pytest.raises(Refused, match="bad_tag"):
        module.accept(intruder, 1.25, session=11, link=22)
    late = host.encode(FrameType.COMMAND, 3, session=11, link=22, clock=1.3, payload={})
    with pytest.raises(Refused, match="stale"):
        module.accept(late, 1.3 + 0.05 + 1.5, session=11, link=22)  # 1.5 s beyond the delay
    other = host.encode(FrameType.COMMAND, 4, session=11, link=22, clock=1.4, payload={})
    with pytest.raises(Refused, match="foreign"):
        module.accept(other, 1.45, session=11, link=22)
    old = host.encode(FrameType.COMMAND, 3, session=10, link=22, clock=1.5, payload={})
    with pytest.raises(Refused, match="stale_session"):
        module.accept(old, 1.55, session=11, link=22)
    assert module.stats.refused == {"replayed": 1, "bad_tag": 2, "stale": 1, "foreign": 1,
                                    "stale_session": 1}
    assert module.stats.received == 1
    assert "key" not in repr(module) and KEY.hex() not in repr(module)


class _Socket:
    """Stands in for a module's socket (``ModuleLink`` leaves sending to its owner)."""


def test_a_module_obeys_its_host_only_and_stops_at_the_first_check_after_its_watchdog() -> None:
    host = _host()
    link = ModuleLink("3", 3, _Socket(), _module(), watchdog=0.3)  # type: ignore[arg-type]
    hello = host.encode(FrameType.HELLO, 3, session=11, link=0, clock=0.0, payload={})
    assert link.handle(hello, ("127.0.0.1", 9), 0.0) is None
    (welcome, _), = link.outbox
    nonce = link.link
    assert _host().accept(welcome, 0.0, session=11, link=None).link == nonce
    go = host.encode(FrameType.COMMAND, 3, session=11, link=nonce, clock=0.1,
                     payload={"w": {"v": 0.5}, "wd": 0.3})
    assert link.handle(go, ("127.0.0.1", 9), 0.1) is None
    assert link.current(0.1) == ModuleCommand(wheels={"v": 0.5}) and link.applied == 2
    stranger = Endpoint(bytes(32), 7, 0, window=1.0).encode(
        FrameType.COMMAND, 3, session=11, link=nonce, clock=0.15, payload={"w": {"v": -1.0}})
    assert link.handle(stranger, ("127.0.0.1", 666), 0.15) == "bad_tag"
    assert link.handle(go, ("127.0.0.1", 9), 0.2) == "replayed"
    assert link.handle(hello, ("127.0.0.1", 9), 0.2) is None  # our host missed the WELCOME
    assert link.link == nonce
    second = host.encode(FrameType.HELLO, 3, session=12, link=0, clock=0.2, payload={})
    assert link.handle(second, ("127.0.0.1", 9), 0.2) is None and link.link != nonce
    assert link.handle(hello, ("127.0.0.1", 9), 0.25) == "replayed"  # an earlier session
    assert link.current(0.3) is None  # a new session starts stopped
    fresh = host.encode(FrameType.COMMAND, 3, session=12, link=link.link, clock=0.3,
                        payload={"w": {"v": 0.5}})
    assert link.handle(fresh, ("127.0.0.1", 9), 0.3) is None
    clocks = np.arange(0.3, 1.0, 0.07)
    moving = [link.current(float(c)) is not None for c in clocks]
    trip, = link.trips
    assert trip.previous - trip.last <= 0.3 + 1e-9 < trip.at - trip.last
    assert moving == [float(c) - 0.3 <= 0.3 + 1e-9 for c in clocks]
    assert link.endpoint.stats.refused == {"bad_tag": 1, "replayed": 2}


def test_systems_file_refers_to_the_key_and_never_holds_it(tmp_path, monkeypatch) -> None:
    entries = [ModuleEntry(id=m, number=i + 1, address="127.0.0.1", port=47000 + i)
               for i, m in enumerate("abc")]
    system = SystemFile(system=9, robot="tiny", key=KeyRef(file="lab.key"), modules=entries)
    path = write_system(tmp_path / "system.json", system)
    write_key(tmp_path / "lab.key", KEY)
    assert KEY.hex() not in path.read_text()
    assert (tmp_path / "lab.key").stat().st_mode & 0o077 == 0
    loaded = load_system(path)
    assert loaded == system and load_key(loaded, path) == KEY
    assert loaded.timeout(entries[0]) == 1.0
    monkeypatch.setenv("LAB_KEY", KEY.hex())
    assert load_key(system.model_copy(update={"key": KeyRef(env="LAB_KEY")}), path) == KEY
    (tmp_path / "lab.key").write_text("abcd\n")
    with pytest.raises(ConfigurationError, match="2 bytes, at least 16"):
        load_key(loaded, path)
    (tmp_path / "lab.key").unlink()
    with pytest.raises(ConfigurationError, match="key.file"):
        load_key(loaded, path)
    data = path.read_text()
    for text, words in [(data.replace('"port": 47001', '"port": 47000'), "two modules"),
                        (data.replace('"number": 2', '"number": 1'), "two modules"),
                        (data.replace('"127.0.0.1"', '"::1"', 1), r"modules\[0\].*IPv4"),
                        (data.replace('"file": "lab.key"', '"file": "k", "env": "E"'), "key")]:
        bad = tmp_path / "bad.json"
        bad.write_text(text)
        with pytest.raises(ConfigurationError, match=words):
            load_system(bad)


def test_link_faults_parse_in_the_fault_syntax() -> None:
    faults = parse_link_faults("loss:p=0.05;latency:ms=20,jitter=5;dropout:module=3,at=2;"
                               "reboot:module=4,at=3;wrong-key:module=5")
    assert [f.kind for f in faults] == ["loss", "latency", "dropout", "reboot", "wrong-key"]
    assert faults[2].params == {"module": "3", "at": 2.0, "for": math.inf}
    assert faults[3].params["for"] == 0.5 and parse_link_faults(" ") == ()
    with pytest.raises(ConfigurationError, match="unknown kind 'dock-fail'"):
        parse_link_faults("dock-fail")


def test_the_host_holds_the_last_observation_while_two_reports_disagree_on_a_latch(
        tmp_path) -> None:
    entries = [ModuleEntry(id=m, number=i + 1, address="127.0.0.1", port=47000 + i)
               for i, m in enumerate("ab")]
    path = write_system(tmp_path / "system.json", SystemFile(
        system=9, robot="tiny", key=KeyRef(file="k.key"), timeout_s=0.5, modules=entries))
    driver = LinkDriver(system=path)
    driver._sock = _Socket()  # type: ignore[assignment]  # no traffic: reports set below
    a, b = driver.modules["a"], driver.modules["b"]

    def reports(time: float, a_links: tuple, b_links: tuple) -> None:
        driver._time = time
        a.report, a.links = {"sensors": {"T": a_links[0][1:] if a_links else None}}, a_links
        b.report, b.links = {"sensors": {"B": b_links[0][1:] if b_links else None}}, b_links

    reports(0.0, (), ())
    apart = driver.get_observation()
    assert apart.groups == (frozenset("a"), frozenset("b")) and driver.held == 0
    reports(0.1, (("T", "b", "B"),), ())  # a reports the dock, b's report is a tick old
    held = driver.get_observation()
    assert held.time == 0.1 and held.sensors == apart.sensors and driver.held == 1
    reports(0.2, (("T", "b", "B"),), (("B", "a", "T"),))  # now both
    docked = driver.get_observation()
    assert docked.groups == () and docked.sensors == {"a": {"T": ("b", "B")},
                                                      "b": {"B": ("a", "T")}}
    reports(0.3, (), (("B", "a", "T"),))
    assert driver.get_observation().sensors == docked.sensors  # held again
    reports(0.8, (), (("B", "a", "T"),))  # disagreeing longer than the timeout: shown
    assert driver.get_observation().sensors == {"a": {"T": None}, "b": {"B": ("a", "T")}}
