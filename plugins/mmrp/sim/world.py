"""The PyBullet world of MMRP modules.

Each module is a box body resting on the floor. Tracks are modelled by velocity
control: every physics step, each driven docked group (connected by dock
constraints) gets the rigid planar velocity fitted to its modules' track speeds, with
the lateral component removed (non-holonomic); modules without commands brake to
zero when they stop and after every contact that touched their group, and sleep in
the physics engine meanwhile. Contacts between bodies are simulated, so modules
collide. A dock is a ``JOINT_FIXED`` constraint between two bodies, created only when
an armed face is within the latch's alignment tolerance of the opposite face of
another module.

The floor carries the modules' weight and nothing else: the tracks set every
body's planar velocity and the floor is frictionless, so its contacts changed no
motion but cost three quarters of each physics step (30 modules). The bodies move in
the plane ``z = height / 2`` (no gravity; vertical, roll and pitch velocities held at
zero every step) and the floor is drawn but does not collide.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import networkx as nx
import numpy as np

from msrr.core.errors import ExecutionError

from ._quiet import quiet_output

with quiet_output():  # pybullet prints its build time on import, into every command's output
    import pybullet as p

from .geometry import ACTIVE_FACES, FACE_NORMALS, OPPOSITE, alignment, group_twist

__all__ = ["MmrpWorld"]

Pose2 = tuple[float, float, float]
Face = tuple[str, str]


class MmrpWorld:
    """Bodies, velocity control and dock constraints in one PyBullet client.

    Args:
        geometry: the module geometry of :data:`msrr.plugins.mmrp.robot.MODULE`.
        gui: open the PyBullet GUI (needs a display) instead of DIRECT.
        physics_rate: physics steps per second [Hz].
        gap_tolerance: latch window along the face normal [m].
        yaw_tolerance: latch window in heading [rad].
    """

    def __init__(self, geometry: Mapping[str, float], *, gui: bool = False,
                 physics_rate: float = 240.0, gap_tolerance: float = 0.015,
                 yaw_tolerance: float = 0.06):
        self.geometry = dict(geometry)
        self.pitch = float(geometry["pitch"])
        self.width = float(geometry["width"])
        self.lateral_tolerance = float(geometry["dock_tolerance"])
        self.gap_tolerance = gap_tolerance
        self.yaw_tolerance = yaw_tolerance
        self.dt = 1.0 / physics_rate
        self.client = p.connect(p.GUI if gui else p.DIRECT)
        if self.client < 0:
            raise ExecutionError("PyBullet could not open a GUI window; run without --gui")
        p.setTimeStep(self.dt, physicsClientId=self.client)
        plane = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=self.client)
        self.plane = p.createMultiBody(0, plane, physicsClientId=self.client)
        p.setCollisionFilterGroupMask(self.plane, -1, 0, 0, physicsClientId=self.client)
        self.bodies: dict[str, int] = {}
        self.tracks: dict[str, tuple[float, float]] = {}
        self.armed: set[Face] = set()
        self.docks: dict[frozenset[Face], int] = {}
        self._groups: list[list[str]] | None = None
        self._driven: list[tuple[list[str], list[int], float, float]] | None = None
        self._moving: set[str] = set()  # modules driven in the last step
        self._touched: set[str] = set()  # modules in a contact in the last step
        self._module_of: dict[int, str] = {}
        self._group_of: dict[str, list[str]] = {}
        self._awake: set[str] = set()  # modules kept awake (driven)
        self.time = 0.0

    def close(self) -> None:
        """Disconnect the PyBullet client."""
        if self.client >= 0:
            p.disconnect(physicsClientId=self.client)
            self.client = -1

    # -- building ---------------------------------------------------------------------

    def add_module(self, module: str, pose: Pose2) -> None:
        """Add a module body at planar ``pose`` ``(x, y, yaw)`` [m, m, rad]."""
        half = [self.geometry["length"] / 2, self.geometry["width"] / 2,
                self.geometry["height"] / 2]
        shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=self.client)
        visual = p.createVisualShape(p.GEOM_BOX, halfExtents=half,
                                     rgbaColor=[0.9, 0.6, 0.2, 1], physicsClientId=self.client)
        body = p.createMultiBody(self.geometry["mass"], shape, visual,
                                 basePosition=[pose[0], pose[1], half[2]],
                                 baseOrientation=p.getQuaternionFromEuler([0, 0, pose[2]]),
                                 physicsClientId=self.client)
        p.changeDynamics(body, -1, lateralFriction=0.0,
                         activationState=p.ACTIVATION_STATE_ENABLE_SLEEPING,
                         physicsClientId=self.client)
        self.bodies[module] = body
        self._module_of[body] = module
        self.tracks[module] = (0.0, 0.0)
        self._groups = None

    def latch(self, a: str, face_a: str, b: str, face_b: str) -> None:
        """Create the dock constraint ``a face_a`` - ``b face_b`` at the nominal geometry."""
        nx_, ny_ = FACE_NORMALS[face_a]
        cid = p.createConstraint(self.bodies[a], -1, self.bodies[b], -1, p.JOINT_FIXED,
                                 [0, 0, 0], [self.pitch * nx_, self.pitch * ny_, 0], [0, 0, 0],
                                 physicsClientId=self.client)
        p.changeConstraint(cid, maxForce=500.0, physicsClientId=self.client)
        self.docks[frozenset({(a, face_a), (b, face_b)})] = cid
        self._groups = None

    def unlatch(self, module: str, face: str) -> None:
        """Remove the dock constraint on ``module face``, if any."""
        for key, cid in list(self.docks.items()):
            if (module, face) in key:
                p.removeConstraint(cid, physicsClientId=self.client)
                del self.docks[key]
                self._groups = None

    # -- state ------------------------------------------------------------------------

    def pose(self, module: str) -> tuple[np.ndarray, np.ndarray]:
        """Position (3,) [m] and quaternion xyzw (4,) of ``module``."""
        pos, quat = p.getBasePositionAndOrientation(self.bodies[module],
                                                    physicsClientId=self.client)
        return np.array(pos), np.array(quat)

    def pose2(self, module: str) -> Pose2:
        """Planar pose ``(x, y, yaw)`` of ``module``."""
        pos, quat = self.pose(module)
        x, y, z, w = quat
        return float(pos[0]), float(pos[1]), math.atan2(2 * (w * z + x * y),
                                                        1 - 2 * (y * y + z * z))

    def links(self) -> dict[str, dict[str, tuple[str, str] | None]]:
        """Per module, per face: the ``(module, face)`` latched to it, or ``None``."""
        out: dict[str, dict[str, tuple[str, str] | None]] = {
            m: dict.fromkeys(FACE_NORMALS) for m in self.bodies}
        for key in self.docks:
            (a, fa), (b, fb) = sorted(key)
            out[a][fa] = (b, fb)
            out[b][fb] = (a, fa)
        return out

    def groups(self) -> list[list[str]]:
        """Modules held together by dock constraints."""
        graph = nx.Graph()
        graph.add_nodes_from(self.bodies)
        graph.add_edges_from(tuple(m for m, _ in key) for key in self.docks)
        return [sorted(c) for c in nx.connected_components(graph)]

    # -- stepping ---------------------------------------------------------------------

    def set_tracks(self, tracks: Mapping[str, tuple[float, float]]) -> None:
        """Every module's ``(left, right)`` track speeds [m/s] (absent: 0, braked)."""
        self.tracks = {m: tuple(tracks.get(m, (0.0, 0.0))) for m in self.bodies}
        self._driven = None

    def step(self) -> None:
        """One physics step: group velocities, integration, then latch armed faces.

        Driven groups get their rigid twist; a module is braked (velocity zeroed) when
        its group stops and whenever a contact touched its group in the last step.
        Nothing else moves an idle body (no gravity, no floor contact), so idle modules
        cost no Python per step.
        """
        if self._groups is None:
            self._groups = self.groups()
            self._group_of = {m: g for g in self._groups for m in g}
            self._driven = None
        client, still = self.client, (0.0, 0.0, 0.0)
        if self._driven is None:
            self._driven = [self._twist(g) for g in self._groups
                            if any(left or right for m in g for left, right in [self.tracks[m]])]
            self._rest({m for g, *_ in self._driven for m in g})
        moving: set[str] = set()
        for group, bodies, along, omega in self._driven:
            moving.update(group)
            states = [p.getBasePositionAndOrientation(b, physicsClientId=client) for b in bodies]
            cx = sum(pos[0] for pos, _ in states) / len(states)
            cy = sum(pos[1] for pos, _ in states) / len(states)
            hx = sum(1 - 2 * (q[1] * q[1] + q[2] * q[2]) for _, q in states)  # sum of cos yaw
            hy = sum(2 * (q[3] * q[2] + q[0] * q[1]) for _, q in states)  # sum of sin yaw
            norm = math.hypot(hx, hy)
            vx, vy = along * hx / norm, along * hy / norm
            for body, (pos, _) in zip(bodies, states, strict=True):
                p.resetBaseVelocity(body, (vx - omega * (pos[1] - cy), vy + omega * (pos[0] - cx),
                                           0.0), (0.0, 0.0, omega), physicsClientId=client)
        stirred = self._moving | {m for t in self._touched for m in self._group_of[t]}
        for module in stirred - moving:
            p.resetBaseVelocity(self.bodies[module], still, still, physicsClientId=client)
        self._moving = moving
        p.stepSimulation(physicsClientId=client)
        self._touched = {self._module_of[c[k]] for c in p.getContactPoints(physicsClientId=client)
                         for k in (1, 2) if c[k] in self._module_of}
        self.time += self.dt
        if self.armed:
            self._latch_armed()

    def _twist(self, group: list[str]) -> tuple[list[str], list[int], float, float]:
        """A driven group, its bodies, and its twist as its tracks set it: speed along its
        heading [m/s] and yaw rate [rad/s] (:func:`group_twist`; both are fixed in the
        group's frame while the tracks keep their speeds, so each step only turns the
        velocity with the group's heading and spreads it over its modules)."""
        poses = np.array([self.pose2(m) for m in group])
        v, omega = group_twist(poses[:, :2], poses[:, 2],
                               np.array([self.tracks[m] for m in group]), self.width)
        heading = np.array([np.cos(poses[:, 2]).sum(), np.sin(poses[:, 2]).sum()])
        along = float(v @ heading) / max(float(np.linalg.norm(heading)), 1e-12)
        return group, [self.bodies[m] for m in group], along, omega

    def _rest(self, driven: set[str]) -> None:
        """Let idle modules sleep in the physics engine (Bullet skips a sleeping island:
        most of a step's cost is the solver of the dock constraints of idle groups) and
        keep driven ones awake; a contact with an awake body wakes a sleeping one."""
        for module in driven ^ self._awake:
            state = (p.ACTIVATION_STATE_DISABLE_SLEEPING | p.ACTIVATION_STATE_WAKE_UP
                     if module in driven else p.ACTIVATION_STATE_ENABLE_SLEEPING)
            p.changeDynamics(self.bodies[module], -1, activationState=state,
                             physicsClientId=self.client)
        self._awake = set(driven)

    def _latch_armed(self) -> None:
        links = self.links()
        for module, face in sorted(self.armed):
            if links[module][face] is not None:
                continue
            other_face = OPPOSITE[face]
            pose = self.pose2(module)
            for other in self.bodies:
                if other == module or links[other][other_face] is not None:
                    continue
                if (module, face) not in self.armed and (other, other_face) not in self.armed:
                    continue
                fit = alignment(pose, face, self.pose2(other), self.pitch)
                if fit.within(self.lateral_tolerance, self.gap_tolerance, self.yaw_tolerance):
                    if face in ACTIVE_FACES:
                        self.latch(module, face, other, other_face)
                    else:
                        self.latch(other, other_face, module, face)
                    links = self.links()
                    break
