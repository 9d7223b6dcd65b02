"""A seeded fuzzer of the run's options (issue 30): ``--driver-option`` items of every
built-in driver and ``--faults`` specs.

Each case is generated together with whether it is valid, from the declarations and the
fault grammar (:data:`~msrr.core.faults.FAULT_KINDS`), independently of the code that
checks it. Every case must end

* when valid, in acceptance: :func:`~msrr.core.driver.check_driver_options` types it, or
  :func:`~msrr.core.faults.parse_faults` and
  :func:`~msrr.core.faults.check_fault_modules` take it;
* when invalid, in one clean :class:`~msrr.core.errors.MsrrError` of one line of at most
  300 characters, never another exception; and, for the cases also fed to ``platform
  run`` (and ``platform sweep`` for fault specs), exit 1 with one line and no run folder.

Run as a script for a longer campaign::

    python tests/fuzz/fuzz_options.py --cases 20000 --seed 7
"""

from __future__ import annotations

import argparse
import math
import random
import sys
import tempfile
import time
import traceback
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass
from functools import cache
from pathlib import Path

from click.testing import CliRunner

from msrr.core import plugins
from msrr.core.app.cli import get_cli
from msrr.core.app.run import parse_driver_options
from msrr.core.driver import RESERVED_OPTIONS, DriverOption, check_driver_options, declared_options
from msrr.core.errors import MAX_MESSAGE, MsrrError
from msrr.core.faults import FAULT_KINDS, check_fault_modules, parse_faults

ROOT = Path(__file__).resolve().parents[2]
DRIVERS = (("mmrp", "pybullet"), ("mmrp", "kinematic"), ("freesn", "mujoco"),
           ("freebot", "mujoco"), ("snailbot", "kinematic"))
"""The drivers whose options are fuzzed (robot, driver)."""
FAULT_ROBOT = ("mmrp", "series-t")
"""The run fault specs are checked against (its start has modules 1 to 4)."""
MODULES = ("1", "2", "3", "4")


@dataclass
class Case:
    """One generated input: what it is, its text and whether it is valid."""

    kind: str  # "driver-option" or "faults"
    robot: str
    driver: str  # the driver; for a fault spec, the scenario it is checked against
    items: tuple[str, ...]  # --driver-option items, or one fault spec
    valid: bool
    why: str  # what makes it invalid (for the report)

    @property
    def label(self) -> str:
        return f"{self.kind}:{self.robot}:{self.driver}:{' '.join(self.items)!r}"


@cache
def _declared(robot: str, driver: str) -> tuple[DriverOption, ...]:
    declared = declared_options(plugins.capabilities(robot).drivers[driver])
    assert declared is not None
    return declared


# -- driver options -----------------------------------------------------------------------


def _value(rng: random.Random, option: DriverOption) -> tuple[str, bool]:
    """A value for ``option`` as text, and whether the option takes it."""
    if option.type is not str:
        return _number(rng, option)
    if rng.random() < 0.6:
        choice = rng.choice(option.choices) if option.choices else "text"
        return rng.choice([choice, f" {choice} "]), True
    text = rng.choice(["", " ", "1.5", "-468.78", "1e+308", "nan", "\u2603",
                       *(c.upper() for c in option.choices), *(c + "x" for c in option.choices)])
    return text, bool(text.strip()) and (not option.choices or text.strip() in option.choices)


def _number(rng: random.Random, option: DriverOption) -> tuple[str, bool]:
    """A value for the number ``option`` as text, and whether it is within its bounds."""
    low = option.low if option.low is not None else -1e3
    high = option.high if option.high is not None else 1e3
    kind = rng.choice(["inside", "inside", "edge", "outside", "text", "special"])
    if kind == "inside":
        value = rng.uniform(low, high)
        if (option.low_open and value <= low) or (option.high_open and value >= high):
            value = (low + high) / 2
        return rng.choice([repr(value), f"{value:.3g}", f"{value:e}"]), _within(option, value)
    if kind == "edge":
        value = rng.choice([low, high])
        return repr(value), _within(option, value)
    if kind == "outside":
        value = rng.choice([low - abs(low) - 1, high + abs(high) + 1, -1e308, 1e308])
        return repr(value), _within(option, value)
    if kind == "text":
        return rng.choice(["abc", "", " ", "1,5", "0x10", "one", "[1]", "true", "none",
                           "\u2603", "1e", "--1"]), False
    text = rng.choice(["nan", "NaN", "inf", "-inf", "1e999", "-1e999", "18446744073709551616",
                       "1" + "0" * 400])
    value = float(text)
    return text, math.isfinite(value) and _within(option, value)


