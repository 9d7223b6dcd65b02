"""The human example's floor steps planned kinematically, step after step (issue 28).

Luo and Lam's human example (six chains of 568 FreeBOTs into a human figure) is planned
with ``miso``; then every step that docks a module over the floor is planned as the
controller would plan it -- a lone module's way (``travel.floor_path``), a piece's way
(``piece_way.piece_way``: its goal place, or the free place nearest to it) -- on the
centres the previous steps left, each piece put where its way ends, docked (no physics:
what the ways need, not what the MuJoCo run does). A piece docked at a free place is then
swung rigidly about its target until its root is at its goal place, when that is within
20 deg and no shell comes within a centimetre of overlapping on the way (as the action's
last move swings a latched piece onto its goal); a piece at its goal place is moved into
the goal's shape when no shell comes within a centimetre of overlapping on the way (as the
action's last move bends a docked piece to the action's goal: a straight piece whose goal
is bent docks straight out through its root's goal place).
Prints the seed and, per step, the piece's size, where it docks (its goal place, or a
free place, swung or not), its legs, the travel of its farthest
module beside the straight distance its centroid covers on the way, and the time the way takes at
the piece speed; stops at the first step whose way cannot be planned and says why.

``--start`` takes another start file of the same modules (one whose module positions lay
the chains elsewhere, as a lab would). ``--save DIR`` writes the state after every action
(``after-NN.json``: the seed, the start file, the actions done, every module's centre,
the rows so far; written whole, then renamed into place); ``--resume`` continues from such
a file, or from the newest in a directory (the plan is made again: the same seed and start
give the same plan).

Usage: ``python benchmarks/human_floor.py [--seed 0] [--steps 47] [--start FILE]
[--save DIR] [--resume DIR|FILE]``.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import click
import networkx as nx
import numpy as np
from scipy.spatial import cKDTree

from msrr.core.alignment import rot_z, wrap_angle
from msrr.core.console import console, table
from msrr.core.errors import ExecutionError
from msrr.core.io import load_configuration

ROOT = Path(__file__).resolve().parents[1]
HUMAN = ROOT / "plugins" / "freebot" / "configs" / "human"
SPEED = 0.02   # a piece's fastest centre [m/s] (0.8 x max_speed x radius)
SWING = np.radians(20.0)   # a latched piece is swung rigidly onto its goal within this [rad]
BENT = 0.01    # a piece at its goal place moved farther than this [m] to take the goal's
#                shape is said to be bent (less: the way's end within its tolerance)


def _groups(config) -> dict[str, set[str]]:
    graph = nx.Graph()
    graph.add_nodes_from(config.modules())
    graph.add_edges_from((e.source, e.target) for e in config.edges())
    return {m: c for c in nx.connected_components(graph) for m in c}


def _goal_centres(config, spacing: float) -> dict[str, np.ndarray]:
    from msrr.core.freeform.travel import lay_out_pieces

    adjacent: dict[str, list] = {m: [] for m in config.modules()}
    for e in config.edges():
        z = np.asarray(e.z, dtype=float)
        adjacent[e.source].append((e.target, z))
        adjacent[e.target].append((e.source, -z))
    return {m: p for piece in lay_out_pieces(adjacent, sorted(adjacent), spacing)
            for m, p in piece.items()}


def _save(folder: Path, state: dict) -> None:
    """Write ``state`` to ``folder/after-NN.json`` (NN: the actions done), whole or not at
    all: to a temporary file first, then renamed over."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"after-{state['done']:02d}.json"
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(state))
    os.replace(tmp, path)


def _load(path: Path) -> dict:
    """The state saved by :func:`_save` in file ``path``, or the newest in folder ``path``."""
    if path.is_dir():
        saved = sorted(path.glob("after-*.json"))
        if not saved:
            raise click.BadParameter(f"no after-NN.json in {path}")
        path = saved[-1]
    try:
        state = json.loads(path.read_text())
        _ = (state["seed"], state["start"], state["done"], state["rows"], state["pos"])
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise click.BadParameter(f"{path}: not a saved state ({error})") from None
    return state


