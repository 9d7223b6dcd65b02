"""A seeded fuzzer of the link decoder (issue 30): frame headers and the payloads of
COMMAND and REPORT frames, as the module and the host read them once a frame's seal
has opened (a seal is only as good as its key: a compromised or buggy module sends
whatever it likes).

Valid payloads (commands of every kind of entry, with their name table; reports of
MMRP's plain sensor data and of FreeSN's records, full and field by field, with poses,
links, events, battery) are mutated as bytes (flipped bits, cut, grown, spliced) and as
CBOR trees (a value replaced by NaN, a huge or negative integer, bytes of another
length, an unknown tag or record id, ``undefined``, deep nesting), then decoded the way
the receivers do: :func:`decode_command` follows the module's COMMAND handling
(``msrr.core.link.module``), :func:`decode_report` the host's REPORT handling
(``msrr.core.link.driver``). Every case must end in acceptance or in
:class:`~msrr.core.link.protocol.Refused` / :class:`~msrr.core.link.codec.CodecError`,
never another exception, each within a second.

Run as a script for a longer campaign::

    python tests/fuzz/fuzz_link.py --cases 50000 --seed 7
"""

from __future__ import annotations

import argparse
import functools
import math
import random
import sys
import time
import traceback
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from functools import cache
from typing import Any

import cbor2
import numpy as np

from msrr.core.driver import ModuleCommand, Pose
from msrr.core.link.codec import INCOMPLETE, Codec, CodecError, RecordTable, infer_records
from msrr.core.link.protocol import (
    HEADER,
    VERSION,
    FrameType,
    NameTable,
    Refused,
    command_entry,
    decode_map,
    parse_entry,
    pose_from_wire,
    pose_wire,
    read_header,
    unsigned,
    want,
)

LIMIT = 1.0
"""Longest a decode may take [s]."""


# -- the receivers' payload handling -------------------------------------------------------


def decode_command(plain: bytes, names: list[str], number: int) -> Any:
    """A COMMAND payload as module ``number`` reads it (its name table ``names``)."""
    payload = decode_map(plain)
    watchdog = unsigned(payload, 0, "watchdog", limit=600_000) / 1000.0
    every = unsigned(payload, 1, "report period", 1, limit=100)
    entries = want(payload, 2, dict, "entries", {})
    asked = want(payload, 4, tuple, "asked", ())
    if not all(isinstance(n, int) and not isinstance(n, bool) for n in asked):
        raise Refused("malformed", "asked")
    if 3 in payload:
        defs = want(payload, 3, tuple, "names")
        if not (defs and isinstance(defs[0], int) and not isinstance(defs[0], bool)
                and all(isinstance(n, str) for n in defs[1:])):
            raise Refused("malformed", "names")
        if defs[0] <= len(names):
            names = names + list(defs[1 + len(names) - defs[0]:])
    if watchdog <= 0 or every < 1:
        raise Refused("malformed", "watchdog or report period")
    entry = entries.get(number)
    return parse_entry(entry, names) if entry is not None else None


def decode_report(codec: Codec, plain: bytes, previous: Any, names: int, known: int = 0
                  ) -> Any:
    """A REPORT payload as the host reads it (the module's last sensor data
    ``previous``; ``names`` entries in the host's name table, ``known`` of them known to
    the module as of its last report)."""
    try:
        raw = codec.loads(plain)
        if not isinstance(raw, dict) or not all(
                isinstance(k, int) and not isinstance(k, bool) and k >= 0 for k in raw):
            raise CodecError("a report is a map of unsigned integer keys")
        payload = {k: codec.from_wire(v, 1) for k, v in raw.items() if k != 3}
        sensors = codec.update(raw[3], previous) if 3 in raw else INCOMPLETE
    except CodecError as exc:
        raise Refused("malformed", str(exc)) from None
    unsigned(payload, 0, "ack")
    unsigned(payload, 1, "lag", 0)
    unsigned(payload, 2, "status", limit=255)
    unsigned(payload, 8, "names known", known, limit=names)
    links = want(payload, 4, tuple, "links", ())
    if not all(isinstance(link, tuple) and len(link) == 3
               and all(isinstance(x, str) for x in link) for link in links):
        raise Refused("malformed", "links")
    want(payload, 5, tuple, "events", ())
    want(payload, 6, (int, float), "battery", -1.0)
    pose = pose_from_wire(payload[7]) if 7 in payload else None
    return sensors, pose


# -- valid payloads ------------------------------------------------------------------------


@dataclass(frozen=True)
class Seed:
    """A valid payload: what it is and its bytes."""

    kind: str  # header, command, report
    name: str
    data: bytes
    records: bool = False  # decoded with FreeSN's record table