def _within(option: DriverOption, value: float) -> bool:
    if not math.isfinite(value):
        return False
    if option.low is not None and (value < option.low or option.low_open and value == option.low):
        return False
    return option.high is None or not (value > option.high
                                       or option.high_open and value == option.high)


def _driver_case(rng: random.Random) -> Case:
    robot, driver = rng.choice(DRIVERS)
    declared = {o.name: o for o in _declared(robot, driver)}
    items, valid, why, seen = [], True, "", set()
    for _ in range(rng.choice([1, 1, 2, 3])):
        roll = rng.random()
        if roll < 0.7 and declared:
            name = rng.choice(sorted(declared))
            text, good = _value(rng, declared[name])
            if not good:
                valid, why = False, why or f"{name}={text!r} out of its declaration"
        elif roll < 0.8:
            name, text = rng.choice(RESERVED_OPTIONS), str(rng.randint(0, 5))
            valid, why = False, why or f"{name} is reserved"
        elif roll < 0.9:
            name = rng.choice(["nope", "noise_", "Noise", "slip ", "physics-rate", "x" * 300,
                               "\u2603"])
            text = str(rng.random())
            if name.strip() not in declared:
                valid, why = False, why or f"unknown {name!r}"
        else:
            items.append(rng.choice(["=1", "novalue", "", "==", " =2"]))
            valid, why = False, why or "not KEY=VALUE"
            continue
        if name.strip() in seen:
            valid, why = False, why or f"{name} twice"
        seen.add(name.strip())
        items.append(f"{name}={text}")
    return Case("driver-option", robot, driver, tuple(items), valid, why)


# -- fault specs ---------------------------------------------------------------------------


def _fault_value(rng: random.Random, kind: str, key: str) -> tuple[str, bool]:
    """A value of ``key`` of fault ``kind`` as text, and whether it is valid."""
    if key == "module":
        if rng.random() < 0.7:
            return rng.choice(MODULES), True
        text = rng.choice(["99", "0", "", "a", "1 ", "\u2603"])
        return text, text.strip() in MODULES  # values are stripped; "" is refused
    if key == "reading":
        text = rng.choice(["pose", "sensors", "pose", "poses", "", "POSE"])
        return text, text in ("pose", "sensors")
    integer = key in ("ticks", "count")
    roll = rng.random()
    if roll < 0.6:
        value = rng.randint(1, 5) if integer else round(rng.uniform(0.0, 1.0 if key == "p"
                                                                    else 10.0), 3)
        return str(value), True
    text = rng.choice(["-1", "nan", "inf", "abc", "", "1e999", "2", "0", "1.5", "18446744073709551616"])
    try:
        value = float(text)
    except ValueError:
        return text, False
    if math.isnan(value) or value < 0 or (math.isinf(value) and key != "for"):
        return text, False
    if integer:
        return text, value >= 1 and value == int(value)
    return text, not (key == "p" and value > 1)


def _fault_item(rng: random.Random) -> tuple[str, bool, str]:
    if rng.random() < 0.08:
        kind = rng.choice(["warp", "Dropout", "", "loss "])
        return f"{kind}:p=0.1", kind.strip() in FAULT_KINDS and kind.strip() == "loss", \
            f"kind {kind!r}"
    kind = rng.choice(sorted(FAULT_KINDS))
    keys = FAULT_KINDS[kind]
    pairs, valid, why = [], True, ""
    chosen = [k for k in keys if keys[k] is None or rng.random() < 0.5]
    if rng.random() < 0.1 and any(keys[k] is None for k in chosen):
        dropped = next(k for k in chosen if keys[k] is None)
        chosen.remove(dropped)
        valid, why = False, f"{kind} without {dropped}"
    if rng.random() < 0.08:
        chosen.append(rng.choice(["zap", "P", "module_"]))
        valid, why = False, why or "unknown key"
    if rng.random() < 0.05 and chosen:
        chosen.append(chosen[0])
        valid, why = False, why or "a key twice"
    for key in chosen:
        text, good = _fault_value(rng, kind, key) if key in keys else ("1", True)
        if not good:
            valid, why = False, why or f"{kind}:{key}={text!r}"
        pairs.append(f"{key}={text}")
    if rng.random() < 0.05:
        pairs.append(rng.choice(["novalue", "=", "x="]))
        valid, why = False, why or "not KEY=VALUE"
    item = f"{kind}:{','.join(pairs)}" if pairs else kind
    return item, valid, why


