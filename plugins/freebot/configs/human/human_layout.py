"""The human example laid on the floor (issue 28): writes its flat goal ``human.json``
and a start laid near it, ``human-chains-near.json``.

**The goal.** Luo and Lam's human figure (2023, section VI.B) is one tree of 568
FreeBOTs: a spine F1..F18 carrying two ribs on each module, four of them (on F6 and F7)
forking into two chains of 15 and 16, and two arms on F18 with four chains of 18 each.
Only the tree (each module's parent, read from ``human.json``) is the paper's; the
vectors are ours. The earlier grid layout stood 93 modules in columns above the floor,
which no piece rolling on the floor builds. This one lays every module on the floor and
every chain straight, so a straight piece docks in its goal's shape:

- the spine along ``x``; a spine module's smaller rib to ``-y``, its larger to ``+y``, at
  120 deg from ``x`` on F1, 114 on F2..F5, 95 on F6, 85 on F7, 66 on F8..F17 (mirrored
  to ``-y``), so the ribs open a wedge on either side of F6's and F7's, and F6's and F7's
  part 10 deg: a long piece sliding in beside the other one, docked, stands clear of it;
- a rib that forks continues straight with its larger chain; the other leaves 60 deg
  off it into the wedge beside (F6's at 155 deg, F7's at 25 deg, mirrored to ``-y``);
- F18's arm of F487 continues the spine, its four side chains (and its tip, F495..F496)
  at 90 deg; the arm of F406 at -66 deg, its four side chains along ``x`` (on the side
  where the plan's pieces for them hang, split off the long pieces docked on F6 and F7).

Chains side by side lie at least 66 deg off the line of modules they leave, so their
lines are at least ``spacing * sin 66 deg`` = 0.092 m apart: a piece slides in along its
neighbour without their shells overlapping (on a hexagonal lattice, 60 deg, they would:
0.087 m; ``piece_way`` keeps 0.091 m while a piece slides in). A FreeBOT connects
anywhere on another module's sphere, so any direction in the plane is one it holds;
every module carries at most 3 (``max_in``: 6). :func:`problems` checks the layout: on
the floor, every vector a unit one, no two unconnected centres closer than one spacing
(shells touch their parent and children only).

**The start.** The six chains of ``human-chains.json`` (F1..F100, F101..F200,
F201..F300, F301..F400, F401..F500, F501..F568, each module on the one before), laid
where a lab would lay them (:data:`RUNS`): the chain F201..F300, whose first 44 modules
are the goal's spine and stay put, from the origin along ``x`` as the goal lays them,
its tail up from the arm's end and back along the top (its last two pieces go to F205's
and F208's ribs); the others beside the figure, each in straight runs
that turn only where the plan cuts the chain anyway (at the first module of a piece
that travels), so every travelling piece is straight. The long pieces of F1..F100 and
F101..F200 lie on their goal lines below F6 and F7, F26 2.1 m down (F1..F25 turns off
to the left below the room F205's lower rib needs to come in along its line) and F126
4.8 m down (F125, at the corner, lies beyond the 42-module piece's stand).

Usage: ``python plugins/freebot/configs/human/human_layout.py [--check]`` (``--check``:
exit 1 if a file is not what this writes).
"""

from __future__ import annotations

import json
import math
import sys
from collections import deque
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from msrr.core.freeform.travel import lay_out_pieces

HERE = Path(__file__).resolve().parent
GOAL = HERE / "human.json"
SPACING = 0.101          # centre distance of two docked FreeBOTs [m] (world spacing)
SPINE = [f"F{k}" for k in range(1, 19)]
GOAL_DESCRIPTION = (
    "Luo and Lam's human example (2023, section VI.B), goal: one tree of 568 FreeBOTs "
    "(the chain F1..F568 with 52 modules moved), a human figure; laid flat by "
    "human_layout.py (the tree is the paper's, the vectors ours): every module on the "
    "floor, every chain straight, ribs at 114, 95, 85 and 66 deg from the spine")
ARMS = {"F487": 0.0, "F406": -66.0}                       # F18's two arms [deg]
SIDE_CHAINS = {"F497": 90.0, "F515": 90.0, "F533": 90.0, "F495": 90.0,
               "F415": 0.0, "F433": 0.0, "F451": 0.0, "F469": 0.0}


def _rib_angle(k: int) -> float:
    """The angle [deg] from ``x`` of spine module ``F{k}``'s ribs (the ``+y`` one)."""
    return {1: 120.0, 6: 95.0, 7: 85.0}.get(k, 114.0 if k <= 5 else 66.0)


def _size(children: dict[str, list[str]], m: str) -> int:
    """The number of modules in ``m``'s subtree."""
    return 1 + sum(_size(children, c) for c in children.get(m, []))


