"""The MuJoCo world of single-connector freeform modules (FreeBOT, SnailBot), with ``MjSpec``.

FreeSN paper, section 2.1: a FreeBOT is a steel sphere whose internal magnet attaches
anywhere on another module and rolls on it (Fig. 1a); a SnailBot crawls on another
module's shell with a magnetic foot and can lock with a vacuum sucker (Fig. 1b). Both
have one connector (MISO: at most one out-connection). Bodies of module ``i``:

* ``module/i`` -- a free sphere (the shell), radius ``r``;
* ``connector/i`` -- the part that carries the connector and the IMU: FreeBOT's magnet
  and drive unit, on a ball joint (``bearing/i``) about the shell's centre
  (``ModuleDesign.bearing``); SnailBot's body frame, rigid with the shell. Its ``+z``
  axis is the connector's axis;
* ``foot/i`` -- a small body at ``L = 2 r + gap`` along that axis, on a ball joint
  (``drive/i``) whose centre is where the centre of the module it docks on lies.

**Docking** welds ``foot/i`` to ``module/j`` (a weld equality switched on through
``data.eq_active``, as FreeSN's connectors): ``i`` then turns about ``j``'s centre on the
``drive`` ball joint -- the SRC joint's (and the SnailBot spherical joint's) motion
about the parent's centre, with the connector staying pointed at ``j``. The drives are
the FreeSN world's DC-motor model: a damping ``D = max_torque / max_rate`` on the joint
(back-EMF, integrated implicitly) and a drive torque ``D * omega`` bounded by the torque
limit, ``omega`` from a position loop toward the commanded connection vector. ``gap``
keeps docked shells a millimetre apart, so a docked pair has no shell contact to fight
the drive. A FreeBOT's bearing is braked (damping ``10 D``: its internal wheels hold the
shell) unless its drive is moving it and no module is docked on it; then the shell
turns freely about the magnet unit and rolls on the ground instead of sliding.

**Flow** (paper 4.1): a module whose connector is told to dock on ``Q`` while it sits
on ``P`` keeps the magnet on ``P`` until its shell comes within ``dock_tolerance`` of
touching ``Q``; then the connector turns about the module's own centre to point at
``Q`` (the magnet slides over the seam inside the shell; a SnailBot turns in place --
the flowing module is a leaf, nothing hangs on it) and the weld switches from ``P`` to
``Q`` in the same step. An undock of ``P`` sent meanwhile waits for that switch. Other
docks draw the foot onto the centre (time constant ``seat``).

**Travel of a piece** (FreeBOT, :meth:`FreeformWorld.command_travel`): every module of a
connected piece rolls its shell under its arm while its drive and bearing track the goals
of one rigid twist, so the piece moves over the floor as one body, each module driving.
A straight piece moves along its line and turns; nothing outside it gives a torque about
that line but the weight of its root's magnet unit, which hangs as a pendulum while the
piece travels (the *keel*, as a free module rolls) and holds the root's velocity across
the line to the twist's: without it a turn in place left the piece rolling sideways.

**Sucker** (SnailBot): a connect equality pins the contact point (``r`` along the
connector axis) to the substrate; with the foot on the substrate's centre, the module
can then only turn about the line through both -- the sucker's revolute joint.

Module reports (:class:`ModuleReport`) carry only what a module senses: the module its
connector holds, its IMU tilt, the connector's odometry relative to that module, the
sucker state and the constraint events; the recognizer never sees the bodies. The
IMU's yaw reference is the body axis most upright at the start, so it stays continuous
(the twist of a frame whose reference axis points straight down is not defined).

The step loop, the dock welds and the event bookkeeping are every freeform world's
(:class:`~msrr.core.freeform.mujoco.MujocoWorld`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

from ..alignment import rot_z, rot_zs, wrap_angle
from ..configuration import Configuration
from ..driver import DriverOption
from ..errors import ExecutionError
from ..kinematics.rotations import rotation_between
from .design import ModuleDesign
from .layout import DOCK_GAP, place
from .mujoco import (
    GROUND_FRICTION,
    WELD_SOLIMP,
    WELD_SOLREF,
    MujocoOptions,
    MujocoWorld,
    Switches,
    connected_groups,
    heading,
    quat_conj,
    quat_log,
    quat_mul,
)

__all__ = ["ConstraintEvent", "FreeformOptions", "FreeformWorld", "ModuleReport", "place"]

_ARMATURE = 1e-3      # drive motor rotors reflected through the gearbox [kg m^2]
_FOOT_MASS = 0.005    # [kg]
_TINY = 1e-6          # inertia of small bodies [kg m^2]
_EZ = np.array([0.0, 0.0, 1.0])
_ROLLING = np.radians(0.5)  # a drive further than this from its target rolls its shell
_BEARING_FREE = 1e-3  # damping of a rolling shell's bearing [N m s/rad]
_BRAKE = 10.0         # braked bearing damping, in units of the drive's
_PENDULUM = 0.5       # centre of mass of a FreeBOT's magnet unit along its axis [radii]
_ROLL_SPEED_GAIN = 5.0  # pendulum drive: lead angle per speed error [rad / (m/s)]
_ROLL_TILT = 0.5        # largest lead angle of the hanging magnet unit [rad]
# an int: numpy compares an array to the binding's enum object element by element in Python
_EQUALITY = int(mujoco.mjtConstraint.mjCNSTR_EQUALITY)
_ROLL_KP = 0.1          # its angle loop [N m / rad]
_ROLL_KD = 0.005        # [N m s / rad]
_CRAWL_GAIN = 60.0      # SnailBot tracks: acceleration per speed error [1/s]
_TRACTION = 0.3         # their largest force, in units of the module's weight
_FOOT_KP = 2.0          # the footprint holding the foot down [N m / rad]
_FOOT_KD = 0.1          # [N m s / rad]
_GRAVITY = 9.81         # [m/s^2]
_REST_TORQUE = 1e-3     # a module at rest whose motors hold it with less stops them [N m]
_TRACK_SLIDE = 0.01     # floor friction of a crawling SnailBot's shell (its tracks carry it)


@dataclass(frozen=True, kw_only=True)
class FreeformOptions(MujocoOptions):
    """How one freeform simulation runs: :class:`~msrr.core.freeform.mujoco.MujocoOptions`
    (``timestep``, ``noise``, ``position_gain`` 8/s, ``servo_rate``, ``seed``) and

    Attributes:
        gap: shell-to-shell gap of a docked pair [m].
        dock_tolerance: a connector told to dock latches when the shells are this close
            to touching [m].
        seat: time constant of a fresh dock drawing the foot onto the centre [s].
        strength_factor: connection strength as a fraction of the description's
            ``connection_strength`` (and ``sucker_strength``).
        break_filter: time constant of the connection-load low-pass before the strength
            check [s] (a magnet does not let go on a one-step impulse).
        sleep_tolerance: speed [m/s] under which MuJoCo puts an island of modules at rest
            to sleep (its island sleeping, ``mjENBL_SLEEP``; velocities scaled by each
            DOF's length) until a command, a dock or a contact wakes it; 0: never.
    """

    OPTIONS: ClassVar[tuple[DriverOption, ...]] = MujocoOptions.OPTIONS + (
        DriverOption("gap", float, "shell-to-shell gap of a docked pair", "m", 0.0, 0.05,
                     low_open=True),
        DriverOption("dock_tolerance", float, "how close the shells latch", "m", 0.0, 0.1,
                     low_open=True),
        DriverOption("seat", float, "time constant of a fresh dock's seating", "s", 0.0, 10.0,
                     low_open=True),
        DriverOption("strength_factor", float, "connection strength / the description's", "",
                     0.0, 10.0, low_open=True),
        DriverOption("break_filter", float, "time constant of the connection-load filter", "s",
                     0.0, 10.0, low_open=True),
        DriverOption("sleep_tolerance", float, "speed under which modules at rest sleep "
                     "(0: never)", "m/s", 0.0, 0.1),
    )

    gap: float = DOCK_GAP
    dock_tolerance: float = 0.006
    seat: float = 0.15
    strength_factor: float = 1.0
    break_filter: float = 0.05
    sleep_tolerance: float = 0.001

    def __post_init__(self) -> None:
        super().__post_init__()
        self._check(positive=("gap", "dock_tolerance", "seat", "strength_factor",
                              "break_filter"), non_negative=("sleep_tolerance",))


@dataclass(frozen=True)
class ConstraintEvent:
    """A switch of a dock constraint, as the simulator made it.

    Attributes:
        time: [s]. module: whose connector. kind: ``"dock"``, ``"undock"``, ``"flow"`` or
            ``"break"`` (the load exceeded the connection's strength).
        target: the module docked on (dock, flow) or left (undock, break).
        previous: the module left by a flow.
        load: the filtered pull-off and shear force at a break [N].
    """

    time: float
    module: str
    kind: str
    target: str
    previous: str | None = None
    load: float = 0.0


@dataclass(frozen=True)
class ModuleReport:
    """What one module reports.

    Attributes:
        attached: the module its connector holds (magnetic contact), or ``None``.
        tilt: rotation (3, 3) of its connector frame in its own horizontal frame (IMU);
            column 2 is the connector's axis.
        relative: rotation (3, 3) of its connector frame in the connector frame of
            ``attached`` (drive and bearing encoders), or ``None`` when free.
        sucker: whether the sucker holds.
        events: its connector's constraint events since the previous report.
        odometry: ``(x, y, yaw)`` (3,): its dead-reckoned pose on the floor in its own
            odometry frame (its horizontal frame at reset) [m, m, rad]: the turn about the
            vertical its gyro integrates (its frame of travel commands), and the centre's
            travel its drive senses while its connector is free or its piece travels
            (FreeBOT: the shell's rotation, rolling without slip; SnailBot: the tracks);
            otherwise the position stays where it was.
    """

    attached: str | None
    tilt: np.ndarray
    relative: np.ndarray | None
    sucker: bool = False
    events: tuple[ConstraintEvent, ...] = field(default_factory=tuple)
    odometry: np.ndarray = field(default_factory=lambda: np.zeros(3))


class FreeformWorld(MujocoWorld[str, ConstraintEvent]):
    """One configuration of single-connector freeform modules in MuJoCo: a pool of one
    weld slot per module (its connector), keyed by the module and pointed at its target
    when it docks.

    Args:
        config: the starting configuration; its connections start docked.
        design: the module (see :class:`ModuleDesign`).
        options: the run's options.
    """

    options: FreeformOptions

    def __init__(self, config: Configuration, design: ModuleDesign, options: FreeformOptions):
        super().__init__(options, seat=options.seat)
        self.design = design
        self.length = 2.0 * design.radius + options.gap
        self.modules = sorted(v for v in config.vertices() if not config.is_virtual(v))
        self._index = {m: i for i, m in enumerate(self.modules)}
        centres, frames = place(config, self.length, design.radius)
        self._conn0 = np.array([Rotation.from_matrix(frames[m] if design.bearing else np.eye(3))
                                .as_quat(scalar_first=True) for m in self.modules])
        self._suckers: Switches[str] = Switches()
        self.compile(self._build(centres, frames))
        self._suckers.bind(self.model)
        m = self.model
        self._shell = np.array([m.body(f"module/{i}").id for i in self.modules])
        self.bodies = dict(zip(self.modules, self._shell.tolist(), strict=True))
        self._owner = {body: module for module, body in self.bodies.items()}
        self._conn = np.array([m.body(f"connector/{i}").id for i in self.modules])
        self._foot = np.array([m.body(f"foot/{i}").id for i in self.modules])
        drives = [m.joint(f"drive/{i}") for i in self.modules]
        self._qadr = np.array([j.qposadr[0] for j in drives])
        self._dofs = np.array([j.dofadr[0] for j in drives])[:, None] + np.arange(3)
        n = len(self.modules)
        self.docked: list[str | None] = [None] * n
        self._joined: _Joined | None = None   # :meth:`groups`' memo
        self._parent = np.full(n, -1)   # index of ``docked`` (-1: free), kept with it
        self.armed: list[str | None] = [None] * n    # dock target ("" = any touching module)
        self.release: list[bool] = [False] * n        # undock waiting for a flow's switch
        self.sucker = [False] * n
        self._target = np.tile(np.array([1.0, 0, 0, 0]), (n, 1))
        self._rolling = np.zeros(n, dtype=bool)   # bearing free: the shell rolls
        self._roll = np.zeros((n, 3))              # ground velocity of a free module [m/s]
        self._travel = np.zeros(n, dtype=bool)     # rolls as part of a travelling piece
        self._keel = np.zeros(n, dtype=bool)       # its root, whose magnet unit hangs
        self._travel_v = np.zeros((n, 3))          # its centre's ground velocity [m/s]
        self._travel_w = np.zeros(n)               # its turn about the vertical [rad/s]
        self._shell_goal = np.tile([1.0, 0, 0, 0], (n, 1))   # where its shell should be
        self._conn_goal = np.tile([1.0, 0, 0, 0], (n, 1))    # and its connector (world)
        self._free_adr = np.array([m.joint(f"free/{i}").dofadr[0] for i in self.modules])
        self._bearing = np.array([m.joint(f"bearing/{i}").dofadr[0] for i in self.modules]
                                 )[:, None] + np.arange(3) if design.bearing else None
        self._bearing_q = np.array([m.joint(f"bearing/{i}").qposadr[0] for i in self.modules]
                                   ) if design.bearing else None
        self._braked = np.zeros(n, dtype=bool)     # bearing held at ``_brake_at``
        self._brake_at = np.tile(np.array([1.0, 0, 0, 0]), (n, 1))
        self._damping = design.max_torque / design.max_rate
        self._wrench = np.zeros((n, 6))            # tracks of crawling SnailBots
        self._shell_geom = np.array([m.geom(f"shell/{i}").id for i in self.modules])
        self._load = np.zeros(n)                   # filtered connection loads [N]
        self._odometry = np.zeros((n, 2))          # travel sensed while free, world [m]
        self._turned = np.zeros(n)                 # yaw the gyros integrated [rad]
        self._gyro = np.random.default_rng([options.seed, 1])  # the yaw's own noise
        self._tree = m.body_treeid[self._shell]    # each module is one kinematic tree
        self._wake = np.zeros(n, dtype=bool)       # commanded to move since the last servo
        # each module's weld to a parent (a lone module has none: its entry is never read)
        self._weld_id = np.array([self.welds.id(i) for i in self.modules] if n > 1 else [0])
        mujoco.mj_forward(self.model, self.data)
        self._upright = np.array([_upright(r) for r in self.data.xmat[self._conn].reshape(-1, 3, 3)])
        self._heading0 = self._headings()
        for e in config.edges():
            self._dock(self._index[e.source], e.target, kind="")
        mujoco.mj_forward(self.model, self.data)

    # -- building ---------------------------------------------------------------------

    def _build(self, centres: dict[str, np.ndarray], frames: dict[str, np.ndarray]
               ) -> mujoco.MjSpec:
        d = self.design
        spec = self.new_spec(f"freeform-{d.kind}")
        if self.options.sleep_tolerance > 0:     # islands at rest sleep (:meth:`_servo`)
            spec.option.enableflags |= int(mujoco.mjtEnableBit.mjENBL_SLEEP)
            spec.option.sleep_tolerance = self.options.sleep_tolerance
        shell_mass = d.mass - d.connector_mass - _FOOT_MASS
        if shell_mass <= 0:
            raise ExecutionError(f"module kind {d.kind!r}: mass must exceed the connector's")
        shell = 2.0 / 3.0 * shell_mass * d.radius**2        # thin shell
        core = 0.4 * d.connector_mass * (0.5 * d.radius) ** 2  # compact drive unit
        for name in self.modules:
            quat = Rotation.from_matrix(frames[name]).as_quat(scalar_first=True)
            body = spec.worldbody.add_body(name=f"module/{name}", pos=centres[name],
                                           quat=quat if not d.bearing else [1, 0, 0, 0],
                                           mass=shell_mass, inertia=[shell] * 3,
                                           explicitinertial=True, ipos=[0, 0, 0],
                                           iquat=[1, 0, 0, 0])
            body.add_freejoint(name=f"free/{name}")
            body.add_geom(name=f"shell/{name}", type=mujoco.mjtGeom.mjGEOM_SPHERE,
                          size=[d.radius, 0, 0], friction=list(GROUND_FRICTION), mass=0,
                          rgba=list(d.rgba), priority=1)   # its friction rules its contacts
            inner = quat if d.bearing else [1, 0, 0, 0]
            conn = body.add_body(name=f"connector/{name}", quat=inner, mass=d.connector_mass,
                                 inertia=[core] * 3, explicitinertial=True, ipos=[0, 0, 0],
                                 iquat=[1, 0, 0, 0])
            if d.bearing:
                conn.add_joint(name=f"bearing/{name}", type=mujoco.mjtJoint.mjJNT_BALL,
                               damping=_BRAKE * d.max_torque / d.max_rate, armature=_ARMATURE)
            conn.add_geom(name=f"mark/{name}", type=mujoco.mjtGeom.mjGEOM_CYLINDER,
                          fromto=[0, 0, 0.55 * d.radius, 0, 0, 0.95 * d.radius],
                          size=[0.35 * d.radius, 0, 0], mass=0, contype=0, conaffinity=0,
                          rgba=[0.15, 0.15, 0.2, 1.0])
            # the foot stands for the weld at the parent's centre: it weighs nothing
            # (:meth:`_pendulum`) but under a lone rolling module, whose hanging drive was
            # tuned with it; a free module's foot 0.1 m out to the side where its magnet
            # let go swung a straight piece about its line (up to 1.6 rad/s measured)
            foot = conn.add_body(name=f"foot/{name}", pos=[0, 0, self.length], mass=_FOOT_MASS,
                                 inertia=[_TINY] * 3, explicitinertial=True, ipos=[0, 0, 0],
                                 iquat=[1, 0, 0, 0], gravcomp=1.0)
            foot.add_joint(name=f"drive/{name}", type=mujoco.mjtJoint.mjJNT_BALL,
                           damping=d.max_torque / d.max_rate, armature=_ARMATURE)
        # one weld (and sucker) slot per module: a module has one connector, so it holds
        # at most one connection; the slot is pointed at its target when it docks
        for a, b in zip(self.modules, self.modules[1:] + self.modules[:1], strict=True):
            if a == b:
                break
            self.add_weld(spec, a, f"dock/{a}", f"foot/{a}", f"module/{b}")
            if d.sucker:
                self._suckers.add(spec, a, f"sucker/{a}", type=mujoco.mjtEq.mjEQ_CONNECT,
                                  objtype=mujoco.mjtObj.mjOBJ_BODY, name1=f"connector/{a}",
                                  name2=f"module/{b}", solref=list(WELD_SOLREF),
                                  solimp=list(WELD_SOLIMP))
        return spec

    # -- commands -----------------------------------------------------------------------

    def _k(self, module: str) -> int:
        try:
            return self._index[module]
        except KeyError:
            raise ExecutionError(f"no module {module!r} in this world (modules: "
                                 f"{', '.join(self.modules)})") from None

    def command_direction(self, module: str, direction: np.ndarray) -> None:
        """Drive ``module`` so its connection vector (unit, from it toward the module it
        is docked on) becomes ``direction``, given in that module's horizontal frame;
        ignored when the connector is free or the sucker holds."""
        k = self._k(module)
        parent = self.docked[k]
        if parent is None or self.sucker[k]:
            return
        d = self.data
        j = self._index[parent]
        want = rot_z(float(self._headings()[j])) @ direction
        want = want / np.linalg.norm(want)
        r_conn = d.xmat[self._conn[k]].reshape(3, 3)
        turn = rotation_between(r_conn[:, 2], want)   # about the parent's centre
        r_foot = d.xmat[self._foot[k]].reshape(3, 3)
        joint = (turn @ r_conn).T @ r_foot               # foot in the turned connector frame
        self._aim(k, Rotation.from_matrix(joint).as_quat(scalar_first=True))
        self._rolling[k] = float(np.arccos(np.clip(want @ r_conn[:, 2], -1, 1))) > _ROLLING

    def command_twist(self, module: str, angle: float) -> None:
        """Turn ``module`` about its sucker's axis (the line through its centre and its
        parent's) by ``angle`` [rad] from where it is now, right-handed about the
        connection vector; only while the sucker holds (the sucker-revolute joint)."""
        k = self._k(module)
        if self.docked[k] is None or not self.sucker[k]:
            return
        q = self.data.qpos[self._qadr[k]:self._qadr[k] + 4]
        joint = Rotation.from_quat(q, scalar_first=True).as_matrix()   # foot in connector
        # the connector turns by ``angle`` about its own z (towards the parent): the foot,
        # seen from it, turns back
        self._aim(k, Rotation.from_matrix(rot_z(-angle) @ joint).as_quat(scalar_first=True))

    def _aim(self, k: int, target: np.ndarray) -> None:
        """Set module ``k``'s drive goal (a quaternion (4,)); a new goal wakes it."""
        self._wake[k] |= not np.array_equal(target, self._target[k])
        self._target[k] = target

    def command_roll(self, module: str, velocity: np.ndarray) -> None:
        """Move a free module on the ground at ``velocity`` (3,) [m/s], given in its own
        horizontal frame as its gyro keeps it (its odometry frame turned by the reported
        yaw; the vertical part is ignored). A FreeBOT rolls: the magnet unit,
        heavier at its magnet's end, hangs as a pendulum, and the drive turns the shell
        against it (:meth:`_roll_torques`). A SnailBot crawls on its tracks, foot down
        (:meth:`_crawl`). Ignored once the module is docked."""
        k = self._k(module)
        if self.docked[k] is not None:   # it latched: the drive now turns it on its parent
            return
        frame = rot_z(float(self._heading0[k] + self._turned[k]))   # as its gyro keeps it
        v = frame @ np.asarray(velocity, dtype=np.float64)
        v[2] = 0.0
        self._roll[k] = v
        self._wake[k] |= bool(np.any(v))
        if self.design.bearing:
            self._rolling[k] = bool(np.any(v))
            self._pendulum(k, self._rolling[k])
        else:
            self._tracks(k, bool(np.any(v)))

    def command_travel(self, module: str, velocity: np.ndarray, turn: float) -> None:
        """Roll ``module`` over the floor as part of a piece travelling as one rigid body:
        its centre at ``velocity`` (3,) [m/s], given in its own horizontal frame as its
        gyro keeps it (vertical part ignored), while the piece turns at ``turn`` [rad/s]
        about the vertical; the velocity turns with the piece (a constant twist in the
        piece's frame) until the next command. The controller sends every module of the piece the velocity
        of its own centre under one twist, ``v_k = v + w e_z x (p_k - p)``.

        A connection is an arm from the module's centre to its parent's, with ball joints
        at both ends (``drive`` on the parent's shell, ``bearing`` in its own), so a shell
        can roll under its arm: every shell rolls without slip, ``omega_k = e_z x v_k / r
        + w e_z``, every connector turns with the piece, ``w e_z``, and each module's two
        joints track the relative rotations of those goals (:meth:`_travel_torques`);
        the arms' directions, the piece's shape, stay as they were. A FreeBOT only: a
        docked SnailBot's tracks hold its parent's shell, not the floor.

        The piece's root (its magnet free, modules docked on it) is its *keel*: its
        magnet unit, on which no arm holds, hangs as a free module's does and its
        bearing drives the root's centre toward the piece's twist at it (:meth:`_hang`,
        :meth:`_keel_velocity`; the lead gain times the piece's size: one unit's weight
        tips the whole piece). That is
        the one torque about a straight piece's line: the joints only hold the piece's
        shape, and a rotation of the whole piece about its line (rolling sideways), which
        a turn in place leaves behind, went on unchecked (a chain of four, after a
        quarter turn, drove 42 deg off its line).

        Raises:
            ExecutionError: the module has no bearing (its shell cannot roll under it).
        """
        k = self._k(module)
        if not self.design.bearing:
            raise ExecutionError(f"module {module}: a {self.design.kind} travels over the "
                                 "floor only alone (its connector is rigid with its shell)")
        frame = rot_z(float(self._heading0[k] + self._turned[k]))   # as its gyro keeps it
        v = frame @ np.asarray(velocity, dtype=np.float64)
        v[2] = 0.0
        if not self._travel[k]:          # the goals start where the bodies are
            self._shell_goal[k] = self.data.xquat[self._shell[k]]
            self._conn_goal[k] = self.data.xquat[self._conn[k]]
            self._travel[k] = True
            self._roll[k] = 0.0
            self._rolling[k] = False
            self._keel[k] = self.docked[k] is None and self._carrying(k)
            self._pendulum(k, bool(self._keel[k]))
        self._wake[k] |= bool(np.any(v)) or bool(turn) or not np.array_equal(
            v, self._travel_v[k])
        self._travel_v[k] = v
        self._travel_w[k] = float(turn)

    def _tracks(self, k: int, on: bool) -> None:
        """A crawling SnailBot stands on its tracks, not on its shell: the shell's floor
        friction gives way to the tracks' bounded traction (:meth:`_crawl`)."""
        self.model.geom_friction[self._shell_geom[k], 0] = (_TRACK_SLIDE if on
                                                            else GROUND_FRICTION[0])

    def _pendulum(self, k: int, on: bool) -> None:
        """Put the magnet unit's weight on its magnet's end (the drive climbs the inside
        of the shell, as in a hamster ball) while a free module rolls; centred otherwise,
        where a hanging weight under a braked bearing would rock the shell. The foot
        weighs only under such a rolling module (its drive was tuned with it)."""
        offset = _PENDULUM * self.design.radius if on else 0.0
        self.model.body_gravcomp[self._foot[k]] = 0.0 if on else 1.0
        if self.model.body_ipos[self._conn[k], 2] != offset:
            self.model.body_ipos[self._conn[k]] = [0.0, 0.0, offset]
            mujoco.mj_forward(self.model, self.data)

    def command_hold(self, module: str) -> None:
        """Brake ``module``'s drive where it is now."""
        k = self._k(module)
        self._target[k] = self.data.qpos[self._qadr[k]:self._qadr[k] + 4]
        self._rolling[k] = False
        self._travel[k] = False
        if self._keel[k]:
            self._keel[k] = False
            self._pendulum(k, False)
        if np.any(self._roll[k]):
            self._roll[k] = 0.0
            if self.design.bearing:
                self._pendulum(k, False)
            else:
                self._tracks(k, False)

    def command_dock(self, module: str, target: str = "") -> None:
        """Arm ``module``'s connector to latch on ``target`` (``""``: any module it touches)."""
        k = self._k(module)
        if target and target not in self._index:
            self._k(target)
        if self.docked[k] != target or not target:
            self.armed[k] = target
            self._wake[k] = True

    def command_undock(self, module: str, target: str = "") -> None:
        """Release ``module``'s connector (from ``target`` if given); while it is armed to
        dock elsewhere, the release waits for that switch (a flow)."""
        k = self._k(module)
        if self.docked[k] is None or (target and self.docked[k] != target):
            return
        if self.armed[k] is not None:
            self.release[k] = True
            return
        self._release(k)

    def command_sucker(self, module: str, on: bool) -> None:
        """Engage or release ``module``'s vacuum sucker on the module it is docked on."""
        k = self._k(module)
        if not self.design.sucker:
            raise ExecutionError(f"module {module}: a {self.design.kind} has no sucker")
        parent = self.docked[k]
        if on == self.sucker[k] or (on and parent is None):
            return
        if not on:
            self._suckers.off(self.data, module)
            self.sucker[k] = False
            return
        d = self.data
        j = self._index[parent]
        self._suckers.attach(self.model, module, self._conn[k], self._shell[j])
        eq = self._suckers.on(d, module)
        contact = d.xpos[self._conn[k]] + d.xmat[self._conn[k]].reshape(3, 3)[:, 2] * (
            self.design.radius + 0.5 * self.options.gap)
        self.model.eq_data[eq, :3] = [0.0, 0.0, self.design.radius + 0.5 * self.options.gap]
        self.model.eq_data[eq, 3:6] = d.xmat[self._shell[j]].reshape(3, 3).T @ (
            contact - d.xpos[self._shell[j]])
        self.sucker[k] = True
        self.command_hold(module)

    # -- docking ------------------------------------------------------------------------

    def _dock(self, k: int, target: str, *, kind: str = "dock") -> None:
        module = self.modules[k]
        previous = self.docked[k]
        if previous is not None:
            self._unlatch(k)
        self.weld(module, self._foot[k], self._shell[self._index[target]])
        self.docked[k] = target
        self._parent[k] = self._index[target]
        self.armed[k] = None
        self.release[k] = False
        self.command_hold(module)
        if kind:
            self.events.append(ConstraintEvent(self.time, module, kind, target,
                                               previous if kind == "flow" else None))

    def _carrying(self, k: int) -> bool:
        """Whether a module is docked on module ``k``."""
        return bool(np.any(self._parent == k))

    def _turn_connector(self, k: int, towards: np.ndarray) -> None:
        """Point ``k``'s connector at ``towards`` (world, (3,)) about its own centre: the
        magnet slides over the seam of a flow, or turns to a module a free module
        reached (FreeBOT: inside the shell, on the bearing; SnailBot: the body turns in
        place). Nothing turns with it: a SnailBot's is a leaf, a FreeBOT's magnet unit
        turns inside its shell, on which the modules it carries hold; the foot keeps its
        world orientation."""
        d, m = self.data, self.model
        r_conn = d.xmat[self._conn[k]].reshape(3, 3)
        turn = rotation_between(r_conn[:, 2], towards / np.linalg.norm(towards))
        r_foot = d.xmat[self._foot[k]].reshape(3, 3)
        new_conn = turn @ r_conn
        if self.design.bearing:
            joint = m.joint(f"bearing/{self.modules[k]}")
            r_shell = d.xmat[self._shell[k]].reshape(3, 3)
            rest = Rotation.from_quat(self._conn0[k], scalar_first=True).as_matrix()
            local = rest.T @ r_shell.T @ new_conn   # relative to the body's rest
        else:
            joint = m.joint(f"free/{self.modules[k]}")
            local = turn @ d.xmat[self._shell[k]].reshape(3, 3)
        adr = joint.qposadr[0] + (0 if self.design.bearing else 3)
        d.qpos[adr:adr + 4] = Rotation.from_matrix(local).as_quat(scalar_first=True)
        drive = new_conn.T @ r_foot
        d.qpos[self._qadr[k]:self._qadr[k] + 4] = Rotation.from_matrix(drive).as_quat(
            scalar_first=True)
        mujoco.mj_forward(m, d)

    def _unlatch(self, k: int) -> None:
        module, parent = self.modules[k], self.docked[k]
        if parent is None:
            return
        self.welds.off(self.data, module)
        if self.sucker[k]:
            self._suckers.off(self.data, module)
            self.sucker[k] = False
        self.docked[k] = None
        self._parent[k] = -1

    def _release(self, k: int) -> None:
        parent = self.docked[k]
        if parent is None:
            return
        self._unlatch(k)
        self.release[k] = False
        self.events.append(ConstraintEvent(self.time, self.modules[k], "undock", parent))

    def _check_docks(self) -> None:
        centres = self.data.xpos[self._shell]
        reach = 2.0 * self.design.radius + self.options.gap + self.options.dock_tolerance
        for k, want in enumerate(self.armed):
            if want is None:
                continue
            gaps = np.linalg.norm(centres - centres[k], axis=1)
            gaps[k] = np.inf
            if self.docked[k] is not None:
                gaps[self._index[self.docked[k]]] = np.inf
            j = self._index[want] if want else int(np.argmin(gaps))
            if gaps[j] <= reach:
                flow = self.docked[k] is not None
                if flow or not self._carrying(k) or self.design.bearing:
                    self._turn_connector(k, centres[j] - centres[k])
                if self._travel[k]:   # the latch stops the piece it leads
                    for m in next(g for g in self.groups() if self.modules[k] in g):
                        self.command_hold(m)
                self._dock(k, self.modules[j], kind="flow" if flow else "dock")

    # -- stepping -----------------------------------------------------------------------

    def _before_step(self) -> None:
        """Brake the bearings of the shells that do not roll, where they are now."""
        if self._bearing is not None:   # the shells of modules at rest are braked
            # so are those others dock on: a shell that turned freely would swing them
            carrying = np.zeros(len(self.modules), dtype=bool)
            carrying[self._parent[self._parent >= 0]] = True
            free = self._rolling & ~carrying
            damping = np.where(free, _BEARING_FREE, _BRAKE * self._damping)
            damping = np.where(     # a travelling piece's bearings are its motors
                self._travel, self._damping, damping)
            damping[self._keel] = _BEARING_FREE       # but its keel hangs
            self.model.dof_damping[self._bearing] = damping[:, None]
            held = ~free & ~self._travel
            newly = held & ~self._braked    # hold where the shell is now
            adr = self._bearing_q[newly][:, None] + np.arange(4)
            self._brake_at[newly] = self.data.qpos[adr]
            self._braked = held

    def _period_done(self, steps: int) -> None:
        """Free modules' odometry integrates, connections over their strength break, then
        fresh docks seat."""
        duration = steps * self.options.timestep
        self._integrate_odometry(duration)
        self._check_loads(duration)
        super()._period_done(steps)

    def _integrate_odometry(self, duration: float) -> None:
        """Add what the modules sense over ``duration`` [s]: every gyro's turn about the
        vertical, and the travel of a free module: a FreeBOT's shell rolling without
        slip, ``v = r omega x e_z`` (``omega`` from its gyro and bearing encoders), a
        SnailBot's tracks (the body's speed over the floor)."""
        d = self.data
        self._turned += duration * d.cvel[self._conn, 2]
        ks = np.flatnonzero((self._parent < 0) | self._travel)
        if not len(ks):
            return
        if self.design.bearing:
            v = self.design.radius * _cross(d.cvel[self._shell[ks], :3], _EZ)
        else:
            v = d.qvel[self._free_adr[ks][:, None] + np.arange(3)]
        self._odometry[ks] += duration * v[:, :2]

    def _check_loads(self, duration: float) -> None:
        """Break every connection whose load, low-passed over ``break_filter``, exceeds
        its strength (FreeSN's rule): the pull-off and shear part of the force on the
        foot (a compression presses the shells together and is carried by contact),
        with an engaged sucker's force and strength added."""
        d = self.data
        rows = np.flatnonzero(d.efc_type[:d.nefc] == _EQUALITY)
        ids = d.efc_id[rows]
        first = rows[np.concatenate(([True], ids[1:] != ids[:-1]))] if len(rows) else rows
        force = np.zeros((self.model.neq, 3))
        force[d.efc_id[first]] = d.efc_force[first[:, None] + np.arange(3)]
        load = np.zeros(len(self.modules))
        strength = np.zeros(len(self.modules))
        factor = self.options.strength_factor
        ks = np.flatnonzero(self._parent >= 0)
        if len(ks):
            on_foot = force[self._weld_id[ks]]
            strength[ks] = factor * self.design.strength
            held = np.array(self.sucker, dtype=bool)[ks] if self.design.sucker else ks < 0
            if np.any(held):
                on_foot[held] += force[[self._suckers.id(self.modules[k]) for k in ks[held]]]
                strength[ks[held]] += factor * self.design.sucker_strength
            parents = self._parent[ks]
            out = d.xpos[self._shell[ks]] - d.xpos[self._shell[parents]]
            out /= np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-12)
            push = np.maximum(np.einsum("ki,ki->k", on_foot, out), 0.0)[:, None]
            load[ks] = np.linalg.norm(on_foot - push * out, axis=1)
        alpha = min(1.0, duration / self.options.break_filter)
        docked = strength > 0
        self._load = np.where(docked, self._load + alpha * (load - self._load), 0.0)
        for k in np.flatnonzero(docked & (self._load > strength)):
            parent = self.docked[k]
            assert parent is not None
            self._unlatch(int(k))
            self.armed[k] = None
            self.release[k] = False
            self.events.append(ConstraintEvent(self.time, self.modules[k], "break", parent,
                                               load=float(self._load[k])))
            self._load[k] = 0.0

    def _docking(self) -> bool:
        """Whether a connector is armed (a dock or a flow waits for the shells to touch)."""
        return self.armed.count(None) < len(self.armed)

    def _servo(self) -> None:
        """Drive motors: position loop on the drive joints of docked modules, bounded
        rate and torque (a DC motor's damping is the joint's own). The motors of idle
        modules (asleep, nothing new to do: :meth:`_activity`) apply nothing whatever they
        would hold, so their torques are not found (the human run's rows at rest)."""
        busy, idle = self._activity()
        tau = np.zeros((len(self.modules), 3))
        ks = np.flatnonzero((self._parent >= 0) & ~idle)
        if len(ks):
            q = self.data.qpos[self._qadr[ks][:, None] + np.arange(4)]
            error = quat_log(quat_mul(quat_conj(q), self._target[ks]))
            omega = self.options.position_gain * error
            norm = np.linalg.norm(omega, axis=1, keepdims=True)
            omega *= np.minimum(1.0, self.design.max_rate / np.maximum(norm, 1e-12))
            torque = self._damping * omega
            size = np.linalg.norm(torque, axis=1, keepdims=True)
            tau[ks] = torque * np.minimum(1.0, self.design.max_torque / np.maximum(size, 1e-12))
        if self._bearing is not None:
            bearing = self._roll_torques() + self._brakes(idle)
            if np.any(self._travel):
                self._travel_torques(tau, bearing)
        quiet = idle | (~busy & self._at_rest(
            tau, bearing if self._bearing is not None else None))
        if self._bearing is not None:
            bearing[quiet] = 0.0
            self.data.qfrc_applied[self._bearing] = bearing
        else:
            self._crawl()
        tau[quiet] = 0.0
        self.data.qfrc_applied[self._dofs] = tau
        self._wake[:] = False

    def _activity(self) -> tuple[np.ndarray, np.ndarray]:
        """Which modules (n,) are busy -- given something new to do since the last servo
        period: a goal, a roll, a travel or a dock -- and which are idle: not busy and
        asleep (MuJoCo's island sleeping, :class:`FreeformOptions` ``sleep_tolerance``).
        Every module is busy when nothing sleeps."""
        n = len(self.modules)
        if self.options.sleep_tolerance <= 0:
            return np.ones(n, dtype=bool), np.zeros(n, dtype=bool)
        busy = self._wake | self._travel | self._rolling | np.any(self._roll, axis=1)
        if self._docking():
            busy |= np.array([a is not None for a in self.armed])
        return busy, ~busy & (self.data.tree_asleep[self._tree] >= 0)

    def _at_rest(self, drive: np.ndarray, bearing: np.ndarray | None) -> np.ndarray:
        """The modules (n,) at rest: every DOF of the module slower than the sleep
        tolerance (scaled by its length) and its motors' torques (``drive``, ``bearing``
        (n, 3) [N m]) under ``_REST_TORQUE``.

        The quiet modules, whose motors apply nothing this servo period, are the idle
        ones (:meth:`_activity`) and those not busy at rest. MuJoCo puts a tree to sleep
        only when no force is applied to it, and a sleeping island does not move, so the
        holding torques would change nothing; a new goal, a dock, a roll, a contact with a
        moving module or a weld to one wakes it."""
        if self.options.sleep_tolerance <= 0:
            return np.zeros(len(self.modules), dtype=bool)
        m, d = self.model, self.data
        speed = np.maximum.reduceat(np.abs(d.qvel * m.dof_length), m.tree_dofadr)[self._tree]
        torque = np.linalg.norm(drive, axis=1)
        if bearing is not None:
            torque = np.maximum(torque, np.linalg.norm(bearing, axis=1))
        return (speed < self.options.sleep_tolerance) & (torque < _REST_TORQUE)

    def _travel_torques(self, drive: np.ndarray, bearing: np.ndarray) -> None:
        """Drive and bearing torques (n, 3) of the modules travelling in a piece (written
        into ``drive`` and ``bearing``), :meth:`command_travel`.

        Over each servo period ``dt`` the goals move: a shell's ``S_k`` by its rolling
        ``omega_k``, a connector's ``C_k`` by the piece's turn. A ball joint's goal is the
        relative rotation of its two bodies' goals -- the bearing's ``Q0^-1 S_k^-1 C_k``
        (``Q0`` its rest), the drive's ``C_i^-1 S_j W_i`` (``W_i = S_j^-1 F_i``, the weld's
        hold of the foot on the parent's shell) -- so the arm from ``C_j`` to ``C_i``,
        ``C_j^-1 C_i``, is the goals' whatever the shells do once both joints are there.
        Each joint runs the motor model of :meth:`_servo` with the goals' relative angular
        velocity fed forward: ``tau = D (omega_ff + K_p log(q^-1 q*))``, rate and torque
        bounded. Rotations are quaternions (n, 4).
        """
        d = self.data
        dt = self._every * self.options.timestep
        ks = np.flatnonzero(self._travel)
        self._anchor_goals(ks)
        for k in ks[self._keel[ks]]:
            self._travel_v[k] = self._keel_velocity(k)
        spin = self._travel_w[ks][:, None] * _EZ
        v = self._travel_v[ks]
        omega = np.column_stack([-v[:, 1], v[:, 0], np.zeros(len(ks))]) / self.design.radius + spin
        self._shell_goal[ks] = quat_mul(_quat_exp(omega * dt), self._shell_goal[ks])
        turn = _quat_exp(spin * dt)
        self._conn_goal[ks] = quat_mul(turn, self._conn_goal[ks])
        self._travel_v[ks] = _rotate(turn, self._travel_v[ks])   # a twist of the piece's frame
        shell_goal, conn_goal = self._shell_goal[ks], self._conn_goal[ks]
        goal = quat_mul(quat_conj(quat_mul(shell_goal, self._conn0[ks])), conn_goal)
        feed = _rotate(quat_conj(conn_goal), spin - omega)          # C^-1 (w_C - w_S)
        q = d.qpos[self._bearing_q[ks][:, None] + np.arange(4)]
        bearing[ks] = self._motor(q, goal, feed)
        for k in ks[self._keel[ks]]:    # one unit hangs for the whole piece's weight
            size = len(self._piece(k))
            bearing[k] = self._hang(k, self._travel_v[k], gain=size * _ROLL_SPEED_GAIN)
        rows = np.flatnonzero(self._parent[ks] >= 0)
        if not len(rows):
            return
        docked = ks[rows]
        parents = self._parent[docked]
        shell = d.xquat[self._shell[parents]]
        held = quat_mul(quat_conj(shell), d.xquat[self._foot[docked]])            # W
        moving = self._travel[parents]
        foot_goal = quat_mul(np.where(moving[:, None], self._shell_goal[parents], shell), held)
        rolling = np.zeros((len(self.modules), 3))
        rolling[ks] = omega
        feed = _rotate(quat_conj(foot_goal), rolling[parents] - spin[rows])
        q = d.qpos[self._qadr[docked][:, None] + np.arange(4)]
        drive[docked] = self._motor(q, quat_mul(quat_conj(conn_goal[rows]), foot_goal), feed)

    def _keel_velocity(self, k: int) -> np.ndarray:
        """The ground velocity (3,) [m/s] the keel ``k`` hangs toward: its piece's twist at
        its centre, taken from an arm of the piece (a travelling module that is not the
        keel), ``v_j + w e_z x (p_k - p_j)``, not its own command. Its magnet unit hangs on
        a free bearing, so it turns about the vertical with nothing holding it (4.7 deg in
        its swing down in chains-to-tree), and the gyro frame its own command is given in
        turns with it: the keel, the one module that holds the piece's velocity across its
        line, drove 2 deg off the piece's line, and the piece turned 2 deg in 13 s into the
        row it drove out beside, which it pushed 9 cm aside. ``_travel_v[k]`` when the piece
        has no other travelling module."""
        piece = self._piece(k)
        arms = piece[self._travel[piece] & ~self._keel[piece]]
        if not len(arms):
            return self._travel_v[k]
        j = int(arms.min())
        arm = self.data.xpos[self._shell[k]] - self.data.xpos[self._shell[j]]
        return self._travel_v[j] + self._travel_w[j] * _cross(_EZ, arm)

    def _anchor_goals(self, ks: np.ndarray) -> None:
        """Turn the travel goals of each travelling piece (modules ``ks``) by the rotation
        ``A`` that best takes its connectors' goals onto the connectors as they are (the
        normalised mean of ``C_k G_k^-1``, signs aligned): every goal ``G <- A G``.

        The joints track only relative goals, so ``A`` changes no joint's goal; it puts
        the goals' frame where the piece is. Without it, a rotation of the whole piece
        that no joint sees (a straight piece rolling about its own line, or turning less
        than asked) accumulates between goals and bodies, and every later rolling
        ``omega_k`` and turn ``w e_z`` is applied about axes turned by it: measured in
        ``chains-to-tree``, a chain 1.3-1.9 rad off about its line spun its shells about
        the vertical and crawled at 1-2 mm/s when told 20 mm/s. Without it the piece of
        ``test_a_piece_that_let_go_sideways_turns_then_drives_along_its_line`` goes
        0.9 cm backwards instead of 5.9 cm along (``chains-to-tree`` itself succeeds
        either way). The offset is the connectors' true attitude against their goals:
        the motors' own model, as each joint's angle is, never the control path's."""
        d = self.data
        done = np.zeros(len(self.modules), dtype=bool)
        for k in ks:
            if done[k]:
                continue
            piece = self._piece(k)
            g = piece[self._travel[piece]]
            done[g] = True
            arms = g[~self._keel[g]]    # a keel's unit hangs, it does not turn with the piece
            if not len(arms):
                continue
            off = quat_mul(d.xquat[self._conn[arms]], quat_conj(self._conn_goal[arms]))
            off *= np.where(off @ off[0] < 0, -1.0, 1.0)[:, None]
            mean = off.sum(axis=0)
            mean /= np.linalg.norm(mean)
            self._conn_goal[g] = quat_mul(np.tile(mean, (len(g), 1)), self._conn_goal[g])
            self._shell_goal[g] = quat_mul(np.tile(mean, (len(g), 1)), self._shell_goal[g])

    def _piece(self, k: int) -> np.ndarray:
        """Indices of the modules joined to module ``k`` through docks (itself included),
        ascending: a piece's sums over its modules (the travel goals' mean turn) come out
        the same under any ``PYTHONHASHSEED`` (in its ``frozenset``'s order, chains-to-tree
        ended in other bits under seeds 0 and 1)."""
        self.groups()
        assert self._joined is not None
        return self._joined.pieces[k]

    def _motor(self, q: np.ndarray, goal: np.ndarray, feed: np.ndarray) -> np.ndarray:
        """Torques (n, 3) of ball-joint motors at ``q`` (n, 4) toward the rotations
        ``goal`` (n, 4), with the angular velocities ``feed`` (n, 3) fed forward (child
        frames): the DC-motor model of :meth:`_servo`."""
        error = quat_log(quat_mul(quat_conj(q), goal))
        omega = feed + self.options.position_gain * error
        norm = np.linalg.norm(omega, axis=1, keepdims=True)
        omega *= np.minimum(1.0, self.design.max_rate / np.maximum(norm, 1e-12))
        torque = self._damping * omega
        size = np.linalg.norm(torque, axis=1, keepdims=True)
        return torque * np.minimum(1.0, self.design.max_torque / np.maximum(size, 1e-12))

    def _crawl(self) -> None:
        """Tracks of free SnailBots on the ground (a wrench on the shell, whose own floor
        friction gives way while it crawls, :meth:`_tracks`): a traction force
        ``m K (v - v_now)``, horizontal and bounded by ``_TRACTION m g``, and the
        footprint's torque holding the foot down (a PD loop on the foot's axis)."""
        d = self.data
        for k in np.flatnonzero(np.any(self._roll, axis=1) | np.any(self._wrench, axis=1)):
            body = self._shell[k]
            if self.docked[k] is not None or not np.any(self._roll[k]):
                self._wrench[k] = 0.0
                d.xfrc_applied[body] = 0.0
                continue
            speed = d.qvel[self._free_adr[k]:self._free_adr[k] + 3].copy()
            speed[2] = 0.0
            force = self.design.mass * _CRAWL_GAIN * (self._roll[k] - speed)
            force *= min(1.0, _TRACTION * self.design.mass * _GRAVITY
                         / max(float(np.linalg.norm(force)), 1e-12))
            axis = d.xmat[self._conn[k]].reshape(3, 3)[:, 2]
            torque = _FOOT_KP * np.cross(axis, -_EZ) - _FOOT_KD * d.cvel[body, :3]
            self._wrench[k] = np.concatenate([force, torque])
            d.xfrc_applied[body] = self._wrench[k]

    def _brakes(self, idle: np.ndarray) -> np.ndarray:
        """Bearing torques (n, 3), connector frames, holding braked shells where they were
        braked: a geared motor holds its position (a damping alone would let the shell
        creep under the reactions of the modules docked on it); none for the ``idle``
        modules (n,), whose motors apply nothing."""
        out = np.zeros((len(self.modules), 3))
        ks = np.flatnonzero(self._braked & ~idle)
        if len(ks):
            q = self.data.qpos[self._bearing_q[ks][:, None] + np.arange(4)]
            error = quat_log(quat_mul(quat_conj(q), self._brake_at[ks]))
            torque = _BRAKE * self._damping * self.options.position_gain * error
            size = np.linalg.norm(torque, axis=1, keepdims=True)
            out[ks] = torque * np.minimum(1.0, self.design.max_torque / np.maximum(size, 1e-12))
        return out

    def _roll_torques(self) -> np.ndarray:
        """Bearing torques (n, 3), connector frames, of free FreeBOTs rolling on the ground
        (:meth:`_hang`)."""
        out = np.zeros((len(self.modules), 3))
        for k in np.flatnonzero(np.any(self._roll, axis=1)):
            if self.docked[k] is None:
                out[k] = self._hang(k, self._roll[k])
        return out

    def _hang(self, k: int, v: np.ndarray, gain: float = _ROLL_SPEED_GAIN) -> np.ndarray:
        """Bearing torque (3,), connector frame, of module ``k``'s magnet unit (heavier at
        its magnet's end) driving its shell toward the ground velocity ``v`` (3,) [m/s].

        A pendulum drive in two loops: the centre's horizontal speed error sets how far
        ahead of the vertical the unit should hang, ``phi = clip(K_v (v - v_now),
        +-phi_max)``; a PD loop turns the unit there against the shell, whose reaction
        rolls the shell.
        """
        d = self.data
        speed = d.qvel[self._free_adr[k]:self._free_adr[k] + 3].copy()
        speed[2] = 0.0
        lead = gain * (v - speed)
        size = np.linalg.norm(lead)
        if size > _ROLL_TILT:
            lead *= _ROLL_TILT / size
        # the unit's axis should point down, turned by |lead| towards ``lead``
        tilt = float(np.linalg.norm(lead))
        want = -_EZ * np.cos(tilt) + (lead / tilt * np.sin(tilt) if tilt > 1e-12 else 0.0)
        r_conn = d.xmat[self._conn[k]].reshape(3, 3)
        error = _cross(r_conn[:, 2], want)
        omega = d.cvel[self._conn[k], :3]       # world angular velocity of the unit
        torque = _ROLL_KP * error - _ROLL_KD * omega
        size = np.linalg.norm(torque)
        if size > self.design.max_torque:
            torque *= self.design.max_torque / size
        return r_conn.T @ torque       # on the magnet unit; the shell gets the reaction

    # -- reading ------------------------------------------------------------------------

    def _headings(self) -> np.ndarray:
        """Heading [rad] of each module's horizontal frame: the twist about the vertical of
        its connector frame turned so that the body axis that was most upright at the start
        is its ``z`` (an IMU's yaw stays continuous; the twist of a frame whose reference
        axis points down would not)."""
        rot = self.data.xmat[self._conn].reshape(-1, 3, 3) @ self._upright
        quat = Rotation.from_matrix(rot).as_quat(scalar_first=True)
        return heading(quat)

    def reports(self) -> dict[str, ModuleReport]:
        """Every module's report, with the run's noise; events since the previous call.
        The noise is drawn module by module, its relative rotation before its tilt, as
        one module after another would read out."""
        d = self.data
        n = len(self.modules)
        rot = d.xmat[self._conn].reshape(-1, 3, 3)
        docked = self._parent >= 0
        before = np.cumsum(docked) - docked            # docked modules before each one
        at = np.arange(n) + before                      # where each one's readings start
        readings = np.empty((n + int(docked.sum()), 3, 3))
        readings[at[docked]] = rot[self._parent[docked]].transpose(0, 2, 1) @ rot[docked]
        tilt_at = at + docked
        readings[tilt_at] = rot_zs(-self._headings()) @ rot
        readings = self.noise.rotations(readings)
        turned = self._turned + (self._gyro.normal(0.0, self.noise.std, n)
                                 if self.noise.std else 0.0)
        odometry = np.empty((n, 3))
        odometry[:, :2] = (rot_zs(-self._heading0)[:, :2, :2] @ self._odometry[:, :, None])[..., 0]
        odometry[:, 2] = wrap_angle(turned)
        events: dict[str, list[ConstraintEvent]] = {}
        for e in self.new_events():
            events.setdefault(e.module, []).append(e)
        return {module: ModuleReport(self.docked[k], readings[tilt_at[k]],
                                     readings[at[k]] if docked[k] else None, self.sucker[k],
                                     tuple(events.get(module, ())), odometry[k])
                for k, module in enumerate(self.modules)}

    def centre(self, module: str) -> np.ndarray:
        """World position (3,) of ``module``'s centre [m] (ground truth, for tests)."""
        return self.data.xpos[self._shell[self._k(module)]].copy()

    def ground_truth(self, *, name: str = "") -> Configuration:
        """The configuration the bodies form (simulator state, never reports): the active
        dock constraints and the centre-to-centre directions, in the world's frame (the
        judge measures a behavior's shift there, along its direction turned onto this)."""
        d = self.data
        config = Configuration(self.design.robot, name=name)
        for module in self.modules:
            config.add_module(module, self.design.kind)
        for a, b in sorted(map(self._joins, self.welds.active(d))):
            z = d.xpos[self._shell[self._index[b]]] - d.xpos[self._shell[self._index[a]]]
            config.connect(a, b, z=z / np.linalg.norm(z))
        return config

    def _joins(self, key: str) -> tuple[str, str]:
        """``(module, target)`` of module ``key``'s active weld slot: the module whose
        shell it holds (``eq_obj2id``, simulator state)."""
        return key, self._owner[int(self.model.eq_obj2id[self.welds.id(key)])]

    def groups(self) -> list[frozenset[str]]:
        """Modules of each physically separate system (connected through docks): found
        again only when a dock changed since the last call (the servo loop asks for a
        travelling piece's group every period, and 568 modules cost a graph each time)."""
        docked = tuple(self.docked)
        if self._joined is None or self._joined.docked != docked:
            groups = connected_groups(self.modules, ((self.modules[k], target)
                                                     for k, target in enumerate(docked)
                                                     if target is not None))
            pieces: list[np.ndarray] = [np.empty(0, dtype=int)] * len(self.modules)
            for g in groups:
                piece = np.array(sorted(self._index[m] for m in g), dtype=int)
                for k in piece:
                    pieces[k] = piece
            self._joined = _Joined(docked, groups, pieces)
        return list(self._joined.groups)


@dataclass(frozen=True)
class _Joined:
    """:meth:`FreeformWorld.groups`' memo: the docks it was found for, the groups, and
    each module's group as module indices (one ascending array per group)."""

    docked: tuple[str | None, ...]
    groups: list[frozenset[str]]
    pieces: list[np.ndarray]


def _quat_exp(rotvec: np.ndarray) -> np.ndarray:
    """Unit quaternions (n, 4) of the rotation vectors ``rotvec`` (n, 3) [rad]."""
    angle = np.linalg.norm(rotvec, axis=1, keepdims=True)
    half = 0.5 * angle
    scale = np.where(angle > 1e-12, np.sin(half) / np.maximum(angle, 1e-12), 0.5)
    return np.hstack([np.cos(half), scale * rotvec])


def _rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Vectors ``v`` (n, 3) rotated by the unit quaternions ``q`` (n, 4)."""
    w, u = q[:, :1], q[:, 1:]
    t = 2.0 * _cross(u, v)
    return v + w * t + _cross(u, t)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross products over the last axis of (..., 3) arrays, broadcast: ``np.cross``'s,
    to the bit, without its axis handling (a third of a small robot's servo)."""
    return np.stack([a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
                     a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
                     a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]], axis=-1)


def _upright(rotation: np.ndarray) -> np.ndarray:
    """A rotation (3, 3) of body axes taking ``z`` to the axis (of +-x, +-y, +-z) of
    ``rotation`` that points most upward."""
    up = rotation.T @ _EZ                       # world up in the body frame
    axis = np.zeros(3)
    i = int(np.argmax(np.abs(up)))
    axis[i] = np.sign(up[i])
    return rotation_between(_EZ, axis)
