"""The joint names of a FreeSN strut's :class:`~msrr.core.driver.ModuleCommand`.

A strut module has two connectors, ``a`` (the source end of its connection) and
``b``. Each takes, like the hardware's low-level controller (FreeSN paper, section
4.2, Fig. 11b), a target connection vector in the horizontal frame of the node it is
docked to -- the unit vector from the node centre to the strut end -- as the joints
``"<end>.dir_x"``, ``"<end>.dir_y"``, ``"<end>.dir_z"``, and optionally the strut's
forward vector in the same frame (``"<end>.fwd_x"``...) which sets the rotation of
the strut about its axis, and optionally ``"<end>.effort"`` in ``[0, 1]``, the fraction
of the torque limit the connector may use (its motor current limit): a connector that
closes a loop of rigid struts is driven softly so it follows rather than fights; ``0``
switches its motor drivers off (coasting: no drive and no back-EMF braking, the node
turns freely under the connector, e.g. a foot that should roll). ``"<end>.effort"``
without a direction brakes the connector: it holds where it is on its node when the
brake begins (its target from then on), at that effort -- the strut end stays put on the
node, and the node turns with the strut (a planted foot grips).
``dock=("b",)`` extends end ``b``'s magnet array until it docks, ``undock=("a",)``
retracts end ``a``'s.

``wheels={"a": w}`` sets the wheel speed ``w`` [rad/s] of connector ``a``'s wheel pair
(the behaviors' ``wheel_speed`` command, paper sections 4.3 and 7.3; ``"source"`` and
``"target"``, the ends of the strut's connection, name ``a`` and ``b`` too). On a
docked connector the two wheels run in opposition and turn the node about the strut's
axis ``z`` (from ``a`` to ``b``) relative to the strut, right-handed, at ``w r / (b / 2)``
[rad/s] for positive ``w`` (the strut turns the other way relative to the node) -- the
one rotation the connection vector leaves free, so a connector
can hold its vector and spin at once (a leaf node on the ground turns as a wheel,
Fig. 18(a)-(c); a strut turns about its axis, Fig. 18(g)-(i)). On a free connector the
two wheels run together about the strut's ``y`` axis (their axle) at ``w``: on the
ground they drive the strut end (Fig. 18(d)-(f)). A wheel speed stays until changed;
``0`` brakes the strut's twist where it is.
``wheels={"b.travel_along": p, "b.travel_across": q}`` go with a node wheel (the
behaviors' ``travel_along`` and ``travel_across`` commands): the body's commanded
translation at its node, along the way the wheel rolls it, ``d = z x up`` made unit
(``z`` the strut's axis), and along the strut's plan direction ``h = up x d``, in the wheel
speed's scale; the travel is ``p d + q h``. A node two struts docked at both ends hold
rolls one way only; the connector servo steers the other strut's twist so that way is
this travel (a swerve wheel, ``FreeSNWorld._swerve``). Like a wheel speed they are one
tick's: not named, 0.

On the module link (``docs/protocol.md``) the connection and forward vectors are unit
vectors: :data:`LINK_VECTORS` declares them, so each travels as one 4-byte direction
(within 6.3e-5 rad) instead of three floats; and a module's pose, which no FreeSN
controller reads, travels in every second report at most (:data:`LINK_POSE_EVERY`).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from msrr.core.driver import ModuleCommand
from msrr.core.errors import ExecutionError
from msrr.core.link.declarations import declare_link

__all__ = ["ENDS", "LINK_POSE_EVERY", "LINK_VECTORS", "ConnectorTarget", "connector_joints",
           "parse_brakes", "parse_command", "parse_travel", "parse_wheels"]

ENDS = ("a", "b")
LINK_VECTORS = tuple(f"{end}.{what}" for end in ENDS for what in ("dir", "fwd"))
"""The joints ``<end>.dir_x/y/z`` and ``<end>.fwd_x/y/z`` are unit vectors (the link packs them)."""
LINK_POSE_EVERY = 2
"""A module's pose on the link at most in every second report: no FreeSN controller reads
poses (real modules measure none; the emulator's are for the timeline, the distance a
gait covered and the judge)."""
declare_link("freesn", vectors=LINK_VECTORS, pose_every=LINK_POSE_EVERY)
WHEEL_PORTS = {"a": "a", "b": "b", "source": "a", "target": "b"}
"""Names of a connector in ``ModuleCommand.wheels``: its end, or its end of the connection."""
TRAVEL = ("travel_along", "travel_across")
"""The behaviors' commands of a node wheel's travel: ``"<end>.travel_along"``..."""
_AXES = ("x", "y", "z")


def connector_joints(end: str, direction: np.ndarray, forward: np.ndarray | None = None,
                     effort: float = 1.0) -> dict[str, float]:
    """The joint entries that command connector ``end`` toward ``direction`` (unit, (3,))."""
    joints = {f"{end}.dir_{a}": float(c) for a, c in zip(_AXES, direction, strict=True)}
    if forward is not None:
        joints.update({f"{end}.fwd_{a}": float(c) for a, c in zip(_AXES, forward, strict=True)})
    if effort != 1.0:
        joints[f"{end}.effort"] = float(effort)
    return joints


ConnectorTarget = tuple[np.ndarray, np.ndarray | None, float]
"""A connector's target: connection vector, optional forward vector (node horizontal frame)
and effort (fraction of the torque limit)."""


def parse_command(strut: str, command: ModuleCommand) -> dict[str, ConnectorTarget]:
    """The connector targets in ``command``, by end; vectors normalised.

    Raises:
        ExecutionError: an unknown joint or port name, or a partial or zero vector.
    """
    targets: dict[str, ConnectorTarget] = {}
    known = {f"{e}.{k}_{a}" for e in ENDS for k in ("dir", "fwd") for a in _AXES}
    known |= {f"{e}.effort" for e in ENDS}
    unknown = set(command.joints) - known
    if unknown:
        raise ExecutionError(f"strut {strut}: unknown joint(s) {sorted(unknown)} (known: "
                             f"<end>.dir_x/y/z, <end>.fwd_x/y/z, <end>.effort with end a or b)")
    for port in (*command.dock, *command.undock):
        if port not in ENDS:
            raise ExecutionError(f"strut {strut}: unknown connector {port!r} (known: a, b)")
    for end in ENDS:
        direction = _vector(strut, command.joints, end, "dir")
        effort = float(command.joints.get(f"{end}.effort", 1.0))
        if not 0.0 <= effort <= 1.0:
            raise ExecutionError(f"strut {strut}: {end}.effort must be in [0, 1], got {effort}")
        if direction is not None:
            targets[end] = (direction, _vector(strut, command.joints, end, "fwd"), effort)
    return targets


def parse_brakes(strut: str, command: ModuleCommand) -> dict[str, float]:
    """The braked connectors of ``command`` (an effort without a direction), by end:
    their effort. Checked by :func:`parse_command`."""
    return {end: float(command.joints[f"{end}.effort"]) for end in ENDS
            if f"{end}.effort" in command.joints and f"{end}.dir_x" not in command.joints}


def _vector(strut: str, joints: Mapping[str, float], end: str, what: str) -> np.ndarray | None:
    names = [f"{end}.{what}_{a}" for a in _AXES]
    present = [n in joints for n in names]
    if not any(present):
        return None
    if not all(present):
        raise ExecutionError(f"strut {strut}: joints {names} must be given together")
    vector = np.array([joints[n] for n in names], dtype=np.float64)
    norm = float(np.linalg.norm(vector))
    if not np.isfinite(norm) or norm < 1e-9:
        raise ExecutionError(f"strut {strut}: {end}.{what} must be a non-zero vector")
    return vector / norm


def parse_wheels(strut: str, command: ModuleCommand) -> dict[str, float]:
    """The wheel speeds [rad/s] in ``command.wheels``, by end (``a``, ``b``).

    Raises:
        ExecutionError: an unknown connector name, a non-finite speed, or both names of
            one end.
    """
    speeds: dict[str, float] = {}
    for name, value in command.wheels.items():
        if name.split(".")[-1] in TRAVEL:
            continue   # parse_travel's
        end = WHEEL_PORTS.get(name)
        if end is None:
            raise ExecutionError(f"strut {strut}: unknown wheel {name!r} (known: "
                                 f"{', '.join(WHEEL_PORTS)})")
        if end in speeds:
            raise ExecutionError(f"strut {strut}: wheel speed of end {end} given twice")
        speed = float(value)
        if not np.isfinite(speed):
            raise ExecutionError(f"strut {strut}: wheel speed {name} must be finite, got {speed}")
        speeds[end] = speed
    return speeds


def parse_travel(strut: str, command: ModuleCommand) -> dict[str, tuple[float, float]]:
    """The node wheels' travel (``"<end>.travel_along"``, ``"<end>.travel_across"`` in
    ``command.wheels``, either missing 0), by end (``a``, ``b``), in the wheel speed's
    scale [rad/s].

    Raises:
        ExecutionError: an unknown end or a non-finite value.
    """
    out: dict[str, list[float]] = {}
    for name, value in command.wheels.items():
        end, _, what = name.rpartition(".")
        if what not in TRAVEL:
            continue
        if end not in ENDS:
            raise ExecutionError(f"strut {strut}: unknown connector in {name!r} (known: a, b)")
        part = float(value)
        if not np.isfinite(part):
            raise ExecutionError(f"strut {strut}: {name} must be finite, got {part}")
        out.setdefault(end, [0.0, 0.0])[TRAVEL.index(what)] = part
    return {end: (along, across) for end, (along, across) in out.items()}
