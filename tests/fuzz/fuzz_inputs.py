"""A seeded fuzzer of every file reader and file-reading command (issues 11 and 30).

Valid files of every kind (configurations of every installed robot, the shipped
libraries, library sources, plans made by the MMRP, MISO and library planners in both
plan file versions, kinematic tree files) are
mutated in the ways of issue 11 and fed in-process to the readers and, through click's
``CliRunner``, to the commands. Every case must end either

* in one clean :class:`~msrr.core.errors.MsrrError`: a reader raises one whose text is
  one line of at most 300 characters naming the file; a command exits 1 (2 for a
  usage error) with one such line and no traceback; or
* in success, when the mutation may leave a valid file (:data:`MAY_PASS`): deleting
  an optional key, another value of an accepted type, a huge but finite number, a
  removed or added connection where the robot allows it, names with rich markup
  (``"[/red]"``), which must print literally.

Tree files are read as they are used: loaded onto the configuration they were made
for, with the robot's joint modes. Plans are also fed to ``platform run --plan`` when
their mutation must be refused: one line, exit 1 and no run folder.

Issue 30 added mutations of whole documents (``null``, a number, a list...), of plans
(an action copied, dropped or moved, the start swapped for the goal, an action's
``modules`` emptied) and of libraries (a mapping entry dropped, a tree's configuration
key removed, a behavior command its module does not take); the build record of a
library is no longer free-form. Driver options and fault specs have their own
generator (:mod:`fuzz_options`), the link decoder its own (:mod:`fuzz_link`).

A mutation not in :data:`MAY_PASS` that is accepted is a *bad file accepted*.

Run as a script for a longer campaign::

    python tests/fuzz/fuzz_inputs.py --cases 20000 --seed 7
"""

from __future__ import annotations

import argparse
import json
import random
import sys
import tempfile
import time
import traceback
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

from click.testing import CliRunner

from msrr.core import plugins
from msrr.core.app.cli import get_cli
from msrr.core.errors import MAX_MESSAGE, MsrrError
from msrr.core.io import load_configuration
from msrr.core.kinematics import default_tree
from msrr.core.kinematics.tree import load_tree, save_tree
from msrr.core.library import load_sources
from msrr.core.plan import save_plan

ROOT = Path(__file__).resolve().parents[2]
FREE = {"stats", "kinematic_tree", "notes", "note", "description", "origins"}
"""Keys whose content is free-form: any JSON value (but NaN, repeated keys...) is fine."""

MAY_PASS = {"delete_key", "wrong_type", "huge_float", "drop_connection", "add_connection",
            "markup_name", "wrong_type_free", "rename_free", "bool_free"}
"""Mutations that may leave a valid file (see the module doc)."""


# -- valid inputs -------------------------------------------------------------------------


@dataclass(frozen=True)
class Seed:
    """A valid input file: its kind and its parsed content."""

    kind: str  # configuration, library, sources, plan, tree
    name: str
    doc: Any