def _swing(pos, piece: set[str], root: str, target: str, arm: np.ndarray,
           spacing: float) -> float | None:
    """Swing ``piece`` (docked by ``root`` on ``target`` at a free place) rigidly about the
    target until its root lies along ``arm`` (2,) from it, as the action's last move swings
    a latched piece within ``SWING`` of its goal (``recognition._LATCH_HOLD``), if no
    shell comes within a centimetre of overlapping another's on the way (``pos`` moved in
    place); the angle [rad] it swung, or ``None``."""
    ms = sorted(piece)
    centre = pos[target]
    now = np.array([pos[m] for m in ms]) - centre
    r = now[ms.index(root)]
    angle = wrap_angle(float(np.arctan2(arm[1], arm[0]) - np.arctan2(r[1], r[0])))
    if abs(angle) > SWING:
        return None
    others = np.array([p for m, p in pos.items() if m not in piece])
    tree = cKDTree(others)
    for t in np.linspace(0.0, 1.0, max(2, int(np.degrees(abs(angle)) * 2) + 1))[1:]:
        at = centre + now @ rot_z(t * angle)[:2, :2].T
        dist, _ = tree.query(at, k=1)
        if np.any(dist < spacing - 0.01):
            return None
    for m, p in zip(ms, at, strict=True):
        pos[m] = p
    return angle


def _step(k, action, current, pos, spacing) -> list[str] | None:
    """Plan step ``k``'s floor docks on ``pos`` (moved in place); a table row, or
    ``None`` when the action docks nothing over the floor."""
    from msrr.core.freeform.piece_way import piece_way
    from msrr.core.freeform.travel import floor_path, piece_goal

    after = current.copy()
    for c in action.changes:
        for e in list(after.edges()):
            if (e.source, e.target) == (c.source, c.target):
                after.disconnect(e.id)
    groups = _groups(after)
    made = [c for c in action.changes if any((e.source, e.target) == (c.source, c.target)
                                             for e in action.target.edges())]
    for c in made:
        if groups[c.source] == groups[c.target]:
            continue
        piece, t0 = groups[c.source], time.perf_counter()
        before = np.mean([pos[m] for m in piece], axis=0)
        if len(piece) == 1:
            others = {m: np.append(p - pos[c.source], 0.0) for m, p in pos.items()
                      if m != c.source}
            way = floor_path(others, c.target, spacing)
            pos[c.source] = pos[c.source] + way[-1]
            length = float(np.sum(np.linalg.norm(np.diff([np.zeros(2), *way], axis=0),
                                                 axis=1)))
            return [str(k), f"{c.source} -> {c.target}", "1", "nearest free spot", "-",
                    f"{length:.2f}", f"{np.linalg.norm(way[-1]):.2f}", f"{length / 0.04:.0f}",
                    f"{time.perf_counter() - t0:.1f}"]
        goal = _goal_centres(action.target, spacing)
        way = piece_way(pos, piece, groups[c.target], c.source, 0.0, c.target, goal, spacing)
        end = way.legs[-1].to + 0.02 * way.push
        for m, p in zip(way.piece, end + way.shape @ rot_z(way.legs[-1].heading)[:2, :2].T,
                        strict=True):
            pos[m] = p
        moved = float(np.linalg.norm(np.mean([pos[m] for m in piece], axis=0) - before))
        where = "goal place"
        then = piece_goal(goal, {m: pos[m] for m in groups[c.target] | piece}, piece,
                          c.target)
        if way.at_goal:
            bent = _bend(pos, piece, then, spacing)
            if bent is None:
                where = "goal place, not bent to the goal's shape"
            elif bent > BENT:
                where = f"goal place, bent {bent:.2f} m onto the goal's shape"
        else:
            swung = _swing(pos, piece, c.source, c.target, then[c.source] - pos[c.target],
                           spacing)
            where = "free place, not the goal's" if swung is None else \
                f"free place, swung {np.degrees(swung):+.0f} deg onto the goal's"
        reach = float(np.max(np.linalg.norm(way.shape, axis=1)))
        travel = sum(float(np.linalg.norm(b.to - a)) + reach * abs(float(np.angle(np.exp(
            1j * (b.heading - h))))) for (a, h), b in zip(
            [(way.origin, way.heading)] + [(x.to, x.heading) for x in way.legs[:-1]],
            way.legs, strict=True))
        return [str(k), f"{c.source} -> {c.target}", str(len(piece)),
                where,
                str(len(way.legs)), f"{travel:.2f}",
                f"{moved:.2f}",
                f"{travel / SPEED:.0f}",
                f"{time.perf_counter() - t0:.1f}"]
    return None