def headings(parent: dict[str, str]) -> dict[str, float]:
    """Each non-root module's direction [deg] from its parent, in the floor plane."""
    children: dict[str, list[str]] = {}
    for m, p in sorted(parent.items(), key=lambda i: int(i[0][1:])):
        children.setdefault(p, []).append(m)
    angle: dict[str, float] = {}
    for k, m in enumerate(SPINE, 1):
        ribs = [] if m == SPINE[-1] else [c for c in children.get(m, []) if c not in SPINE]
        for sign, rib in zip((-1.0, 1.0), sorted(ribs, key=lambda c: _size(children, c)),
                             strict=False):
            angle[rib] = sign * _rib_angle(k)
        if k < len(SPINE):
            angle[SPINE[k]] = 0.0
    angle.update(ARMS)
    angle.update(SIDE_CHAINS)
    queue = deque(SPINE[:1])
    while queue:
        m = queue.popleft()
        kids = children.get(m, [])
        if len(kids) == 2 and m in angle and all(c not in angle for c in kids):
            big, small = sorted(kids, key=lambda c: -_size(children, c))
            outward = 1.0 if _fork_on(m, parent) == "F6" else -1.0
            angle[big] = angle[m]
            angle[small] = angle[m] + outward * math.copysign(60.0, angle[m])
        for c in kids:
            if c not in angle:
                angle[c] = angle[m]
            queue.append(c)
    return angle


def _fork_on(m: str, parent: dict[str, str]) -> str:
    """The spine module whose rib holds ``m``."""
    while parent[m] not in SPINE:
        m = parent[m]
    return parent[m]


def _unit(deg: float) -> list[float]:
    """The unit vector (3,) at ``deg`` from ``x`` in the floor plane, rounded."""
    a = math.radians(deg)
    return [round(math.cos(a), 12) + 0.0, round(math.sin(a), 12) + 0.0, 0.0]


def flat(document: dict) -> dict:
    """``document`` (a ``human.json``) with every connection's ``z`` laid flat (the
    same sources and targets, in the same order) and this layout's description."""
    parent = {c["source"]: c["target"] for c in document["connections"]}
    angle = headings(parent)
    out = dict(document)
    out["description"] = GOAL_DESCRIPTION
    out["connections"] = [{**c, "z": [-v + 0.0 for v in _unit(angle[c["source"]])]}
                          for c in document["connections"]]
    return out


def centres(document: dict, spacing: float = SPACING) -> dict[str, np.ndarray]:
    """Every module's centre (3,) [m] relative to the root, from the vectors (a
    connection ``i -> j`` puts ``j`` at ``p_i + spacing z``)."""
    adjacent: dict[str, list[tuple[str, np.ndarray]]] = {m["id"]: [] for m in document["modules"]}
    for c in document["connections"]:
        z = np.asarray(c["z"], dtype=float)
        adjacent[c["source"]].append((c["target"], z))
        adjacent[c["target"]].append((c["source"], -z))
    return lay_out_pieces(adjacent, [document["modules"][0]["id"]], spacing)[0]


def problems(document: dict, spacing: float = SPACING) -> list[str]:
    """What keeps ``document``'s layout from lying flat: a module off the floor, a
    connection not one ``spacing`` long, two unconnected centres closer than
    ``spacing`` (less 1e-6 m), a module reached twice; empty when it is valid."""
    where = centres(document, spacing)
    found = [f"{m} is {p[2]:+.3f} m above the root" for m, p in where.items()
             if abs(p[2]) > 1e-9]
    if len(where) != len(document["modules"]):
        found.append(f"{len(document['modules']) - len(where)} modules not reached")
    links = {frozenset((c["source"], c["target"])) for c in document["connections"]}
    for c in document["connections"]:
        if abs(float(np.linalg.norm(c["z"])) - 1.0) > 1e-9:
            found.append(f"{c['source']} -> {c['target']}: z is not a unit vector")
    names = sorted(where)
    tree = cKDTree(np.array([where[m] for m in names]))
    for a, b in sorted(tree.query_pairs(spacing - 1e-6)):
        if frozenset((names[a], names[b])) not in links:
            gap = float(np.linalg.norm(where[names[a]] - where[names[b]]))
            found.append(f"{names[a]} and {names[b]} are {gap:.3f} m apart, not connected")
    return found


def text(document: dict) -> str:
    """The file's text (the configs' format: one-space indent, no final newline)."""
    return json.dumps(document, indent=1)