@cache
def seeds() -> tuple[Seed, ...]:
    """Every valid input the fuzzer mutates (built once per process)."""
    out = []
    configs = sorted((ROOT / "plugins").glob("*/configs/**/*.json"))
    configs += sorted((ROOT / "examples").glob("*/*/configs/**/*.json"))
    robots = set(plugins.robots())
    for path in configs:
        doc = json.loads(path.read_text())
        if doc["robot"] in robots:
            out.append(Seed("configuration", path.name, doc))
    for path in sorted((ROOT / "plugins/freesn/libraries").glob("*.json")):
        if not path.name.endswith(".check.json"):
            out.append(Seed("library", path.name, json.loads(path.read_text())))
    for path in sorted((ROOT / "plugins/freesn/library_sources").glob("*/*.json")):
        out.append(Seed("sources", f"{path.parent.name}-{path.name}",
                        json.loads(path.read_text())))
    with tempfile.TemporaryDirectory() as tmp:
        mmrp = ROOT / "plugins/mmrp/configs"
        planner = plugins.planners.get("mmrp")
        for start, goal in (("probe", "cross"), ("t", "series")):
            plan = planner.plan(load_configuration(mmrp / f"{start}.json"),
                                load_configuration(mmrp / f"{goal}.json"), seed=0)
            save_plan(plan, Path(tmp) / "plan.json")
            out.append(Seed("plan", f"{start}-{goal}.plan.json",
                            json.loads((Path(tmp) / "plan.json").read_text())))
        for robot, start, goal in PLAN_PAIRS:  # vectors, kinematic trees
            plan = plugins.planners.get(robot).plan(load_configuration(ROOT / start),
                                                    load_configuration(ROOT / goal))
            save_plan(plan, Path(tmp) / "plan.json")
            out.append(Seed("plan", f"{robot}.plan.json",
                            json.loads((Path(tmp) / "plan.json").read_text())))
        for path in sorted(V1_PLANS.glob("*.json")):  # version 1: every target whole
            out.append(Seed("plan", f"v1-{path.name}", json.loads(path.read_text())))
        freesn = plugins.resolve("freesn")
        for name in TREE_CONFIGURATIONS:
            config = _configuration_named(name)
            save_tree(default_tree(config, freesn.default_joint_mode()), Path(tmp) / "tree.json")
            out.append(Seed("tree", f"{name}.tree.json",
                            json.loads((Path(tmp) / "tree.json").read_text())))
    return tuple(out)


# -- mutations ----------------------------------------------------------------------------


def _nodes(doc: Any, path: tuple = ()) -> Iterator[tuple[tuple, Any]]:
    yield path, doc
    if isinstance(doc, dict):
        for key, value in doc.items():
            yield from _nodes(value, (*path, key))
    elif isinstance(doc, list):
        for i, value in enumerate(doc):
            yield from _nodes(value, (*path, i))


def _free(path: tuple) -> bool:
    return any(part in FREE for part in path if isinstance(part, str))


def _set(doc: Any, path: tuple, value: Any) -> None:
    for part in path[:-1]:
        doc = doc[part]
    doc[path[-1]] = value


TOKEN = "\u2603fuzz-token\u2603"


def _with_raw(doc: Any, path: tuple, raw: str) -> bytes:
    """``doc`` as JSON text with the value at ``path`` replaced by the raw text ``raw``."""
    doc = _copy(doc)
    if path:
        _set(doc, path, TOKEN)
        return json.dumps(doc).replace(json.dumps(TOKEN), raw, 1).encode()
    return raw.encode()


def _dump(doc: Any) -> bytes:
    return json.dumps(doc).encode()


@dataclass
class Case:
    """One mutated input: how it was made and its bytes (``None``: a directory)."""

    seed: Seed
    mutation: str
    data: bytes | None

    @property
    def label(self) -> str:
        return f"{self.seed.kind}:{self.seed.name}:{self.mutation}"


Mutator = Callable[[random.Random, Seed], tuple[str, bytes | None] | None]


_NODES: dict[int, list[tuple[tuple, Any]]] = {}
_TEXT: dict[int, str] = {}
_FOUND: dict[tuple[int, Any], list[tuple]] = {}


def _pick(rng: random.Random, doc: Any, want: Callable[[tuple, Any], bool]) -> tuple | None:
    """A random path of ``doc`` whose value ``want`` accepts (seed documents only: the
    paths each predicate accepts are listed once)."""
    key = (id(doc), want.__code__)  # the predicates close over nothing
    found = _FOUND.get(key)
    if found is None:
        nodes = _NODES.get(id(doc))
        if nodes is None:
            nodes = _NODES[id(doc)] = [(p, v) for p, v in _nodes(doc) if p]
        found = _FOUND[key] = [p for p, v in nodes if want(p, v)]
    return rng.choice(found) if found else None


def _copy(doc: Any) -> Any:
    """A deep copy of a seed document (through its JSON text: fast)."""
    text = _TEXT.get(id(doc))
    if text is None:
        text = _TEXT[id(doc)] = json.dumps(doc)
    return json.loads(text)