@cache
@functools.lru_cache(maxsize=1)
def _freesn_reports() -> tuple[RecordTable, dict[str, Any]]:
    """FreeSN's sensor data of a real start (node and strut reports) and its records (a
    simulated world built once: its cost is no decoder's)."""
    from msrr.core.io import load_configuration
    from msrr.plugins.freesn.sim.driver import FreeSNMujocoDriver

    config = load_configuration(next((_root() / "plugins/freesn/configs").rglob("S6N3-1.1.json")))
    with FreeSNMujocoDriver() as driver:
        driver.reset(config)
        sensors = dict(driver.get_observation().sensors)
    return RecordTable(infer_records(sensors.values())), sensors


def _root():  # type: ignore[no-untyped-def]
    from pathlib import Path

    return Path(__file__).resolve().parents[2]


NAMES = ["a.dir_x", "a.dir_y", "a.dir_z", "left", "right", "T", "B"]
VECTORS = ("a.dir", "b.dir")
"""FreeSN's unit-vector joints: entry 4 of the command seed carries one packed."""


@cache
def seeds() -> tuple[Seed, ...]:
    """Every valid payload the fuzzer mutates (built once per process)."""
    plain = Codec()
    out = [Seed("header", f"{t.name}", HEADER.pack(VERSION << 4 | t, 3, 77, 1234) + b"\0" * 40)
           for t in FrameType]
    names = NameTable()
    commands = [ModuleCommand(joints={"a.dir_x": 0.1, "a.dir_y": 0.0, "a.dir_z": 1.0}),
                ModuleCommand(wheels={"left": 0.2, "right": -0.2}, dock=("T",)),
                ModuleCommand(undock=("B",)),
                ModuleCommand(joints={"a.dir_x": 0.6, "a.dir_y": 0.0, "a.dir_z": -0.8,
                                      "b.effort": 1.0, "a.effort": 0.25})]
    entries = {n + 1: command_entry(c, n + 3, names, VECTORS) for n, c in enumerate(commands)}
    entries[5] = 7  # a version only
    entries[6] = None  # stop
    out.append(Seed("command", "full", plain.encode(
        {0: 250, 1: 3, 2: entries, 3: [0, *names.names], 4: [1, 4]})))
    out.append(Seed("command", "no-names", plain.encode({0: 250, 2: {1: entries[1]}})))
    pose = pose_wire(Pose(np.array([0.31, -0.2, 0.05]), np.array([0.0, 0.0, 0.38, 0.92])))
    mmrp = {"T": ("2", "B"), "B": None, "L": None, "R": ("3", "L")}
    out.append(Seed("report", "mmrp", plain.encode(
        {0: 41, 1: 2, 2: 0, 3: mmrp, 4: [["1", "T", "2"]], 5: ["dock T"], 6: 0.93, 7: pose,
         8: 4})))
    table, sensors = _freesn_reports()
    codec = Codec(table)
    kinds = {type(r).__name__: m for m, r in sorted(sensors.items(), reverse=True)}
    for module in sorted(kinds.values()):  # one module of each kind of report
        tree = codec.to_wire(sensors[module])
        out.append(Seed("report", f"freesn-{module}", codec.dumps(
            {0: 12, 2: 0, 3: tree, 7: pose, 8: 2}), records=True))
        partial = cbor2.CBORTag(tree.tag, [tree.value[0], *(
            cbor2.undefined if i % 2 else v for i, v in enumerate(tree.value[1:]))])
        out.append(Seed("report", f"freesn-{module}-partial", codec.dumps(
            {0: 13, 2: 0, 3: partial}), records=True))
    return tuple(out)


# -- mutations -----------------------------------------------------------------------------


def _bytes(rng: random.Random, data: bytes) -> tuple[str, bytes]:
    how = rng.choice(["flip", "cut", "grow", "byte", "splice", "random"])
    buf = bytearray(data)
    if how == "flip" and buf:
        for _ in range(rng.randint(1, 4)):
            i = rng.randrange(len(buf))
            buf[i] ^= 1 << rng.randrange(8)
    elif how == "cut":
        buf = buf[:rng.randrange(len(buf) + 1)]
    elif how == "grow":
        buf += bytes(rng.randrange(256) for _ in range(rng.randint(1, 16)))
    elif how == "byte" and buf:
        buf[rng.randrange(len(buf))] = rng.choice([0x00, 0x1f, 0x5f, 0x7f, 0x9f, 0xbf, 0xf7,
                                                   0xf9, 0xfa, 0xfb, 0xff, 0xd8, 0xc1])
    elif how == "splice" and buf:
        i = rng.randrange(len(buf))
        buf[i:i] = rng.choice([b"\xfb\x7f\xf8\0\0\0\0\0\0", b"\x1b" + b"\xff" * 8,
                               b"\x9f", b"\xbf", b"\xf7", b"\xc1\x00", b"\xd8\x1b\x80"])
    else:
        buf = bytearray(rng.randrange(256) for _ in range(rng.randint(0, 64)))
    return f"bytes_{how}", bytes(buf)


def _deep(levels: int) -> Any:
    value: Any = 0
    for _ in range(levels):
        value = [value]
    return value


