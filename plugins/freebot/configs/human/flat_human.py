"""The human example's goal laid flat on the floor: writes ``human.json`` (issue 28).

Luo and Lam's human figure (2023, section VI.B) is one tree of 568 FreeBOTs: a spine
F1..F18 carrying two ribs on each module, four of them (on F6 and F7) forking into two
chains of 15 and 16, and two arms on F18 with four chains of 18 each. Only the tree
(each module's parent, read from ``human.json``) is the paper's; the vectors are ours.
The earlier grid layout stood 93 modules in columns above the floor, which no piece
rolling on the floor builds. This one lays every module on the floor, each chain straight
(so a straight piece docks in its goal's shape), at angles of a hexagonal lattice where
chains run side by side (neighbouring centres one spacing apart, not closer):

- the spine along ``x``; a spine module's smaller rib to ``-y``, its larger to ``+y``, at
  120 deg from ``x`` on F1..F5, 90 deg on F6 and F7, 60 deg on F8..F17, so the fans
  open a wedge on either side of F6 and F7;
- a rib that forks continues straight with its larger chain; the other chain leaves 60
  deg off it into the wedge beside (F6's outward, F7's outward: 150 and 30 deg);
- F18's arm of F487 continues the spine, its four side chains (and its tip, F495..F496)
  at -60 deg; the arm of F406 at 60 deg, its four side chains along ``x``.

A FreeBOT connects anywhere on another module's sphere, so any direction in the plane is
one it can hold; every module carries at most 3 (``max_in``: 6). :func:`problems` checks
the layout: on the floor, every connection one spacing long, no two other centres closer
than one spacing (shells touch their parent and children only).

Usage: ``python plugins/freebot/configs/human/flat_human.py [--check]`` (``--check``:
exit 1 if ``human.json`` is not what this writes).
"""

from __future__ import annotations

import json
import math
import sys
from collections import deque
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

HERE = Path(__file__).resolve().parent
GOAL = HERE / "human.json"
SPACING = 0.101          # centre distance of two docked FreeBOTs [m] (world spacing)
SPINE = [f"F{k}" for k in range(1, 19)]
DESCRIPTION = (
    "Luo and Lam's human example (2023, section VI.B), goal: one tree of 568 FreeBOTs "
    "(the chain F1..F568 with 52 modules moved), a human figure; laid flat by "
    "flat_human.py (the tree is the paper's, the vectors ours): every module on the "
    "floor, every chain straight, ribs at 120, 90 and 60 deg from the spine")
ARMS = {"F487": 0.0, "F406": 60.0}                       # F18's two arms [deg]
SIDE_CHAINS = {"F497": -60.0, "F515": -60.0, "F533": -60.0, "F495": -60.0,
               "F415": 0.0, "F433": 0.0, "F451": 0.0, "F469": 0.0}


def _rib_angle(k: int) -> float:
    """The angle [deg] from ``x`` of spine module ``F{k}``'s ribs (the ``+y`` one)."""
    return 120.0 if k <= 5 else 90.0 if k <= 7 else 60.0


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
    out["description"] = DESCRIPTION
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
    root = document["modules"][0]["id"]
    where, queue = {root: np.zeros(3)}, deque([root])
    while queue:
        u = queue.popleft()
        for v, z in adjacent[u]:
            if v not in where:
                where[v] = where[u] + spacing * z
                queue.append(v)
    return where


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


def main(argv: list[str]) -> int:
    """Write ``human.json`` laid flat, or with ``--check`` compare it."""
    document = flat(json.loads(GOAL.read_text()))
    bad = problems(document)
    if bad:
        print("\n".join(bad[:20]), file=sys.stderr)
        return 1
    if "--check" in argv:
        return 0 if GOAL.read_text() == text(document) else 1
    GOAL.write_text(text(document))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