def m_truncate(rng: random.Random, seed: Seed):
    text = _dump(seed.doc)
    return "truncate", text[:rng.randrange(0, len(text.rstrip()) - 1)]


def m_empty(rng, seed):
    return "empty", b""


def m_directory(rng, seed):
    return "directory", None


def m_non_utf8(rng, seed):
    text = _dump(seed.doc)
    at = rng.randrange(len(text))
    return "non_utf8", text[:at] + rng.choice([b"\xff", b"\xc3\x28", b"\xed\xa0\x80"]) + text[at:]


def m_delete_key(rng, seed):
    doc = _copy(seed.doc)
    path = _pick(rng, seed.doc, lambda p, v: isinstance(p[-1], str))
    if path is None:
        return None
    parent = doc
    for part in path[:-1]:
        parent = parent[part]
    del parent[path[-1]]
    return ("delete_key", _dump(doc))


def m_rename_key(rng, seed):
    doc = _copy(seed.doc)
    path = _pick(rng, seed.doc, lambda p, v: isinstance(p[-1], str))
    if path is None:
        return None
    parent = doc
    for part in path[:-1]:
        parent = parent[part]
    parent[path[-1] + "_x"] = parent.pop(path[-1])
    return ("rename_free" if _free(path) else "rename_key", _dump(doc))


def m_duplicate_key(rng, seed):
    path = _pick(rng, seed.doc, lambda p, v: isinstance(v, dict) and v)
    if path is None:
        return None
    obj = _copy(seed.doc)
    for part in path:
        obj = obj[part]
    key = rng.choice(list(obj))
    pairs = [f"{json.dumps(k)}: {json.dumps(v)}" for k, v in obj.items()]
    pairs.append(f"{json.dumps(key)}: {json.dumps(rng.choice([0, 'x', None]))}")
    return "duplicate_key", _with_raw(seed.doc, path, "{" + ", ".join(pairs) + "}")


def m_wrong_type(rng, seed):
    path = _pick(rng, seed.doc, lambda p, v: True)
    if path is None:
        return None
    value = _value_at(seed.doc, path)
    choices = [v for v in (0, 1.5, "text", None, [], {}, [1, 2], {"a": 1})
               if type(v) is not type(value)]
    doc = _copy(seed.doc)
    _set(doc, path, rng.choice(choices))
    return ("wrong_type_free" if _free(path) else "wrong_type", _dump(doc))


def _value_at(doc: Any, path: tuple) -> Any:
    for part in path:
        doc = doc[part]
    return doc