def _bend(pos, piece: set[str], then: dict[str, np.ndarray], spacing: float) -> float | None:
    """Move ``piece`` (docked at its goal place in the shape its way left) into the goal's
    shape ``then`` (centres (2,)), as the action's last move bends a docked piece to the
    action's goal, if no shell comes within a centimetre of overlapping another's on the
    way, each module on the straight line from where it is (``pos`` moved in place); the
    farthest a module moved [m], or ``None``."""
    ms = sorted(piece)
    now = np.array([pos[m] for m in ms])
    goal = np.array([then[m][:2] for m in ms])
    far = float(np.max(np.linalg.norm(goal - now, axis=1)))
    others = np.array([p for m, p in pos.items() if m not in piece])
    tree = cKDTree(others)
    for t in np.linspace(0.0, 1.0, max(2, int(np.ceil(far / 0.005)) + 1))[1:]:
        dist, _ = tree.query(now + t * (goal - now), k=1)
        if np.any(dist < spacing - 0.01):
            return None
    for m, p in zip(ms, goal, strict=True):
        pos[m] = p
    return far


@click.command()
@click.option("--seed", default=0, show_default=True)
@click.option("--steps", default=47, show_default=True, help="plan this many actions")
@click.option("--start", "start_file", type=click.Path(exists=True, dir_okay=False,
                                                       path_type=Path),
              default=HUMAN / "human-chains.json", show_default=True,
              help="the start file (the same modules, any layout)")
@click.option("--save", type=click.Path(file_okay=False, path_type=Path),
              help="write the state after each action here")
@click.option("--resume", type=click.Path(exists=True, path_type=Path),
              help="continue from a saved state (a file, or the newest in a folder)")
def main(seed: int, steps: int, start_file: Path, save: Path | None,
         resume: Path | None) -> None:
    from msrr.core import plugins
    from msrr.core.freeform.world import place

    start = load_configuration(start_file)
    goal = load_configuration(HUMAN / "human.json")
    plan = plugins.planners.get("freebot", "miso").plan(start, goal, seed=seed)
    spacing = 0.101
    centres, _ = place(start, spacing, 0.05)
    pos = {m: c[:2].copy() for m, c in centres.items()}
    console.print(f"seed {seed}; {len(plan.actions)} actions, "
                  f"{plan.stats['changes']:.0f} changes (IM, published: 91)")
    rows, current, why, done = [], start, "", 0
    if resume:
        state = _load(resume)
        if (state["seed"], state["start"]) != (seed, start_file.name):
            raise click.BadParameter(f"{resume} was saved for seed {state['seed']} and "
                                     f"start {state['start']}")
        done, rows = state["done"], state["rows"]
        pos = {m: np.array(p) for m, p in state["pos"].items()}
        current = plan.actions[done - 1].target if done else start
        console.print(f"resumed after action {done} ({resume})")
    for k, action in enumerate(plan.actions[done:steps], done + 1):
        try:
            row = _step(k, action, current, pos, spacing)
        except ExecutionError as error:
            why = f"action {k}: {error}"
            break
        if row:
            rows.append(row)
            console.print(" | ".join(row))
        current = action.target
        if save:
            _save(save, {"seed": seed, "start": start_file.name, "done": k, "rows": rows,
                         "pos": {m: p.tolist() for m, p in pos.items()}})
    console.print(table("the human example's floor steps, planned kinematically",
                        ["action", "dock", "modules", "where", "legs", "travel [m]",
                         "straight [m]", "at 0.02 m/s [s]", "planning [s]"], rows))
    console.print(why or f"all {min(steps, len(plan.actions))} actions planned")


if __name__ == "__main__":
    main()