ODD: tuple[Callable[[random.Random], Any], ...] = (
    lambda r: math.nan, lambda r: math.inf, lambda r: -math.inf, lambda r: 2**64 - 1,
    lambda r: -(2**63), lambda r: -1, lambda r: 1e308, lambda r: True, lambda r: None,
    lambda r: bytes(r.randrange(256) for _ in range(r.choice([0, 3, 4, 5, 6, 7, 8, 9, 1000]))),
    lambda r: "\u2603" * r.randint(0, 3),
    lambda r: cbor2.undefined, lambda r: cbor2.CBORTag(r.choice([1, 2, 25, 27, 40, 85, 999]),
                                                        r.choice([0, b"\x01\x02", [99, 1], []])),
    lambda r: cbor2.CBORTag(27, [r.choice([0, 2, 99, -1]), "x"]),
    lambda r: cbor2.CBORTag(40, [[4096, 4096, 4096], cbor2.CBORTag(85, b"\0" * 4)]),
    lambda r: _deep(20), lambda r: {True: 1}, lambda r: {1.5: 2},
    lambda r: [], lambda r: {}, lambda r: (1, 2, 3),
)


def _nodes(tree: Any, path: tuple = ()) -> Iterator[tuple]:
    yield path
    value = tree.value if isinstance(tree, cbor2.CBORTag) else tree
    if isinstance(value, dict):
        for key in value:
            yield from _nodes(value[key], (*path, key))
    elif isinstance(value, list | tuple):
        for i, item in enumerate(value):
            yield from _nodes(item, (*path, i))


def _replace(tree: Any, path: tuple, new: Any) -> Any:
    if not path:
        return new
    if isinstance(tree, cbor2.CBORTag):
        return cbor2.CBORTag(tree.tag, _replace(tree.value, path, new))
    head, rest = path[0], path[1:]
    if isinstance(tree, dict):
        return {k: _replace(v, rest, new) if k == head else v for k, v in tree.items()}
    items = list(tree)
    items[head] = _replace(items[head], rest, new)
    return items


def _tree(rng: random.Random, data: bytes) -> tuple[str, bytes] | None:
    try:
        tree = cbor2.loads(data)
    except Exception:  # noqa: BLE001 - a header, not CBOR
        return None
    path = rng.choice(list(_nodes(tree)))
    odd = rng.choice(ODD)(rng)
    try:
        return "tree", cbor2.dumps(_replace(tree, path, odd), canonical=True)
    except Exception:  # noqa: BLE001 - a value cbor2 cannot write (a NaN map key...)
        return None


@dataclass
class Case:
    seed: Seed
    mutation: str
    data: bytes

    @property
    def label(self) -> str:
        return f"{self.seed.kind}:{self.seed.name}:{self.mutation}:{self.data.hex()[:80]}"


def cases(count: int, seed: int) -> Iterator[Case]:
    """``count`` mutated payloads, the same ones for the same ``seed``."""
    rng = random.Random(seed)
    pool = seeds()
    made = 0
    while made < count:
        base = rng.choice(pool)
        made_case = _tree(rng, base.data) if rng.random() < 0.5 else _bytes(rng, base.data)
        if made_case is None:
            continue
        made += 1
        yield Case(base, *made_case)


# -- feeding them --------------------------------------------------------------------------


@dataclass
class Outcome:
    case: Case
    ok: bool
    problem: str | None


def decode(case: Case) -> Outcome:
    """Decode ``case`` as its receiver would."""
    if case.seed.records:
        _freesn_reports()   # built before the clock starts
    started = time.perf_counter()
    try:
        if case.seed.kind == "header":
            read_header(case.data)
        elif case.seed.kind == "command":
            for number in (1, 4):  # a plain entry, and one with a packed vector
                decode_command(case.data, list(NAMES[:2]), number)
        else:
            table, sensors = _freesn_reports() if case.seed.records else (RecordTable(), {})
            previous = next(iter(sensors.values()), None)
            decode_report(Codec(table), case.data, previous, 4)
        ok, problem = True, None
    except (Refused, CodecError):
        ok, problem = False, None
    except Exception:  # noqa: BLE001 - what the fuzzer looks for
        ok, problem = False, "traceback: " + traceback.format_exc(limit=-3)
    took = time.perf_counter() - started
    if took > LIMIT:
        problem = f"took {took:.1f} s"
    return Outcome(case, ok, problem)


def campaign(count: int, seed: int) -> list[Outcome]:
    return [decode(case) for case in cases(count, seed)]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=5000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    print(f"seed {args.seed}, {args.cases} cases")
    started = time.perf_counter()
    outcomes = campaign(args.cases, args.seed)
    problems = [o for o in outcomes if o.problem]
    print(f"{len(outcomes)} decodes in {time.perf_counter() - started:.1f} s; accepted "
          f"{sum(o.ok for o in outcomes)}, refused {sum(not o.ok for o in outcomes)}; problems: "
          f"{dict(Counter(o.problem.split(':')[0] for o in problems)) or 'none'}")
    for outcome in problems[:20]:
        print(f"- {outcome.case.label}: {outcome.problem[:900]}")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