CHAINS = HERE / "human-chains.json"
START = HERE / "human-chains-near.json"
RADIUS = 0.05            # a FreeBOT's shell [m]
START_DESCRIPTION = (
    "Luo and Lam's human example (2023, section VI.B), start: 568 FreeBOTs in six "
    "chains of 100, 100, 100, 100, 100 and 68, each module on the one before; laid by "
    "human_layout.py near the flat goal: the chain F201..F300 from the origin along x, the "
    "others in straight runs beside the figure, turning only where the plan cuts them")
# Each chain: its first module's place (x, y) [m] and its runs, (first module, heading
# [deg] from x of the run's growth, module to module).
RUNS: dict[str, tuple[tuple[float, float], list[tuple[str, float]]]] = {
    "F201": ((0.0, 0.0), [("F201", 0.0), ("F245", 90.0), ("F281", 180.0)]),
    "F501": ((-1.0, 6.3), [("F501", -90.0)]),
    "F401": ((1.3, -3.82), [("F401", 90.0), ("F420", 0.0), ("F421", -90.0), ("F429", 0.0), ("F430", 90.0), ("F438", 0.0), ("F439", -90.0), ("F447", 0.0), ("F448", 90.0), ("F456", 0.0), ("F457", -90.0), ("F465", 0.0), ("F466", 90.0), ("F474", 0.0), ("F475", -90.0), ("F483", 0.0), ("F484", 90.0), ("F492", 0.0), ("F493", -90.0)]),
    "F301": ((10.8, 4.3), [("F301", 180.0)]),
    "F1": ((-2.203, -2.092), [("F1", 0.0), ("F27", -95.0)]),
    "F101": ((3.553, -4.78), [("F101", 180.0), ("F127", -85.0)]),
}


def _order(document: dict, first: str) -> list[str]:
    """The chain that starts at ``first``, module after module."""
    after = {c["target"]: c["source"] for c in document["connections"]}
    chain = [first]
    while chain[-1] in after:
        chain.append(after[chain[-1]])
    return chain


def run_headings(document: dict) -> dict[str, float]:
    """Each module's run heading [deg] (:data:`RUNS`)."""
    heading: dict[str, float] = {}
    for first, (_, runs) in RUNS.items():
        turns, angle = dict(runs), 0.0
        for m in _order(document, first):
            angle = turns.get(m, angle)
            heading[m] = angle
    return heading


def start_centres(document: dict) -> dict[str, tuple[float, float]]:
    """Every module's centre (x, y) [m] as laid (:data:`RUNS`)."""
    heading, where = run_headings(document), {}
    for first, ((x, y), _) in RUNS.items():
        for m in _order(document, first):
            if m != first:
                a = math.radians(heading[m])
                x, y = x + SPACING * math.cos(a), y + SPACING * math.sin(a)
            where[m] = (x, y)
    return where


def overlaps(document: dict) -> list[str]:
    """Pairs of modules not connected whose shells come closer than one spacing."""
    where = start_centres(document)
    names = sorted(where)
    links = {frozenset((c["source"], c["target"])) for c in document["connections"]}
    tree = cKDTree(np.array([where[m] for m in names]))
    return [f"{names[a]} and {names[b]}" for a, b in sorted(tree.query_pairs(SPACING - 1e-6))
            if frozenset((names[a], names[b])) not in links]


def lay(document: dict) -> dict:
    """``document`` (the six chains) with each connection's ``z`` along its run and
    each chain's first module at its place (:data:`RUNS`)."""
    heading = run_headings(document)
    out = dict(document)
    out["name"] = "human-chains-near"
    out["description"] = START_DESCRIPTION
    places = {first: at for first, (at, _) in RUNS.items()}
    out["modules"] = [{**m, "position": [*places[m["id"]], RADIUS]} if m["id"] in places
                      else {k: v for k, v in m.items() if k != "position"}
                      for m in document["modules"]]
    out["connections"] = [{**c, "z": _back(heading[c["source"]])}
                          for c in document["connections"]]
    return out


def _back(deg: float) -> list[float]:
    """The unit vector (3,) from a module back to the one before it, for a run growing
    at ``deg`` from ``x``."""
    a = math.radians(deg)
    return [-round(math.cos(a), 12) + 0.0, -round(math.sin(a), 12) + 0.0, 0.0]


def main(argv: list[str]) -> int:
    """Write ``human.json`` and ``human-chains-near.json``, or with ``--check`` compare
    them."""
    goal = flat(json.loads(GOAL.read_text()))
    start = lay(json.loads(CHAINS.read_text()))
    bad = problems(goal) + [f"start: {p} overlap" for p in overlaps(start)]
    if bad:
        print("\n".join(bad[:20]), file=sys.stderr)
        return 1
    files = {GOAL: text(goal), START: text(start)}
    if "--check" in argv:
        return 0 if all(path.read_text() == t for path, t in files.items()) else 1
    for path, t in files.items():
        path.write_text(t)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