def _faults_case(rng: random.Random) -> Case:
    items = [_fault_item(rng) for _ in range(rng.choice([1, 1, 2, 3]))]
    spec = rng.choice([";", "; ", " ;"]).join(text for text, _, _ in items)
    valid = all(good for _, good, _ in items)
    why = next((w for _, good, w in items if not good), "")
    if rng.random() < 0.03:  # blank is no fault (as 'none' is for a sweep); ';' is none given
        spec = rng.choice([";", " ", ";;", ""])
        valid, why = not spec.strip(), "no fault"
    return Case("faults", *FAULT_ROBOT, (spec,), valid, why)


def cases(count: int, seed: int) -> Iterator[Case]:
    """``count`` cases, the same ones for the same ``seed``."""
    rng = random.Random(seed)
    for _ in range(count):
        yield _driver_case(rng) if rng.random() < 0.5 else _faults_case(rng)


# -- feeding them --------------------------------------------------------------------------


@dataclass
class Outcome:
    case: Case
    target: str
    ok: bool
    problem: str | None


def _message(text: str) -> str | None:
    lines = text.strip().splitlines()
    if len(lines) != 1:
        return f"{len(lines)} lines: {text.strip()[:300]}"
    if len(lines[0]) > MAX_MESSAGE + len("Error: "):
        return f"{len(lines[0])} characters"
    return None


def check(case: Case) -> Outcome:
    """Feed ``case`` to the function that checks it."""
    try:
        if case.kind == "driver-option":
            factory = plugins.capabilities(case.robot).drivers[case.driver]
            check_driver_options(factory, parse_driver_options(case.items))
        elif case.items[0].strip():  # blank: no faults (platform run's rule)
            check_fault_modules(parse_faults(case.items[0]), MODULES)
    except MsrrError as exc:
        bad = _message(str(exc))
        if case.valid:
            bad = f"valid input refused: {exc}"
        return Outcome(case, "check", False, bad)
    except Exception:  # noqa: BLE001 - what the fuzzer looks for
        return Outcome(case, "check", False, "traceback: " + traceback.format_exc(limit=-3))
    return Outcome(case, "check", True, None if case.valid else f"bad input accepted "
                   f"({case.why})")


def run_command(case: Case, folder: Path, runner: CliRunner, sweep: bool = False) -> Outcome:
    """Feed an invalid ``case`` to ``platform run`` (or ``sweep``): exit 1, one line, no
    folder."""
    out = folder / "out"
    if case.kind == "driver-option":
        args = ["run", "--robot", case.robot, "--driver", case.driver]
        args += [a for item in case.items for a in ("--driver-option", item)]
    else:
        args = ["sweep" if sweep else "run", "--robot", case.robot, "--scenario",
                FAULT_ROBOT[1], "--faults", case.items[0]]
        args += ["--runs", "1", "--workers", "1"] if sweep else []
    result = runner.invoke(get_cli(), [*args, "--out", str(out)])
    target = args[0]
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        text = "".join(traceback.format_exception(result.exception, limit=-3))
        return Outcome(case, target, False, "traceback: " + text)
    if result.exit_code == 0:
        return Outcome(case, target, True, f"bad input accepted ({case.why})")
    bad = _message(result.stderr) or (None if result.exit_code in (1, 2)
                                      else f"exit status {result.exit_code}")
    if out.exists():
        bad = "an output folder for refused input"
    return Outcome(case, target, False, bad)


def campaign(count: int, seed: int, folder: Path, *, command_every: int = 1) -> list[Outcome]:
    """``count`` cases checked, and every ``command_every``-th invalid one also fed to
    ``platform run`` (fault specs alternately to ``platform sweep``)."""
    runner = CliRunner()
    outcomes: list[Outcome] = []
    invalid = 0
    for index, case in enumerate(cases(count, seed)):
        outcomes.append(check(case))
        if not case.valid:
            invalid += 1
            if invalid % command_every == 0:
                place = folder / f"{index:05d}"
                place.mkdir()
                sweep = case.kind == "faults" and (invalid // command_every) % 2 == 0
                outcomes.append(run_command(case, place, runner, sweep=sweep))
    return outcomes


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--command-every", type=int, default=5)
    args = parser.parse_args(argv)
    print(f"seed {args.seed}, {args.cases} cases")
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        outcomes = campaign(args.cases, args.seed, Path(tmp), command_every=args.command_every)
    problems = [o for o in outcomes if o.problem]
    print(f"{len(outcomes)} checks in {time.perf_counter() - started:.1f} s; accepted "
          f"{sum(o.ok for o in outcomes)}, refused {sum(not o.ok for o in outcomes)}; problems: "
          f"{dict(Counter(o.problem.split(':')[0] for o in problems)) or 'none'}")
    for outcome in problems[:40]:
        print(f"- {outcome.case.label} -> {outcome.target}: {outcome.problem[:600]}")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