def _numbers(p: tuple, v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


def m_non_finite(rng, seed):
    path = _pick(rng, seed.doc, _numbers) or _pick(rng, seed.doc, lambda p, v: True)
    raw = rng.choice(["NaN", "Infinity", "-Infinity", "1e400", "-1e999"])
    return "non_finite", _with_raw(seed.doc, path, raw)


def m_huge(rng, seed):
    path = _pick(rng, seed.doc, _numbers)
    if path is None:
        return None
    if rng.random() < 0.5:
        return "huge_int", _with_raw(seed.doc, path, "1" + "0" * rng.choice([19, 30, 400, 5000]))
    doc = _copy(seed.doc)
    _set(doc, path, rng.choice([1e300, -1e308, 1e200]))
    return "huge_float", _dump(doc)


def m_bool_number(rng, seed):
    path = _pick(rng, seed.doc, _numbers)
    if path is None:
        return None
    doc = _copy(seed.doc)
    _set(doc, path, rng.choice([True, False]))
    return ("bool_free" if _free(path) else "bool_number", _dump(doc))


def m_deep(rng, seed):
    path = _pick(rng, seed.doc, lambda p, v: True)
    depth = rng.choice([70, 1000, 5000, 20000])
    opener, closer = rng.choice([("[", "]"), ('{"a":', "}")])
    return "deep_nesting", _with_raw(seed.doc, path, opener * depth + "0" + closer * depth)


def m_surrogate(rng, seed):
    path = _pick(rng, seed.doc, lambda p, v: isinstance(v, str)) or ()
    return "surrogate", _with_raw(seed.doc, path, rng.choice(['"\\ud800"', '"a\\udfff"']))


def m_unknown_kind(rng, seed):
    doc = _copy(seed.doc)
    path = _pick(rng, seed.doc, lambda p, v: p[-1] in ("kind", "robot", "type", "action")
                 and isinstance(v, str) and not _free(p))
    if path is None:
        return None
    _set(doc, path, rng.choice(["warpdrive", "", "[/red]"]))
    return "unknown_kind", _dump(doc)


def m_unknown_port(rng, seed):
    doc = _copy(seed.doc)
    path = _pick(rng, seed.doc, lambda p, v: p[-1] in ("ports",) and isinstance(v, list)
                 and not _free(p))
    if path is None:
        return None
    _set(doc, path, [v if i else "Q9" for i, v in enumerate(_value_at(doc, path))])
    return "unknown_port", _dump(doc)


def _connections(rng: random.Random, doc: Any) -> tuple | None:
    return _pick(rng, doc, lambda p, v: p[-1] == "connections" and isinstance(v, list) and v
                 and not _free(p))


def m_self_loop(rng, seed):
    doc = _copy(seed.doc)
    path = _connections(rng, seed.doc)
    if path is None:
        return None
    conns = _value_at(doc, path)
    edge = rng.choice(conns)
    edge["target"] = edge["source"]
    return "self_loop", _dump(doc)


def m_duplicate_id(rng, seed):
    doc = _copy(seed.doc)
    path = _pick(rng, seed.doc, lambda p, v: isinstance(v, list) and len(v) > 1
                 and all(isinstance(x, dict) and "id" in x for x in v) and not _free(p))
    if path is None:
        return None
    items = _value_at(doc, path)
    i, j = rng.sample(range(len(items)), 2)
    items[j]["id"] = items[i]["id"]
    return "duplicate_id", _dump(doc)


def m_drop_connection(rng, seed):
    doc = _copy(seed.doc)
    path = _connections(rng, seed.doc)
    if path is None:
        return None
    conns = _value_at(doc, path)
    conns.pop(rng.randrange(len(conns)))
    return "drop_connection", _dump(doc)


def m_add_connection(rng, seed):
    doc = _copy(seed.doc)
    path = _connections(rng, seed.doc)
    if path is None:
        return None
    conns = _value_at(doc, path)
    modules = _value_at(doc, path[:-1]).get("modules") or []
    if len(modules) < 2:
        return None
    extra = dict(rng.choice(conns))
    a, b = rng.sample([m["id"] for m in modules], 2)
    extra.update(source=a, target=b)
    if "id" in extra:
        extra["id"] = f"{extra['id']}x"
    conns.append(extra)
    return "add_connection", _dump(doc)


def m_markup_name(rng, seed):
    doc = _copy(seed.doc)
    path = _pick(rng, seed.doc, lambda p, v: p[-1] in ("name", "description", "note")
                 and isinstance(v, str) and len(p) <= 3)
    if path is None or (seed.kind in ("library", "sources") and path[-1] == "name"):
        return None  # library and sequence names are references; descriptions are free
    _set(doc, path, rng.choice(["[/red]", "[red]x[/red] [nan, 0.0, 1.0]", "q[", "[bold]"]))
    return "markup_name", _dump(doc)


def m_not_object(rng, seed):
    raw = rng.choice(["null", "1", "true", '"text"', "[]", "-0.5", json.dumps([seed.doc])])
    return "not_object", raw.encode()


PLAN_PAIRS = (("freebot", "plugins/freebot/configs/chain6.json",
               "plugins/freebot/configs/star6.json"),
              ("freesn", "plugins/freesn/configs/library/S6N3-1.1.json",
               "plugins/freesn/configs/library/S6N3-2.1.json"))
"""Plans of other robots than MMRP among the seeds: connection vectors (FreeBOT),
kinematic trees (a FreeSN library plan)."""

V1_PLANS = ROOT / "tests/core/plans_v1"
"""Version 1 plan files (every target whole), still read."""


def _changing(doc: Any) -> list[int]:
    """Indices of a plan's actions that make or break connections."""
    return [i for i, a in enumerate(doc.get("actions", [])) if a.get("changes")]


def m_plan_steps(rng, seed):
    """An action copied next to itself, one that changes connections dropped, two next to
    each other (one changing connections) swapped, or the start swapped for the goal:
    each breaks the chain from the start to the goal.

    In a version 2 file each target is its changes to the one before, so two actions
    swap all but their targets (swapped whole, with their changes, they would be
    another valid plan), and the start loses a connection instead (the goal is changes
    too)."""
    if seed.kind != "plan" or not _changing(seed.doc):
        return None
    doc = _copy(seed.doc)
    actions = doc["actions"]
    changes = doc.get("schema_version", 1) == 2
    how = rng.choice(["copy", "drop", "swap", "start"])
    if how == "copy":
        i = rng.randrange(len(actions))
        actions.insert(i, json.loads(json.dumps(actions[i])))
    elif how == "drop":
        del actions[rng.choice(_changing(doc))]
    elif how == "swap":
        i = rng.choice([i for i in _changing(doc) if i + 1 < len(actions)]
                       or [i - 1 for i in _changing(doc) if i] or [-1])
        if i < 0:  # no changing action has a neighbour: two moves may swap validly
            return None
        actions[i], actions[i + 1] = actions[i + 1], actions[i]
        if changes:
            targets = [actions[j].pop("target", None) for j in (i + 1, i)]
            for j, target in zip((i, i + 1), targets, strict=True):
                if target is not None:
                    actions[j]["target"] = target
    elif changes:
        doc["start"]["connections"].pop()
    else:
        doc["start"] = doc["goal"]
    return f"plan_{how}", _dump(doc)


def m_plan_changes(rng, seed):
    """Version 2: an action's target changes emptied (it changes connections), a
    connection it removes that is not there, or an insertion index past the end."""
    changing = [i for i in _changing(seed.doc) if seed.doc["actions"][i].get("target")]
    if seed.kind != "plan" or seed.doc.get("schema_version") != 2 or not changing:
        return None
    doc = _copy(seed.doc)
    target = doc["actions"][rng.choice(changing)]["target"]
    how = rng.choice(["emptied", "unknown", "index"])
    if how == "emptied":
        target.clear()
    elif how == "unknown":
        target.setdefault("removed_connections", []).append("no-such-connection")
    else:
        written = target.get("connections") or target.get("modules")
        if not written:
            return None
        rng.choice(written)["at"] = 10_000 + rng.randrange(10**6)
    return f"plan_{how}", _dump(doc)


def m_plan_modules(rng, seed):
    """An action that changes connections or has goals names none of its modules."""
    if seed.kind != "plan":
        return None
    doc = _copy(seed.doc)
    acting = [a for a in doc["actions"] if a.get("changes") or a.get("goals")]
    if not acting:
        return None
    rng.choice(acting)["modules"] = []
    return "plan_modules", _dump(doc)


def m_library_parts(rng, seed):
    """A module dropped from an edge's mapping, a tree's configuration key removed, or a
    behavior command its module kind does not take."""
    if seed.kind != "library":
        return None
    doc = _copy(seed.doc)
    subs = doc["sublibraries"]
    mappings = [e["mapping"] for s in subs for e in s["edges"] if e.get("mapping")]
    trees = [t["tree"] for s in subs for g in s["groups"] for t in g["trees"]]
    commands = [c for s in subs for b in s["behaviors"] for c in b.get("commands", [])]
    how = rng.choice([h for h, there in (("mapping", mappings), ("tree", trees),
                                         ("command", commands)) if there])
    if how == "mapping":
        mapping = rng.choice(mappings)
        modules = [k for k in mapping["nodes"] if ":" not in k] + list(mapping["edges"])
        key = rng.choice(modules)
        mapping["nodes" if key in mapping["nodes"] else "edges"].pop(key)
    elif how == "tree":
        rng.choice(trees).pop("configuration")
    else:
        rng.choice(commands)["command"] = rng.choice(["warp", "wheel-speed", ""])
    return f"library_{how}", _dump(doc)


MUTATORS: tuple[Mutator, ...] = (
    m_truncate, m_empty, m_directory, m_non_utf8, m_delete_key, m_rename_key, m_duplicate_key,
    m_wrong_type, m_non_finite, m_huge, m_bool_number, m_deep, m_surrogate, m_unknown_kind,
    m_unknown_port, m_self_loop, m_duplicate_id, m_drop_connection, m_add_connection,
    m_markup_name, m_not_object, m_plan_steps, m_plan_modules, m_plan_changes,
    m_library_parts)


KIND_WEIGHTS = {"configuration": 4, "library": 2, "sources": 1.5, "plan": 1.5, "tree": 1}
"""How often each kind of file is mutated (configurations feed the most commands)."""


def cases(count: int, seed: int, kinds: tuple[str, ...] | None = None) -> Iterator[Case]:
    """``count`` mutated inputs, the same ones for the same ``seed``."""
    rng = random.Random(seed)
    pool: dict[str, list[Seed]] = {}
    for s in seeds():
        if kinds is None or s.kind in kinds:
            pool.setdefault(s.kind, []).append(s)
    weights = [KIND_WEIGHTS[kind] for kind in pool]
    made = 0
    while made < count:
        base = rng.choice(pool[rng.choices(list(pool), weights)[0]])
        made_case = rng.choice(MUTATORS)(rng, base)
        if made_case is None:
            continue
        made += 1
        yield Case(base, *made_case)


def cases_of(mutation: str, count: int, seed: int, *, attempts: int = 20_000
             ) -> list[Case]:
    """``count`` cases whose mutation is ``mutation`` (e.g. ``plan_drop``), drawn as
    :func:`cases` draws, the others skipped: a rare mutation is exercised whatever the
    seed files are, which a random campaign of a fixed size cannot promise."""
    rng = random.Random(seed)
    pool = seeds()
    found: list[Case] = []
    for _ in range(attempts):
        base = rng.choice(pool)
        made = rng.choice(MUTATORS)(rng, base)
        if made is not None and made[0] == mutation:
            found.append(Case(base, *made))
            if len(found) == count:
                break
    return found


# -- feeding them -------------------------------------------------------------------------


@dataclass
class Outcome:
    case: Case
    target: str  # reader or command
    ok: bool  # the input was accepted
    problem: str | None  # a traceback, a bad message, or a bad file accepted


def write(case: Case, folder: Path, index: int) -> Path:
    path = folder / f"in [red] {index:05d} {case.seed.name}"
    if case.data is None:
        path.mkdir()
    else:
        path.write_bytes(case.data)
    return path


def _check_message(text: str, path: Path) -> str | None:
    lines = text.strip().splitlines()
    if len(lines) != 1:
        return f"{len(lines)} lines"
    if len(lines[0]) > MAX_MESSAGE + len("Error: "):
        return f"{len(lines[0])} characters"
    if path.name not in lines[0]:
        return "does not name the file"
    return None


READERS: dict[str, Callable[[Path], object]] = {
    "configuration": plugins.load_configuration,
    "library": plugins.load_library,
    "plan": plugins.load_plan,
    "sources": lambda path: load_sources([path], plugins.resolve),
    "tree": lambda path: load_tree(path, _tree_configuration(path),
                                   modes=plugins.resolve("freesn").joint_modes),
}


@cache
def _configuration_named(name: str):
    """A shipped FreeSN configuration by name (wherever under configs/ it is)."""
    return load_configuration(_configuration_path(name))


def _tree_configuration(path: Path):
    """The configuration a fuzzed tree file was made for (its name says which)."""
    return _configuration_named(next(n for n in TREE_CONFIGURATIONS if n in path.name))


TREE_CONFIGURATIONS = ("S6N3-1.1", "S4N5-2.1")


def _configuration_path(name: str) -> Path:
    return next((ROOT / "plugins/freesn/configs").rglob(f"{name}.json"))


def read(case: Case, path: Path) -> Outcome:
    """Feed ``path`` to the reader of its kind."""
    target = f"read {case.seed.kind}"
    try:
        READERS[case.seed.kind](path)
    except MsrrError as exc:
        bad = _check_message(str(exc), path)
        return Outcome(case, target, False, bad and f"message {bad}: {exc}")
    except Exception:  # noqa: BLE001 - what the fuzzer looks for
        return Outcome(case, target, False, "traceback: " + traceback.format_exc(limit=-3))
    accepted = None if case.mutation in MAY_PASS else "bad file accepted"
    return Outcome(case, target, True, accepted)


def _commands(case: Case, path: Path) -> list[list[str]]:
    """The commands that read ``path``: cheap ones for every case, costly ones for few."""
    kind = case.seed.kind
    if kind == "configuration":
        out = [["validate", str(path)], ["show", str(path)]]
        name = case.seed.name
        if name in ("chain3.json", "pair.json"):  # a cheap match and a cheap plan
            out.append(["match", str(path), str(ROOT / "plugins/freebot/configs/chain3.json")
                        if name == "chain3.json" else str(path)])
        if name in ("t.json", "probe.json"):
            out.append(["plan", "--robot", "mmrp", str(path),
                        str(ROOT / "plugins/mmrp/configs/series.json")])
        return out
    if kind == "plan" and case.mutation not in MAY_PASS:
        return [["run", "--robot", case.seed.doc["robot"], "--plan", str(path), "--no-log",
                 "--out",
                 str(path.with_name(path.name + ".run"))]]
    if kind == "library":
        out = [["library", "show", str(path)]]
        if case.seed.name == "S4N5.json" and hash(case.mutation) % 3 == 0:
            out.append(["library", "retrieve", str(path), "--from",
                        str(_configuration_path("S4N5-1.2")), "--to", "S4N5-1.3"])
        return out
    return []


def run_command(case: Case, path: Path, args: list[str], runner: CliRunner) -> Outcome:
    target = " ".join(args[:2] if args[0] == "library" else args[:1])
    result = runner.invoke(get_cli(), args)
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        text = "".join(traceback.format_exception(result.exception, limit=-3))
        return Outcome(case, target, False, "traceback: " + text)
    if args[0] == "run" and Path(args[-1]).exists():
        return Outcome(case, target, result.exit_code == 0, "a run folder for refused input"
                       if result.exit_code else "bad file accepted")
    if result.exit_code == 0:
        if args[0] in ("show", "validate") and path.name not in result.output:
            return Outcome(case, target, True, "the file name was not printed literally")
        accepted = None if case.mutation in MAY_PASS else "bad file accepted"
        return Outcome(case, target, True, accepted)
    errors = result.stderr if args[0] != "validate" else result.stderr
    bad = _check_message(errors, path)
    if result.exit_code not in (1, 2):
        bad = f"exit status {result.exit_code}"
    return Outcome(case, target, False, bad and f"message {bad}: {errors.strip()[:400]}")


def campaign(count: int, seed: int, folder: Path, *, command_every: int = 1
             ) -> list[Outcome]:
    """Make ``count`` cases and feed each to its reader, and every ``command_every``-th
    case also to its commands."""
    runner = CliRunner()
    outcomes = []
    for index, case in enumerate(cases(count, seed)):
        path = write(case, folder, index)
        outcomes.append(read(case, path))
        if index % command_every == 0:
            outcomes += [run_command(case, path, args, runner) for args in _commands(case, path)]
    return outcomes


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    print(f"seed {args.seed}, {args.cases} cases")
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        outcomes = campaign(args.cases, args.seed, Path(tmp))
    elapsed = time.perf_counter() - started
    problems = [o for o in outcomes if o.problem]
    kinds = Counter(o.problem.split(":")[0] for o in problems)
    print(f"{len(outcomes)} runs in {elapsed:.1f} s; accepted {sum(o.ok for o in outcomes)}, "
          f"refused {sum(not o.ok for o in outcomes)}; problems: {dict(kinds) or 'none'}")
    for outcome in problems[:40]:
        print(f"- {outcome.case.label} -> {outcome.target}: {outcome.problem[:600]}")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
