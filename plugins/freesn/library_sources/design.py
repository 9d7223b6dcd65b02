"""Design of the shipped FreeSN library sources (FreeSN paper, sections 6-7, Figs. 14-22).

This script plays the part of the paper's library design tool (Fig. 13(a)): it lays
out node positions [m] for every designed and recorded configuration, derives each
strut's unit connection vector ``z`` from them (free struts get a designed
direction), and writes the source files that ``platform library build`` turns
into the shipped libraries::

    python plugins/freesn/library_sources/design.py        # rewrite the sources
    platform library build plugins/freesn/library_sources/S6N3/*.json \
        -o plugins/freesn/libraries/S6N3.json              # and so on per sub-library

Geometry (strut length, wheel radius) is the FreeSN robot spec's
(``msrr.plugins.freesn.robot``); every closed loop therefore closes
geometrically. Sequences record the intermediate configurations at topology
changes (section 6.2): the system first reaches ``S_conn`` (the free connector
pointing at the node it docks to) and then connects with unchanged vectors; a
disconnection keeps the vectors and the following moving step swings the strut.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from msrr.plugins.freesn.robot import NODE, STRUT

L = STRUT.geometry["length"]               # strut length, node centre to node centre [m]
R_WHEEL = STRUT.geometry["wheel_radius"]   # connector wheel radius [m]
UP = np.array([0.0, 0.0, 1.0])
HERE = Path(__file__).parent


def unit(v) -> list[float]:
    v = np.asarray(v, dtype=float)
    return [round(float(c), 12) for c in v / np.linalg.norm(v)]


def horizontal(angle: float, down: float = 0.0) -> np.ndarray:
    """A direction at azimuth ``angle`` [rad], tilted ``down`` [rad] below the horizon."""
    return np.array([math.cos(angle) * math.cos(down), math.sin(angle) * math.cos(down),
                     -math.sin(down)])


def configuration(name: str, nodes: dict[str, np.ndarray], struts: list[tuple],
                  description: str = "") -> dict:
    """A configuration file model.

    Args:
        nodes: node id -> centre position [m].
        struts: ``(id, source node, target node)`` for docked struts (z from positions)
            or ``(id, source node, None, direction[, forward])`` for a strut with a free
            end (``forward``: its x vector, where the morphology matters).
    """
    modules = [{"id": n, "kind": "node", "position": [round(float(c), 12) for c in p]}
               for n, p in nodes.items()]
    connections = []
    for strut in struts:
        sid, source, target = strut[:3]
        forward = None
        if target is None:
            free = f"{sid}:b"
            modules.append({"id": free, "kind": "virtual"})
            z = unit(strut[3])
            target = free
            if len(strut) > 4:   # a designed forward vector x (morphology, Fig. 18(d))
                forward = unit(strut[4])
        else:
            z = unit(nodes[target] - nodes[source])
        connections.append({"id": sid, "kind": "strut", "source": source, "target": target,
                            "z": z, **({"x": forward} if forward is not None else {})})
    return {"schema_version": 1, "robot": "freesn", "name": name, "description": description,
            "modules": modules, "connections": connections}


def step(config: dict, tree: str | None = None) -> dict:
    return {"configuration": config} if tree is None else {"configuration": config,
                                                           "tree": tree}


def write(path: Path, data: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")


def source(library: str, description: str, **parts) -> dict:
    return {"schema_version": 1, "robot": "freesn", "library": library,
            "description": description, **parts}


def tree(name: str, joint_mode: str = "opposite_steering") -> dict:
    return {"name": name, "joint_mode": joint_mode}


# -- S6N3: triangle with three legs (Figs. 14, 15, 20) ----------------------------------


def triangle(height: float = 0.0) -> dict[str, np.ndarray]:
    r = L / math.sqrt(3.0)
    return {f"N{i + 1}": np.array([r * math.cos(a), r * math.sin(a), height])
            for i, a in enumerate(np.deg2rad([90.0, 210.0, 330.0]))}


RING = [("S1", "N1", "N2"), ("S2", "N2", "N3"), ("S3", "N3", "N1")]
LEGS = [("S4", "N1"), ("S5", "N2"), ("S6", "N3")]
CLEAR = {"S1": 150.0, "S2": 210.0}
"""Where a ring strut undocked for a leg transfer swings, in plan [deg]: S1 on N1
square to the line N1-N2 (S5's capsule sweeping round N2 onto that line then passes
its body 20 mm clear), S2 on N2 outward, where its leg S5 was."""


def leg_forward(u: np.ndarray) -> np.ndarray:
    """A free leg's forward vector ``x`` with its connector's wheel axle (its ``y``)
    perpendicular to world ``x``: on the floor its wheels roll along
    ``x`` (Fig. 18(d)-(f), the locomotion tests' tripod)."""
    axle = np.cross([1.0, 0.0, 0.0], u)
    return np.cross(axle / np.linalg.norm(axle), u)


def s6n3_state(name: str, docked: dict[str, str] | None = None,
               free: dict[str, str | float] | None = None, *, standing: bool = False,
               description: str = "") -> dict:
    """Triangle N1 N2 N3 (ring struts S1-S3) with legs S4-S6 on N1-N3, changed by
    ``docked`` and ``free``.

    ``docked``: leg -> the node its free end docks to (a leg transferred into the
    ring). ``free``: strut -> what its free end does: a node name, aimed at it
    (``S_conn``, or the vectors a disconnection keeps), or an azimuth [deg] in plan
    along the floor; a ring strut in ``free`` is undocked at its target end. Legs
    otherwise point outward, down to the floor when ``standing``, their wheel axles
    perpendicular to ``x`` (:func:`leg_forward`). Every pair of struts at a node stays
    at least 60 deg apart (their capsules touch under 31.8 deg).
    """
    docked, free = docked or {}, free or {}
    nodes = triangle(height=L * 0.7 if standing else 0.0)
    struts: list[tuple] = []
    for sid, at, to in [*RING, *((leg, at, docked.get(leg)) for leg, at in LEGS)]:
        aim = free.get(sid)
        if to is not None and aim is None:
            struts.append((sid, at, to))
        elif isinstance(aim, str):
            struts.append((sid, at, None, nodes[aim] - nodes[at]))
        else:
            out = math.atan2(nodes[at][1], nodes[at][0]) if aim is None else math.radians(aim)
            u = horizontal(out, math.radians(45 if standing else 0))
            struts.append((sid, at, None, u, leg_forward(u)))
    return configuration(name, nodes, struts, description)


def s6n3() -> None:
    """S6N3 (Figs. 14, 15, 20): four groups, Fig. 20(a) to (d) and back by one leg
    transfer and one opening.

    Every strut docked at both ends joins two nodes ``L`` apart along the line through
    their centres, so three nodes hold at most three such struts (a fourth would
    coincide with one of them); the other struts are legs. Fig. 20(a)-(d): S1 undocks
    from N2 (it becomes N1's second leg) and swings clear, N2's leg S5 docks to N1 in
    its place (the triangle closed again with N1 holding two legs and N2 none), and S2
    undocks from N3 and swings out: Fig. 20(d) is the chain N2-N1-N3 with two legs on
    its middle node and one on each end. Fig. 20(e)-(h) reverses it.
    """
    out = HERE / "S6N3"
    a = s6n3_state("fig20a", standing=True,
                   description="Fig. 20(a): triangle standing on three legs")
    flat = s6n3_state("flat", description="triangle lying flat, legs outward")
    free_s1 = s6n3_state("free-S1", free={"S1": "N2"},
                         description="S1 undocked from N2, aimed at it: a chain N2-N3-N1")
    clear_s1 = s6n3_state("clear-S1", free={"S1": CLEAR["S1"]},
                          description="S1 swung clear: N1's second leg")
    aim_s5 = s6n3_state("aim-S5", free={"S1": CLEAR["S1"], "S5": "N1"},
                        description="N2's leg S5 aimed at N1")
    fig20c = s6n3_state("fig20c", docked={"S5": "N1"}, free={"S1": CLEAR["S1"]},
                        description="S5 docked to N1: the triangle closed with two legs "
                        "on N1, none on N2")
    free_s2 = s6n3_state("free-S2", docked={"S5": "N1"}, free={"S1": CLEAR["S1"], "S2": "N3"},
                         description="S2 undocked from N3, aimed at it")
    fig20d = s6n3_state("fig20d", docked={"S5": "N1"},
                        free={"S1": CLEAR["S1"], "S2": CLEAR["S2"]},
                        description="Fig. 20(d): the chain N2-N1-N3, two legs on N1, one "
                        "on each end")
    groups = [
        {"name": "triangle-three-legs", "description": "Fig. 14(a) group 1: a triangle, one "
         "free leg per node", "reference": a, "trees": [tree("K1")]},
        {"name": "open-triangle", "description": "group 2: S1 undocked from N2, a chain of "
         "three nodes with two legs on an end node", "reference": free_s1,
         "trees": [tree("K1")]},
        {"name": "leg-transferred", "description": "group 3: the triangle closed by N2's leg, "
         "two legs on N1, one on N3", "reference": fig20c, "trees": [tree("K1")]},
        {"name": "chain-four-legs", "description": "group 4: the chain N2-N1-N3, two legs on "
         "its middle node (Fig. 20(d))", "reference": fig20d, "trees": [tree("K1")]},
    ]
    write(out / "designs.json", source("S6N3", "FreeSN sub-library S6N3 (paper Figs. 14, 15, "
                                       "20): six struts, three nodes", groups=groups))
    forward = [a, flat, free_s1, clear_s1, aim_s5, fig20c, free_s2, fig20d]
    back = [fig20d, s6n3_state("aim-S2", docked={"S5": "N1"},
                               free={"S1": CLEAR["S1"], "S2": "N3"}),
            s6n3_state("dock-S2", docked={"S5": "N1"}, free={"S1": CLEAR["S1"]}),
            s6n3_state("free-S5", free={"S1": CLEAR["S1"], "S5": "N1"}),
            s6n3_state("out-S5", free={"S1": CLEAR["S1"]}),
            s6n3_state("aim-S1", free={"S1": "N2"}), flat, a]
    sequences = [
        {"name": "fig20-a-to-d", "description": "Fig. 20(a)-(d): open the triangle at N2, "
         "transfer N2's leg into it, open it at N3",
         "steps": [step(c) for c in forward]},
        {"name": "fig20-d-to-h", "description": "Fig. 20(d)-(h): the same reversed",
         "steps": [step(c) for c in back]},
    ]
    # wheeled move standing on the legs' free connector wheels (all rolling along x)
    behaviors = [{
        "name": "wheeled-move", "start": "fig20a",
        "description": "Fig. 15: system speed [m/s] and yaw rate [rad/s] to the wheel speeds "
        "[rad/s] of the three legs' free connectors, standing on them",
        "parameters": ["speed", "yaw_rate"],
        "commands": leg_wheel_commands(triangle(height=L * 0.7)),
    }]
    write(out / "sequences.json", source("S6N3", "recorded sequences of S6N3",
                                         sequences=sequences, behaviors=behaviors))


def leg_wheel_commands(nodes: dict[str, np.ndarray]) -> list[dict]:
    """Gains of the legs' free connector wheels, axles perpendicular to ``x``
    (:func:`leg_forward`): ``+w`` rolls a wheel along ``+x`` at ``w r`` (the tripod of
    the locomotion tests), so body speed ``v`` and yaw rate ``w_z`` need
    ``(v - w_z y_i) / r`` at a wheel ``y_i`` aside the centre (skid steering: the wheels
    slip sideways to turn)."""
    centre = np.mean(list(nodes.values()), axis=0)
    commands = []
    for leg, at in LEGS:
        out = math.atan2(nodes[at][1], nodes[at][0])
        contact = nodes[at] + L * horizontal(out, math.radians(45)) - centre
        commands.append({"module": leg, "command": "wheel_speed", "connector": "target",
                         "gains": {"speed": round(1.0 / R_WHEEL, 9),
                                   "yaw_rate": round(-float(contact[1]) / R_WHEEL, 9) or 0.0}})
    return commands


def star(name: str, centre_height: float, azimuths: list[float], description: str = "") -> dict:
    """Centre N0, struts S1-S4 to leaf nodes N1-N4 at the given azimuths [deg]."""
    nodes = {"N0": np.array([0.0, 0.0, centre_height])}
    horizontal_reach = math.sqrt(max(L * L - centre_height * centre_height, 0.0))
    for i, az in enumerate(azimuths):
        a = math.radians(az)
        nodes[f"N{i + 1}"] = np.array([horizontal_reach * math.cos(a),
                                       horizontal_reach * math.sin(a), 0.0])
    struts = [(f"S{i + 1}", "N0", f"N{i + 1}") for i in range(len(azimuths))]
    return configuration(name, nodes, struts, description)


def chain(name: str, hump: float, description: str = "") -> dict:
    """Nodes N1-N5, struts S1-S4 along x, the middle node N3 raised by ``hump`` [m].

    The end struts S1 and S4 are splayed :data:`CHAIN_SPLAY` in plan to either side (a
    Z, point-symmetric about N3): the contacts N1 N2 N4 N5 span an area, so the raised
    chain cannot tip, nor the flat one roll, about its line, as four collinear contacts
    let it (squirm-up then tipped over and the chain rolled sideways for metres).
    """
    rise = min(hump, L * 0.9)
    run = math.sqrt(L * L - rise * rise)
    splay = math.radians(CHAIN_SPLAY)
    side = np.array([math.cos(splay), -math.sin(splay), 0.0]) * L   # N4 -> N5
    nodes = {"N2": np.array([L, 0.0, 0.0]), "N3": np.array([L + run, 0.0, rise]),
             "N4": np.array([L + 2 * run, 0.0, 0.0])}
    nodes = {"N1": nodes["N2"] - side, **nodes, "N5": nodes["N4"] + side}
    struts = [(f"S{i + 1}", f"N{i + 1}", f"N{i + 2}") for i in range(4)]
    return configuration(name, nodes, struts, description)


def chain_tree(name: str, held: str) -> dict:
    """A chain tree whose fixed root holds strut ``held`` still (Fig. 19(a)-(e)).

    The root owns N3 and, through ``held`` (S2 or S3), its neighbour; S2 and S3 are
    otherwise opposite-steering joints. Holding one stem strut steers the squirm; the
    end leg on the held side is planted (its foot, N1 or N5, grips) and the other
    swings (its foot rolls), so the held half stands still while the other half is
    drawn in (squirm-up, front held) or pushed out (squirm-down, rear held).
    """
    neighbour = {"S2": "N2", "S3": "N4"}[held]
    planted = {"S2": "S1", "S3": "S4"}[held]
    joints = [("S2", "N2"), ("S3", "N4"), ("S1", "N1"), ("S4", "N5")]
    nodes = [{"type": "fixed", "edges": [held], "vertices": ["N3", neighbour]}]
    nodes += [{"type": ("planted" if e == planted else "swing") if e in ("S1", "S4")
               else "opposite_steering", "edges": [e], "vertices": [v]}
              for e, v in joints if e != held]
    return tree_file(name, chain("chain-flat", 0.0), nodes)


def tree_file(name: str, topology: dict, nodes: list[dict]) -> dict:
    """A designed kinematic tree ``name`` over ``topology`` (a configuration file)."""
    return {"name": name, "tree": {
        "schema_version": 1, "robot": "freesn", "configuration": topology["name"],
        "modules": [{"id": m["id"], "kind": m["kind"]} for m in topology["modules"]],
        "connections": [{k: c[k] for k in ("id", "source", "target", "kind")}
                        for c in topology["connections"]],
        "nodes": nodes}}


def legs_tree(name: str, topology: dict, root: list[str], legs: dict[str, str],
              planted: set[str]) -> dict:
    """A tree with a fixed root over ``root`` (vertices) and one leg joint per strut of
    ``legs`` (strut -> its foot node): ``planted`` legs grip with their feet (the foot's
    connector braked, :class:`~msrr.plugins.freesn.joints.PlantedJoint`), the others
    swing, their feet coasting so they roll (:class:`~.SwingJoint`, Fig. 19(f)-(o))."""
    nodes = [{"type": "fixed", "edges": [], "vertices": root}]
    nodes += [{"type": "planted" if s in planted else "swing", "edges": [s],
               "vertices": [foot]} for s, foot in legs.items()]
    return tree_file(name, topology, nodes)


STAR_LEGS = {"S1": "N1", "S2": "N2", "S3": "N3", "S4": "N4"}
FRONT = {"S1", "S4"}   # legs at azimuths 45 and 315 deg: the +x side, the crawl's front
REAR = {"S2", "S3"}
SQUIRM_HUMP = 0.12        # rise of the middle node in squirm-up [m]
CHAIN_SPLAY = 45.0        # plan angle of the chain's end struts off its line [deg]
CRAWL_HALF_STRIDE = 0.04  # body travel of one crawl phase [m]; a loop moves it twice that


def crawl_low(height: float, stride: float, azimuth: float = 45.0) -> dict:
    """The low stance of the S4N5 crawl: the standup star (legs at ``azimuth`` [deg] from
    +x, centre ``height`` [m] above the feet) with the centre moved ``stride`` [m] along
    +x while the two rear feet stay where they are, so every foot lies ``stride``
    further out along x and the centre lowers to keep the legs' length. From here the
    front feet staying put bring the body back to the standup shape another ``stride``
    ahead: the loop moves it ``2 stride``.
    """
    reach = math.sqrt(L * L - height * height)
    ax = reach * math.cos(math.radians(azimuth)) + stride
    ay = reach * math.sin(math.radians(azimuth))
    low = math.sqrt(L * L - ax * ax - ay * ay)
    a = math.degrees(math.atan2(ay, ax))
    return star("crawl-low", low, [a, 180.0 - a, 180.0 + a, 360.0 - a],
                f"Fig. 19(h): the body {stride:g} m ahead of the standup over the rear feet, "
                "lowered")


def s4n5() -> None:
    out = HERE / "S4N5"
    square = [45.0, 135.0, 225.0, 315.0]
    flat = star("star-flat", 0.0, square, "four struts lying flat around the centre node")
    stand_height = L * math.sin(math.radians(40))
    stand = star("standup", stand_height, square,
                 "Fig. 18(a)-(c): standing on the four leaf nodes")
    groups = [
        {"name": "star", "description": "a centre node with four struts to leaf nodes",
         "reference": flat,
         "trees": [tree("K1"), legs_tree("K-plant-front", flat, ["N0"], STAR_LEGS, FRONT),
                   legs_tree("K-plant-rear", flat, ["N0"], STAR_LEGS, REAR)]},
        {"name": "chain", "description": "five nodes in a row, squirming (Fig. 19(a)-(e))",
         "reference": chain("chain-flat", 0.0),
         "trees": [tree("K1"), chain_tree("K-hold-front", "S3"), chain_tree("K-hold-rear", "S2")]},
    ]
    write(out / "designs.json", source("S4N5", "FreeSN sub-library S4N5 (paper Figs. 18, 19): "
                                       "four struts, five nodes", groups=groups))
    low = crawl_low(stand_height, CRAWL_HALF_STRIDE)
    sequences = [
        {"name": "standup", "description": "Fig. 18(a): stand up from lying flat",
         "steps": [step(flat), step(stand)]},
        # standup -> low under K-plant-rear: the rear feet grip, the body moves forward
        # and down, the front feet roll; low -> standup (the loop back, under the first
        # step's tree) under K-plant-front: the front feet grip, the body rises forward,
        # the rear feet roll. Each phase is kinematically consistent with its planted
        # feet standing still (crawl_low), so a cycle moves the body 2 x half stride
        {"name": "crawl", "behavior": "crawl", "loop": True,
         "description": "Fig. 19(f)-(j): crawl with the four leaf struts as legs, the rear "
         "and the front pair planted in turn",
         "steps": [step(stand, "K-plant-front"), step(low, "K-plant-rear")]},
        # driven from N2, an inner node on the floor: from the raised middle node (N3) the
        # squirm crabs ~22 deg off its heading, from N4 (N2's mirror) it goes backwards
        {"name": "squirm", "behavior": "squirm", "loop": True, "drive_root": "N2",
         "description": "Fig. 19(a)-(e): squirm up and down with alternating trees",
         "steps": [step(chain("squirm-up", SQUIRM_HUMP, "middle node raised"), "K-hold-front"),
                   step(chain("squirm-down", 0.0, "flat"), "K-hold-rear")]},
    ]
    nodes = {f"N{i + 1}": np.array([L * math.cos(math.radians(a)), L * math.sin(math.radians(a)),
                                    0.0]) for i, a in enumerate(square)}
    commands = []
    for i in range(4):
        leaf = nodes[f"N{i + 1}"]
        side = 1.0 if leaf[1] > 0 else -1.0
        # the connector on the leaf node spins the node about the strut axis; a positive
        # spin rolls the node along d = u x e_z (u the leg's direction), whose x part has
        # the sign of ``side``; the body's turn (e_z x p) . d is -|p| at every diagonal leaf
        # (the yaw gain was +|p| until issue 31: the heading loop turned the wrong way)
        commands.append({"module": f"S{i + 1}", "command": "wheel_speed", "connector": "target",
                         "gains": {"speed": round(side / R_WHEEL, 9),
                                   "yaw_rate": round(-float(np.hypot(*leaf[:2])) / R_WHEEL, 9)}})
    behaviors = [{"name": "node-wheels", "start": "standup", "parameters": ["speed", "yaw_rate"],
                  "description": "Fig. 18(a)-(c): the four leaf nodes driven as wheels",
                  "commands": commands}]
    write(out / "sequences.json", source("S4N5", "recorded sequences of S4N5",
                                         sequences=sequences, behaviors=behaviors))


# -- S4N1: a node on four leaf struts, wheeled (Fig. 18(d)-(i)) --------------------------

R_STRUT = STRUT.geometry["radius"]
R_NODE = NODE.geometry["radius"]
HALF_BASE = STRUT.geometry["wheel_base"] / 2.0
SPIDER = [45.0, 135.0, 225.0, 315.0]   # leg azimuths [deg]; x is the driving direction


def spider(name: str, tilt: float, description: str = "") -> tuple[dict, list[np.ndarray]]:
    """Centre N0 with free legs S1-S4 at :data:`SPIDER`, tilted ``tilt`` [deg] below the
    horizon. The morphology the wheel behaviors assume: each leg's wheel axle (its y)
    is horizontal and tangential (counter-clockwise), so its connector wheels roll
    radially on the floor; tilting a leg in its vertical plane keeps it so, and the
    library stores skeletal vectors only, so the system is built with its legs' wheels
    facing down (x = -e_z when level). Returns the file and the leg axes."""
    axes = [horizontal(math.radians(a), math.radians(tilt)) for a in SPIDER]
    struts = []
    for i, (a, u) in enumerate(zip(SPIDER, axes, strict=True)):
        axle = np.array([-math.sin(math.radians(a)), math.cos(math.radians(a)), 0.0])
        struts.append((f"S{i + 1}", "N0", None, u, np.cross(axle, u)))
    return configuration(name, {"N0": np.zeros(3)}, struts, description), axes


def roller_commands(nodes: dict[str, np.ndarray], legs: dict[str, tuple[str, np.ndarray]]
                    ) -> list[dict]:
    """Gains of free struts rolled about their axes on the floor (Fig. 18(g)-(i)).

    As in S4N1's ``struts-as-wheels``: the docked connector turns the node about the
    strut's ``+z = u`` relative to the strut, so the strut turns about ``-u`` and, lying
    on the floor, rolls along ``d = -(u x e_z)`` at ``r_s w r / (b/2)`` per rad/s of
    ``w``. Each strut takes the part of its contact's velocity along ``d``: ``d_x`` per
    m/s of ``speed`` and ``(e_z x p_c) . d`` per rad/s of ``yaw_rate``, ``p_c`` the
    contact (the strut's far cap) about the centre.

    Args:
        legs: strut id -> (the node its docked source end holds, its direction ``u``).
    """
    rate = R_STRUT * R_WHEEL / HALF_BASE
    centre = np.mean(list(nodes.values()), axis=0)
    out = []
    for sid, (node, u) in legs.items():
        u = np.asarray(u, dtype=float) / np.linalg.norm(u)
        d = -np.cross(u, UP)
        d /= np.linalg.norm(d)
        contact = nodes[node] + (L - R_NODE - R_STRUT) * u - centre
        out.append({"module": sid, "command": "wheel_speed", "connector": "source",
                    "gains": {"speed": round(float(d[0]) / rate, 9) or 0.0,
                              "yaw_rate": round(float(np.cross(UP, contact) @ d) / rate, 9)
                              or 0.0}})
    return out


def s4n1() -> None:
    """Fig. 18(d)-(f): standing on the free connectors' wheels, driven as a differential
    drive; Fig. 18(g)-(i): legs low, their capsules on the floor, each rolled about its
    axis by the connector on N0."""
    out = HERE / "S4N1"
    flat, _ = spider("spider-flat", 0.0, "four leaf struts level around the node")
    wheels, down = spider("spider-wheels", 55.0, "Fig. 18(d): standing on the four leaf "
                          "struts' connector wheels")
    rollers, low = spider("spider-rollers", 20.0, "Fig. 18(g): the leaf struts low, lying on "
                          "the floor by their ends")
    groups = [{"name": "spider", "description": "one node with four leaf struts",
               "reference": flat, "trees": [tree("K1")]}]
    write(out / "designs.json", source("S4N1", "FreeSN sub-library S4N1 (paper Fig. 18(d)-(i)): "
                                       "four struts, one node", groups=groups))
    sequences = [
        {"name": "stand-on-wheels", "description": "Fig. 18(d): onto the connector wheels",
         "steps": [step(flat), step(wheels), step(flat)]},
        {"name": "lie-on-struts", "description": "Fig. 18(g): the struts down to the floor",
         "steps": [step(flat), step(rollers), step(flat)]},
    ]
    drive = []
    for i, az in enumerate(SPIDER):
        # free connector wheels, axle y tangential: +1 rad/s rolls the end radially
        # outward by r; the body's velocity v needs v . e_r of it, v_x cos(azimuth) +
        # v_y sin(azimuth) (the tangential part slips). Radial wheels exert no yaw
        # moment: no yaw_rate; a base that travels any way, so ``sideways``, which the
        # executor turns the travel by to hold its direction in the world (issue 31).
        a = math.radians(az)
        drive.append({"module": f"S{i + 1}", "command": "wheel_speed", "connector": "target",
                      "gains": {"speed": round(math.cos(a) / R_WHEEL, 9),
                                "sideways": round(math.sin(a) / R_WHEEL, 9)}})
    behaviors = [
        {"name": "strut-wheels", "start": "spider-wheels", "parameters": ["speed", "sideways"],
         "description": "Fig. 18(d)-(f): the leaf struts' wheels on the floor drive",
         "commands": drive},
        {"name": "struts-as-wheels", "start": "spider-rollers",
         "parameters": ["speed", "yaw_rate"],
         "description": "Fig. 18(g)-(i): the leaf struts rolled about their axes",
         "commands": roller_commands({"N0": np.zeros(3)},
                                     {f"S{i + 1}": ("N0", u) for i, u in enumerate(low)})},
    ]
    write(out / "sequences.json", source("S4N1", "recorded sequences of S4N1",
                                         sequences=sequences, behaviors=behaviors))


# -- S12N6: octahedron, hexagonal star, tree (Figs. 21, 22) -----------------------------


def octahedron_nodes() -> dict[str, np.ndarray]:
    """Antiprism layout: bottom face B1-B3 on the floor, top face T1-T3 turned by 60 deg."""
    r = L / math.sqrt(3.0)
    height = L * math.sqrt(2.0 / 3.0)
    nodes = {}
    for i in range(3):
        a = math.radians(90 + 120 * i)
        nodes[f"B{i + 1}"] = np.array([r * math.cos(a), r * math.sin(a), 0.0])
        a = math.radians(30 + 120 * i)
        nodes[f"T{i + 1}"] = np.array([r * math.cos(a), r * math.sin(a), height])
    return nodes


# The Hamiltonian zig-zag cycle of the antiprism's side edges, T1-B1-T2-B2-T3-B3 (azimuths 30,
# 90, 150, 210, 270, 330 deg: each top node to its two *neighbouring* bottom nodes, struts of
# length L), plays the hexagon ring R1-R6; chords C1-C6 join every other ring node (i -> i+2):
# the top and the bottom triangle, so ring + chords is the regular octahedron.
RING_NODES = ["T1", "B1", "T2", "B2", "T3", "B3"]


def ring_struts(nodes: dict[str, np.ndarray] | None = None, free: frozenset[int] = frozenset(),
                *, up: bool = False) -> list[tuple]:
    """The ring struts; those in ``free`` undocked at their target end, aimed at it (or,
    with ``up``, straight up: a vertical strut puts no weight moment on its floor node,
    35 deg from its aim, which it leaves without crossing the freed chord's way out).

    Laid level, 60 deg clockwise of the radial direction (stop 36), R6's weight moment on
    B3 (0.3 N m) was the one the other free struts did not cancel, and the structure crept
    4.7 mm/s toward it with every wheel stopped (issue 31); level counter-clockwise it met
    the freed chord on its way down (Fig. 22(f)-(j) stalled)."""
    out: list[tuple] = []
    for i in range(6):
        sid, s, t = f"R{i + 1}", RING_NODES[i], RING_NODES[(i + 1) % 6]
        if i not in free:
            out.append((sid, s, t))
        else:
            assert nodes is not None
            out.append((sid, s, None, UP if up else nodes[t] - nodes[s]))
    return out


def chord(i: int) -> tuple[str, str, str]:
    return (f"C{i + 1}", RING_NODES[i], RING_NODES[(i + 2) % 6])


def octa_state(name: str, docked: set[int], description: str = "", *,
               free_ring: frozenset[int] = frozenset()) -> dict:
    """The octahedron layout with chords not in ``docked`` (and ring struts in
    ``free_ring``) free, aimed at their node."""
    nodes = octahedron_nodes()
    struts = ring_struts(nodes, free_ring)
    for i in range(6):
        cid, s, t = chord(i)
        struts.append((cid, s, t) if i in docked else (cid, s, None, nodes[t] - nodes[s]))
    return configuration(name, nodes, struts, description)


ROLLER_TILT = math.radians(16.0)
"""How far the freed chords of fig22e point below the horizon: their far caps press on
the floor (they touch at ~13.7 deg; at 24 deg the pressing tipped the structure)."""


def roller_legs() -> dict[str, tuple[str, np.ndarray]]:
    """fig22e's freed bottom chords C2, C4, C6 as rollers: all along +-y (parallel, so
    rolling them drives along x without slip between them), tilted onto the floor."""
    out = {}
    for i, side in ((1, 1.0), (3, -1.0), (5, -1.0)):
        cid, s, _ = chord(i)
        out[cid] = (s, np.array([0.0, side * math.cos(ROLLER_TILT), -math.sin(ROLLER_TILT)]))
    return out


def octa_legs_down(name: str, docked: set[int], description: str = "", *,
                   free_ring: frozenset[int] = frozenset(), rollers: bool = False,
                   up: bool = True) -> dict:
    """Octahedron layout with the chords not in ``docked`` free, pointing outward along the
    floor (Fig. 22(e): the bottom face's struts freed as wheels; the top face stays
    docked, so each bottom node and its two ring struts form a rigid flap hinged on a
    top edge and the structure stands by friction, not by connector torque). Ring struts
    in ``free_ring`` point straight up (Fig. 22(j), :func:`ring_struts`), or without
    ``up`` still at the node they left (the pose of their undocking)."""
    nodes = octahedron_nodes()
    struts = ring_struts(nodes, free_ring, up=up)
    for i in range(6):
        cid, s, t = chord(i)
        if i in docked:
            struts.append((cid, s, t))
        elif rollers:
            struts.append((cid, s, None, roller_legs()[cid][1]))
        else:
            struts.append((cid, s, None, horizontal(math.atan2(nodes[s][1], nodes[s][0]))))
    return configuration(name, nodes, struts, description)


def hex_nodes(open_gap: float = 0.0) -> dict[str, np.ndarray]:
    """The ring nodes on a flat regular hexagon of side L (opened by ``open_gap`` [rad])."""
    nodes = {}
    for i, n in enumerate(RING_NODES):
        a = math.radians(60 * i) + open_gap * (i / 5.0 - 0.5)
        nodes[n] = np.array([L * math.cos(a), L * math.sin(a), 0.0])
    return nodes


def hex_star(name: str, description: str = "", *, aimed: bool = False,
             open_ring: bool = False, c1_up: bool = False) -> dict:
    """Flat hexagon ring R1-R6 with the chords C1-C6 as outward legs (Fig. 21(a)).

    ``aimed``: the chords point at the node they dock to in the octahedron (after the
    ring is folded, see :func:`octa_state`). ``open_ring``: R6 is undocked from T1.
    ``c1_up``: C1 points straight up, on the way between its outward rest and its aim
    across the ear (:func:`ear_state`): swung along the floor it passes through R1 or R6
    on its node.
    """
    nodes = hex_nodes()
    struts = ring_struts()
    if open_ring:
        struts[5] = ("R6", RING_NODES[5], None, nodes[RING_NODES[0]] - nodes[RING_NODES[5]])
    for i in range(6):
        cid, s, t = chord(i)
        out = math.atan2(nodes[s][1], nodes[s][0])
        struts.append((cid, s, None, UP if c1_up and i == 0 else horizontal(out)))
    return configuration(name, nodes, struts, description)


def tree_state(name: str, description: str = "") -> dict:
    """The open ring stretched into a zig-zag line with its legs (Fig. 21(e))."""
    nodes = {}
    for i, n in enumerate(RING_NODES):
        nodes[n] = np.array([i * L * math.cos(math.radians(30)),
                             (i % 2) * L * math.sin(math.radians(30)), 0.0])
    struts: list[tuple] = ring_struts()[:5]
    struts.append(("R6", RING_NODES[5], None, [1.0, 0.0, 0.0]))
    for i in range(6):
        cid, s, _ = chord(i)
        struts.append((cid, s, None, [0.0, 1.0 if i % 2 else -1.0, 0.0]))
    return configuration(name, nodes, struts, description)


def ear_nodes() -> dict[str, np.ndarray]:
    """The ring nodes folded into a regular pentagon T1-T2-B2-T3-B3 (side L) with B1 an
    equilateral ear on the edge T1-T2, where the hexagon had it: T1 and T2 are L apart,
    so chord C1 (T1 -> T2) spans them (Fig. 21(b)-(d))."""
    rp = L / (2.0 * math.sin(math.radians(36.0)))   # the pentagon's circumradius
    nodes = {}
    for n, a in zip(("T1", "T2", "B2", "T3", "B3"), (24.0, 96.0, 168.0, 240.0, 312.0),
                    strict=True):
        nodes[n] = np.array([rp * math.cos(math.radians(a)), rp * math.sin(math.radians(a)),
                             0.0])
    apex = rp * math.cos(math.radians(36.0)) + L * math.sqrt(3.0) / 2.0
    nodes["B1"] = np.array([apex * math.cos(math.radians(60.0)),
                            apex * math.sin(math.radians(60.0)), 0.0])
    return {n: nodes[n] for n in RING_NODES}


def ear_state(name: str, docked: set[str], description: str = "") -> dict:
    """The ear layout (:func:`ear_nodes`) with the ring struts and C1 in ``docked`` docked
    and the others free: a free ring strut or C1 aims at the node it docks to (``S_conn``,
    or the vectors a disconnection keeps); chords C2-C6 are legs along the floor, away
    from the centre."""
    nodes = ear_nodes()
    struts: list[tuple] = []
    for sid, s, t in ring_struts() + [chord(0)]:
        struts.append((sid, s, t) if sid in docked else (sid, s, None, nodes[t] - nodes[s]))
    for i in range(1, 6):
        cid, s, _ = chord(i)
        struts.append((cid, s, None, horizontal(math.atan2(nodes[s][1], nodes[s][0]))))
    return configuration(name, nodes, struts, description)


def rooted_tree(name: str, topology: dict, root: str) -> dict:
    """A kinematic tree over a tree-shaped ``topology`` with the fixed root at node
    ``root`` and one opposite-steering joint per strut, at its end away from the root
    (section 3.2's default tree, rooted elsewhere than the centre)."""
    ends = {c["id"]: (c["source"], c["target"]) for c in topology["connections"]}
    nodes, seen, frontier = [{"type": "fixed", "edges": [], "vertices": [root]}], {root}, [root]
    while frontier:
        v = frontier.pop(0)
        for sid, (a, b) in ends.items():
            if v in (a, b) and (b if v == a else a) not in seen:
                far = b if v == a else a
                seen.add(far)
                frontier.append(far)
                nodes.append({"type": "opposite_steering", "edges": [sid], "vertices": [far]})
    return tree_file(name, topology, nodes)


def node_wheel_commands(nodes: dict[str, np.ndarray], struts: tuple[str, ...]) -> list[dict]:
    """Gains of ring struts' target connectors that roll their (bottom) node as a wheel.

    A docked connector turns its node about the strut's ``+z`` = ``u`` (source to target
    node) at ``w r / (b/2)`` per rad/s of wheel speed ``w``; a node of radius ``R``
    rolling without slip about ``u`` moves its centre at ``R w r / (b/2) (u x e_z)``,
    along the floor at right angles to the strut's plan direction, at speed
    ``R w r / (b/2) |u_h|``. Each node takes the part of the body's velocity along its
    rolling direction ``d``: ``v_x d_x`` for ``speed`` (along +x), ``v_y d_y`` for
    ``sideways`` (along +y) and ``yaw_rate`` times the node's tangential velocity
    ``(e_z x p) . d``; the rest slips. Rolling directions 120 deg apart (fig22(j)) make
    the three a kiwi drive: the course loop slides the travel onto the line instead of
    turning the body, which every wheel scrubs (issue 31).

    Each strut also gets ``travel_along`` and ``travel_across``: the body's commanded
    translation (``speed``, ``sideways``; not its turn) along ``d`` and along the
    strut's plan direction ``h = u_h / |u_h|``, in the wheel speed's scale: the travel
    in the strut's own horizontal frame, which the connector servo steers the node's
    other struts by (a node two struts hold is a fixed wheel: stop 52 in
    docs/freesn.md).
    """
    rate = R_NODE * R_WHEEL / HALF_BASE   # centre speed [m/s] per rad/s of w, per |u_h|
    out = []
    for sid in struts:
        source, target = next((s, t) for i, s, t in ring_struts() if i == sid)
        u = (nodes[target] - nodes[source]) / L
        roll = np.cross(u, UP)                 # centre velocity per unit node spin
        scale = rate * float(np.linalg.norm(roll))
        d = roll / np.linalg.norm(roll)
        h = np.cross(UP, d)                    # u_h / |u_h|
        tangential = np.cross(UP, nodes[target])
        out.append({"module": sid, "command": "wheel_speed", "connector": "target",
                    "gains": {"speed": round(float(d[0]) / scale, 9),
                              "yaw_rate": round(float(tangential @ d) / scale, 9),
                              "sideways": round(float(d[1]) / scale, 9) + 0.0}})
        for command, e in (("travel_along", d), ("travel_across", h)):
            out.append({"module": sid, "command": command, "connector": "target",
                        "gains": {"speed": round(float(e[0]) / scale, 9) + 0.0,
                                  "sideways": round(float(e[1]) / scale, 9) + 0.0}})
    return out


# The S12N6 crawl (Fig. 19(k)-(o)): a quadruped that crawls as the S4N5 star does, its
# legs planted and swinging in turn. Two body nodes N1 (front) and N2 (rear), joined by
# one bar S1 (a second bar between the same two nodes would lie inside it: a strut's axis
# passes through the centres of the nodes it docks to); each carries two legs to
# leaf-node feet (F1, F2 under N1; F3, F4 under N2) leaning aside, and three free masts
# up; the twelfth strut S2 is a tail, level, back from N2 (>= 78 deg from every other
# strut there; it moves the centre of mass 12.5 mm back, inside the feet). A hip connector holds about (load
# on its foot) x (horizontal reach of its leg): 4.8 kg on four feet is ~12 N each, so
# the legs stand steep, reaching aside only as far as keeps two feet apart (~0.5 N m
# against the 1.2 N m of the simulated connectors). The feet move in diagonal pairs (a
# trot): every body node keeps one foot gripping while its other foot rolls. Tried and
# dropped (docs/freesn.md): a tripod (16-19 N on a foot's connection, over the 20 N
# strength), front and rear pairs in turn (the rolling pair's hips folded), one leg at a
# time (the weight shifted onto a planted diagonal and broke a foot's connection).
QUAD_SPLAY = math.radians(16.0)   # sideways lean of a leg from the vertical [rad]
QUAD_STRIDE = 0.01                # foot ahead of / behind its hip in the stances [m]
"""At 0.015 m a foot's connection broke in 9 of 10 newly built starts (the longer, faster
steps rock the body onto a diagonal); under ~0.009 m a step's 3 deg RMS change is within
the executor's reaching tolerance, so every step would end at its first tick."""
QUAD_MAST_TILT = math.radians(25.0)  # masts' lean from the vertical (42 deg apart) [rad]
QUAD_LEGS = {"L1": ("N1", "F1", 1.0), "L2": ("N1", "F2", -1.0),
             "L3": ("N2", "F3", 1.0), "L4": ("N2", "F4", -1.0)}
"""leg -> (hip node, foot node, side: +1 left (+y), -1 right)."""
QUAD_DIAGONALS = ({"L1", "L4"}, {"L2", "L3"})
"""The trot's pairs: front-left with rear-right, front-right with rear-left."""
QUAD_MASTS = {"M1": ("N1", 0.0), "M2": ("N1", 120.0), "M3": ("N1", 240.0),
              "M4": ("N2", 0.0), "M5": ("N2", 120.0), "M6": ("N2", 240.0)}
"""mast -> (node, azimuth [deg]), the same on both nodes: no two tips meet, and the
stances have no symmetry (turned by 180 deg, a trot stance is the other one relabelled;
the library then matched them so, an equally short motion)."""


def quadruped(name: str, ahead: dict[str, float], description: str = "") -> dict:
    """The S12N6 quadruped with each leg's foot ``ahead[leg]`` [m] ahead of its hip
    along +x (every ``|ahead|`` equal, so the body is level) and
    :data:`QUAD_SPLAY` aside; N1 at ``+L/2``, N2 at ``-L/2`` on x."""
    side = L * math.sin(QUAD_SPLAY)
    reach = max(abs(a) for a in ahead.values())
    drop = math.sqrt(L * L - side * side - reach * reach)
    nodes = {"N1": np.array([L / 2, 0.0, drop]), "N2": np.array([-L / 2, 0.0, drop])}
    struts: list[tuple] = [("S1", "N1", "N2"), ("S2", "N2", None, [-1.0, 0.0, 0.0])]
    for leg, (hip, foot, y) in QUAD_LEGS.items():
        nodes[foot] = nodes[hip] + np.array([ahead[leg], y * side, -drop])
        struts.append((leg, hip, foot))
    for mast, (node, azimuth) in QUAD_MASTS.items():
        struts.append((mast, node, None, horizontal(math.radians(azimuth),
                                                    QUAD_MAST_TILT - math.pi / 2)))
    return configuration(name, nodes, struts, description)


def quad_tree(name: str, topology: dict, planted: set[str]) -> dict:
    """A crawl tree of the quadruped: the body (N1, N2, the bar and the tail) a fixed root,
    the masts opposite-steering joints, ``planted`` legs gripping with their feet and
    the others swinging (:func:`legs_tree`'s joints, Fig. 19(f)-(o))."""
    nodes = [{"type": "fixed", "edges": ["S1", "S2"], "vertices": ["N1", "N2", "S2:b"]}]
    nodes += [{"type": "opposite_steering", "edges": [mast], "vertices": [f"{mast}:b"]}
              for mast in QUAD_MASTS]
    nodes += [{"type": "planted" if leg in planted else "swing", "edges": [leg],
               "vertices": [foot]} for leg, (_, foot, _) in QUAD_LEGS.items()]
    return tree_file(name, topology, nodes)


def trot_stances() -> tuple[dict, dict]:
    """The two stances of the trot: in the first, front-left and rear-right feet stand
    :data:`QUAD_STRIDE` behind their hips and the other two as far ahead; the second
    is the first with the diagonals swapped."""
    first = {leg: -QUAD_STRIDE if leg in QUAD_DIAGONALS[0] else QUAD_STRIDE
             for leg in QUAD_LEGS}
    return (quadruped("trot-1", first, "Fig. 19(k): front-left and rear-right feet behind "
                      "their hips, the others ahead"),
            quadruped("trot-2", {leg: -a for leg, a in first.items()}, "Fig. 19(l): the "
                      "diagonals swapped, the body two strides on"))


def s12n6_crawl_group() -> dict:
    """The quadruped group of S12N6 with its two crawl trees (one diagonal planted)."""
    first = trot_stances()[0]
    one, two = QUAD_DIAGONALS
    return {"name": "quadruped", "description": "Fig. 19(k): two body nodes on four legs "
            "to leaf-node feet, six free masts up, a tail", "reference": first,
            "trees": [tree("K1"), quad_tree("K-quad-plant-L1-L4", first, one),
                      quad_tree("K-quad-plant-L2-L3", first, two)]}


def s12n6_crawl_sequences() -> list[dict]:
    """Fig. 19(k)-(o): the S12N6 crawl, the S4N5 crawl's approach on four legs.

    trot-1 -> trot-2 under ``K-quad-plant-L2-L3``: those feet grip and stay, their legs
    turn from ``QUAD_STRIDE`` ahead to as far behind, so the body moves ``2 QUAD_STRIDE``
    and the other two feet roll ``4 QUAD_STRIDE``; trot-2 -> trot-1 under
    ``K-quad-plant-L1-L4`` the same with the diagonals swapped. Every ``|ahead|`` is
    equal, so each step keeps the body level at one height and its planted feet still
    (their legs keep length ``L`` about a fixed foot): a loop moves the body
    ``4 QUAD_STRIDE``.
    """
    first, second = trot_stances()
    return [{"name": "crawl", "behavior": "crawl", "loop": True,
             "description": "Fig. 19(k)-(o): crawl on four legs with leaf-node feet, the "
             "diagonal pairs planted in turn",
             "steps": [step(first, "K-quad-plant-L1-L4"),
                       step(second, "K-quad-plant-L2-L3")]}]


RING_IDS = {f"R{i + 1}" for i in range(6)}
BRANCHED = (RING_IDS - {"R1", "R4"}) | {"C1"}   # the Fig. 21 tree: R2, R3, R5, R6, C1 docked


def s12n6_groups(octa: dict, star_: dict) -> list[dict]:
    """The S12N6 groups: the octahedron and its opened forms (Fig. 22), the hexagonal
    star, its opened ring and the folded ear (Fig. 21), and the quadruped (Fig. 19)."""
    return [
        {"name": "octahedron", "description": "Fig. 22(a): twelve struts, every node degree 4",
         "reference": octa, "trees": [tree("K1")]},
        {"name": "hexagonal-star", "description": "Fig. 21(a): hexagon ring with six legs",
         "reference": star_, "trees": [tree("K1")]},
        {"name": "tree", "description": "Fig. 21(e): the opened ring, a tree",
         "reference": tree_state("fig21e"),
         "trees": [tree("K1"), rooted_tree("K-root-T1", tree_state("fig21e"), "T1")]},
        {"name": "open-face", "description": "Fig. 22(e): octahedron with one face's struts "
         "free as wheels", "reference": octa_legs_down("fig22e", {0, 2, 4}, rollers=True),
         "trees": [tree("K1")]},
        {"name": "open-face-and-edge", "description": "Fig. 22(j): ring strut R6 free too",
         "reference": octa_legs_down("fig22j", {0, 2, 4}, free_ring=frozenset({5})),
         "trees": [tree("K1")]},
        {"name": "ear", "description": "Fig. 21(c): the ring folded to a pentagon with an ear, "
         "chord C1 docked across it (two loops)",
         "reference": ear_state("ear-closed", RING_IDS | {"C1"}), "trees": [tree("K1")]},
        {"name": "branched-tree", "description": "Fig. 21(e): the two loops opened in "
         "parallel at R1 and R4, a tree",
         "reference": ear_state("fig21-tree", BRANCHED), "trees": [tree("K1")]},
        s12n6_crawl_group(),
    ]


def s12n6_fig21_sequences(star_: dict) -> list[dict]:
    """Fig. 21(a)-(i): the hexagonal star opened into a tree and closed again, one
    connection at a time and with parallel actions (section 6.3)."""
    ear_aim = ear_state("ear-aim", RING_IDS - {"R6"}, "Fig. 21(b): the open ring folded, R6 "
                        "and C1 aimed at T1 and T2")
    return [
        # No sequence stretches the open ring into the tree fig21e or back (S12N6-3.2 <->
        # 3.1, the group's reference): every node is dragged over the floor, the struts
        # meeting at B1 and B2 bind, and it broke a connector or stalled at the torque
        # limit whatever the controllers (docs/freesn.md); Fig. 21 takes the ear.
        # The ear -> ring move runs under K-root-T1: with the default root (the chain's
        # centre T2) or B2, T3, B3 it stalls 5-25 deg short (R4 17 deg off, IK residual
        # 0.1 deg); rooted at T1, where R6 docks, it finishes in 3.2 s.
        # Fig. 21 with parallel actions (section 6.3): C1 rises, the open ring folds so
        # that R6 and chord C1 both aim at their nodes and dock in one parallel
        # connection; then R1 and R4 undock in one parallel disconnection, leaving a
        # branched tree. Back: the same two parallel actions reversed, the fold undone
        # (C1 up on the way), R6 docked.
        {"name": "fig21-star-to-branched-tree", "description": "Fig. 21(a)-(e) with parallel "
         "actions: open the ring, fold it, dock R6 and C1, undock R1 and R4",
         "steps": [step(star_), step(hex_star("ring-open", open_ring=True)),
                   step(hex_star("c1-up", open_ring=True, c1_up=True)), step(ear_aim),
                   step(ear_state("ear-closed", RING_IDS | {"C1"})),
                   step(ear_state("fig21-tree", BRANCHED))]},
        {"name": "fig21-branched-tree-to-star", "description": "Fig. 21(e)-(i) with parallel "
         "actions: dock R1 and R4, undock R6 and C1, unfold, dock R6",
         "steps": [step(ear_state("fig21-tree", BRANCHED)),
                   step(ear_state("ear-closed", RING_IDS | {"C1"})), step(ear_aim),
                   step(hex_star("c1-up", open_ring=True, c1_up=True), "K-root-T1"),
                   step(hex_star("ring-aim", open_ring=True), "K-root-T1"),
                   step(star_, "K-root-T1")]},
    ]


def s12n6_fig22_sequences(octa: dict, star_: dict) -> list[dict]:
    """The folded ring docked into the octahedron, and Fig. 22(a)-(p): the octahedron opened
    to roll on one face's struts, then on its nodes, and closed again."""
    return [
        # The star itself does not fold: the edge's tree holds the closed ring in one
        # fixed node (a cycle has no joint mode), and the fold broke a connector (20.2 N,
        # 74.7 deg off). The library goes around it: the folded ring (S12N6-2.2) docks
        # its legs into the octahedron, no sequence leads from the star to it.
        {"name": "folded-to-octahedron", "description": "dock the folded ring's legs in "
         "two parallel connections",
         "steps": [step(octa_state("folded", set())),
                   step(octa_state("three-docked", {1, 3, 5})), step(octa)]},
        {"name": "fig22-a-to-e", "description": "Fig. 22(a)-(e): free one face in parallel, "
         "legs down",
         "steps": [step(octa), step(octa_state("face-free", {0, 2, 4})),
                   step(octa_legs_down("fig22e", {0, 2, 4}, rollers=True))]},
        {"name": "fig22-j-to-a", "description": "Fig. 22(k)-(p): back to the octahedron",
         "steps": [step(octa_legs_down("fig22j", {0, 2, 4}, free_ring=frozenset({5}))),
                   step(octa_state("aim-j", {0, 2, 4}, free_ring=frozenset({5}))),
                   step(octa_state("three-docked-j", {0, 2, 4})), step(octa)]},
        # After j-to-a so that aim-j keeps its id (S12N6-5.2). R6 lets go where fig22(e)
        # holds it, then the rollers turn 60 deg outward to fig22(j)'s wheels. Through
        # aim-j (the closed face's chord directions) C4 and C6 turned 90 and 150 deg
        # toward each other along the floor onto the same segment B2-B3 and jammed
        # (issue 31: seeds 12, 17, 19 at 2 deg + 5 % stalled there).
        {"name": "fig22-e-to-j", "description": "Fig. 22(f)-(j): free one more strut, "
         "then turn the rollers outward",
         "steps": [step(octa_legs_down("fig22e", {0, 2, 4}, rollers=True)),
                   step(octa_legs_down("release-j", {0, 2, 4}, free_ring=frozenset({5}),
                                       rollers=True, up=False)),
                   step(octa_legs_down("fig22j", {0, 2, 4}, free_ring=frozenset({5})))]},
    ]


def s12n6_behaviors() -> list[dict]:
    """Fig. 22(e) and (j): the opened octahedron rolling on its struts and on its nodes."""
    nodes = octahedron_nodes()
    return [
        {"name": "wheeled-move", "start": "fig22e", "parameters": ["speed", "yaw_rate"],
         "description": "Fig. 22(e): the freed bottom chords rolled about their axes on "
         "the floor",
         "commands": roller_commands(nodes, roller_legs())},
        # driven from T3, the node fig22's runs were tuned and swept with (T2 and T3 tie)
        {"name": "node-wheels", "start": "fig22j", "drive_root": "T3",
         "parameters": ["speed", "yaw_rate", "sideways"],
         "description": "Fig. 22(j): nodes driven as wheels by their ring struts",
         "commands": node_wheel_commands(nodes, ("R1", "R3", "R5"))},
    ]


def s12n6() -> None:
    out = HERE / "S12N6"
    octa = octa_state("fig22a", set(range(6)), "Fig. 22(a): octahedron")
    star_ = hex_star("fig21a", "Fig. 21(a): hexagonal star")
    write(out / "designs.json", source("S12N6", "FreeSN sub-library S12N6 (paper Figs. 18, 21, "
                                       "22): twelve struts, six nodes",
                                       groups=s12n6_groups(octa, star_)))
    sequences = [*s12n6_fig21_sequences(star_), *s12n6_fig22_sequences(octa, star_),
                 *s12n6_crawl_sequences()]
    write(out / "sequences.json", source("S12N6", "recorded sequences of S12N6",
                                         sequences=sequences, behaviors=s12n6_behaviors()))


if __name__ == "__main__":
    s6n3()
    s4n5()
    s4n1()
    s12n6()
