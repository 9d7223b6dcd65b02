"""The FreeSN MuJoCo world, built in code with ``mujoco.MjSpec``.

Bodies (FreeSN paper, section 2.1, Fig. 2):

* a node is a free steel sphere;
* a strut is a free body (a capsule between its two ends) carrying one *connector*
  body per end. The connector hangs on a ball joint whose centre is the point of the
  strut axis at ``L/2`` from the strut centre -- where the node centre lies when that
  end is docked. The connector is the part that rolls on the node (wheels, magnet
  array); its ball joint is the spherical joint of the paper's kinematics;
* docking welds the connector to the node with the connector's origin on the node's
  centre (a weld equality, activated and deactivated at run time through
  ``data.eq_active``). Strut and node are then joined by a spherical joint about the
  node's centre whose three rotations are driven by the connector's motors; loops (a
  triangle, the octahedron) close through the same welds.

Actuation (section 4.2, Fig. 11b), two models (``SimOptions.connector_drive``):

* ``"differential"``: the paper's connector, two wheels that roll the strut end along
  their heading and turn the strut about its axis, gripping sideways. Each wheel motor
  is a velocity actuator on the ball joint in the strut's frame (its back-EMF implicit,
  its torque bounded, :meth:`FreeSNWorld._drive`), the grip Coulomb friction on a tendon
  through the contact point (:meth:`FreeSNWorld._add_drive`), and the connector turns,
  then rolls toward its target (:meth:`FreeSNWorld._steer`). A stopped wheel pair (a
  connector at its target, or the rolling of one turning in place) is braked: its gear
  train is not back-driven, so the wheels grip the shell in rolling and turning as they
  grip sideways, up to their friction (:meth:`FreeSNWorld._hold_wheels`);
* ``"holonomic"`` (the default): three torques on the ball joint. The motors are DC
  motors: a passive damping ``D = torque / roll rate`` on the ball joint (their
  back-EMF, integrated implicitly) and a drive torque ``D * omega_cmd`` bounded by the
  torque limit, with ``omega_cmd`` from a position loop toward the commanded pose,
  bounded by the wheel speed (rolling) and the differential speed (spinning).

Wheels (sections 4.2, 7.3): a connector's wheel pair also takes a speed command (see
:mod:`.commands`). Docked, the two wheels run in opposition: the twist of the ball
joint about the strut axis is velocity-controlled (the same DC-motor model, bounded
by the torque limit) while the connection vector stays under the position loop, so
a leaf node turns against the ground as a wheel, or a strut turns about its axis.
Free, the wheels are a body on a hinge about the strut's ``y`` axis at the strut end,
whose rim stands a little past the end cap and touches only the ground (an explicit
contact pair); a velocity-controlled hinge with bounded torque (back-EMF damping on
the hinge, drive ``D_w * omega_cmd`` bounded by the wheel torque) drives the strut end
through friction. Locomotion therefore comes from contact forces alone.

A docked wheel pair holds its speed: its encoders measure the spin of the node against
the strut, and a speed loop adds the integrated lag (``_SPIN_GAIN``) to the drive's
command, so a load no longer makes the spin droop (``D (omega_cmd - omega)`` alone ran a
node of fig22(j) at a quarter of the spin asked, issue 31) until the torque limit.
The other connectors on a node its wheels spin follow that spin at the servo rate: each
period their targets turn, in the node frame, against the node's rotation (its gyro)
about the spinning struts' axes. Re-aimed only at each command (10 Hz), they held the
shell in between and braked the wheel; a rotation about any other axis (the node
rolling under a load) is not followed, so they resist it.

Slip and drift: each docked connector keeps an odometry heading error ``eps`` (a
rotation about the strut axis that its encoders do not see); it grows by ``slip``
per radian rolled and by ``drift`` per square-root second. The connector servos its
*estimate*, so the physical pose is off by ``eps``, and its reports carry it.

IMU (sections 2.1, 4.2): a node reports its tilt (the accelerometer's, with the run's
``noise``) and its gyro: the mean body-frame angular rate over the last :meth:`step`
(what the IMU's samples average to), plus a constant bias per node (``gyro_bias``),
its random walk (``gyro_walk``) and white rate noise (``gyro_noise``), from a generator
of its own so the other noise draws stay as they were; and, as a real IMU's
delta-angle output, those rates integrated since it started (``turned``) with its clock
(``stamp``), so a host that missed or repeated reports still integrates exactly what
the gyro measured between two it used (issue 32). No heading is reported: the
recognizer's estimator integrates the gyros (:mod:`.recognizer`).

Sensing in the loop: a connector servos on its own sensors with the reports' noise
model (``noise``, the same seeded generator): the node's IMU attitude (one estimate per
node and tick, shared by its connectors; the readings' error low-passed at the weight
``SimOptions.fusion``, with the gyro's drift in between) turns a command into the node
frame, and its pose on the node is its encoders fused with a magnetic-localisation fix
per command (the fixes' error low-passed, ``fusion``); it never reads the true node
orientation.

Docking (Fig. 11c-d): a dock command extends the magnet array; an extended free end
docks when its magnet touches a node (the face within ``_CONTACT`` of the docked
stand-off) squarely (the strut axis within ``_ALIGNMENT`` of the node centre). Nearer
than ``dock_tolerance`` the magnet pulls on the node (:func:`magnet_pull`), a force
bounded by the connection strength, falling with the gap and, for a face pressed on
the shell askew, with its tilt, applied at the strut tip and back on the node; what
docks is only what touches. The weld then starts at the current offset of the
connector from the node centre (up to about 9 mm sideways for a face 10 deg askew) and
seats. An undock command retracts the array and
releases the weld. A connection breaks (weld released, ``break`` event) when its
low-passed constraint force exceeds the connection strength; a compressive force (the
connector pressed onto its node) is carried by contact, not by the magnet, so only the
pull-off and shear parts count.

The step loop, the dock welds and the event bookkeeping are those of every freeform
world (:class:`~msrr.core.freeform.mujoco.MujocoWorld`); this module adds the bodies,
the connectors' motors and wheels, loads and breaks, odometry and the module reports.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

from msrr.core.alignment import rot_z
from msrr.core.configuration import Configuration
from msrr.core.errors import ExecutionError
from msrr.core.freeform.mujoco import (
    GROUND_FRICTION,
    MujocoWorld,
    connected_groups,
    heading,
    quat_conj,
    quat_log,
    quat_mul,
)
from msrr.core.robot import RobotSpec

from .commands import ENDS, ConnectorTarget
from .geometry import END_SIGN, Placement, place
from .options import Physical, SimOptions

__all__ = ["INTERPENETRATION", "Accuracy", "DockEvent", "FreeSNWorld", "Interpenetration", "NodeReport",
           "StrutReport", "magnet_pull", "node_travel", "swerve_heading"]

_GAP = 0.003          # strut capsule tip to node surface when docked [m]
_ROLLER_MASS = 0.02   # rolling frame of a connector (wheels, magnet carrier) [kg]
_ARMATURE = 1e-3     # wheel-motor rotors reflected through the gearbox (~1e-7 x 100^2) [kg m^2]
_EZ = np.array([0.0, 0.0, 1.0])
_SEAT = 0.1           # time constant of a magnet drawing a docked connector onto the centre [s]
_SATURATED = 0.8      # fraction of the torque limit a saturated (stalled) motor delivers
_SATURATION_FILTER = 0.2  # time constant of the net motor torque for the saturation test [s]
_WHEEL_MASS = 0.005   # one connector's wheel pair [kg]
_WHEEL_PROUD = 0.003  # wheel rim past the node surface point of the strut end [m]
_WHEEL_FRICTION = [1.0, 1.0, 0.005, 0.0001, 0.0001]  # polyurethane on the floor
_WHEEL_ARMATURE = 1e-5  # wheel-motor rotor through its gearbox [kg m^2]
_CONTACT = 0.001      # magnet face within this of its seated stand-off: touching [m]
_ALIGNMENT = np.radians(10.0)  # strut axis to the node centre: a magnet that docks lies flat
_ATTRACTION_CONE = np.radians(45.0)  # a magnet pulls on a node in front of it
_MAGNET_FALLOFF = 0.005  # g0 = l_m / mu_r: air gap at which a face-on pull falls to 1/4 [m]
_MAGNET_HALF_WIDTH = 0.01  # half the magnet array's face (it sits between wheels 30 mm apart) [m]
_TWIST_FUSION = 0.2  # weight of a strut accelerometer's twist reading (10 Hz: 0.45 s)
_GRIP_LEVER = 0.05    # a grip tendon's length: contact point to its anchor along the axle [m]
_GRIP_SOLIMP = [0.999, 0.9999, 0.001, 0.5, 2.0]  # a stiff grip (MuJoCo's default creeps)
_GRIPS = ("grip", "roll", "turn")  # a connector's friction tendons: sideways, wheels braked
_ANCHORS = ((0.0, _GRIP_LEVER), (_GRIP_LEVER, 0.0), (_GRIP_LEVER, _GRIP_LEVER))
"""Each tendon's node-side anchor, (x, y) in the strut's axes on the contact's tangent
plane: one lever along the axle (sideways slip), ahead (rolling), ahead and sideways from
a point one lever ahead (turning about the contact normal)."""
_HUB = 3   # a node this many docked connectors hold: a soft end there winds a capped integral
_STILL_ON = np.radians(0.3)   # a connector this near its target stops, its wheels braked
_STILL_OFF = np.radians(0.6)  # ... until pushed this far off it
_TURN_ON = np.radians(5.0)     # a connector this far from its target turns toward it first
_TURN_OFF = _STILL_ON   # ... and rolls straight (no turning) once this near
_HEADING_OK = np.radians(5.0)  # heading error under which a turning connector rolls fully
_HEADING_HOLD = np.radians(1.0)  # ... and under which it stops turning, its turn braked
_HEADING_GO = np.radians(15.0)  # ... and over which it only turns (the firmware's 5 degrees)
_WAY_KEPT = np.radians(90.0)  # ... turning on a small swing, the way kept until this much better
_ROLLER_AIM = 0.5  # a wheeling connector's aim takes at most this of a wheel's torque, the spin the rest
_SPIN_GAIN = 20.0  # a docked wheel pair's speed loop: command per rad of spin lag [1/s]
_LEVEL_FROM = np.radians(100.0)  # a held node's shell tilted past this is levelled back ...
_LEVEL_GAIN = 0.5               # ... by this fraction of the excess at each command ...
_LEVEL_STEP = np.radians(5.0)   # ... and at most this much (issue 31, fig18's hub)
_LEVEL_HOLDS = 3                # ... if it holds this many connectors (a chain node, two, is not)
_LEVEL_BELOW = -np.sin(np.radians(10.0))  # ... and, not a root, a strut commanded this far down
_AZIMUTH_FROM = np.sin(np.radians(10.0))  # a leg nearer the vertical has no level axle
_AXLE_LEVEL = np.sin(np.radians(10.0))  # a free wheel pair's axle built this near level is
# held level (the ride a pair is built for, :meth:`FreeSNWorld._ride_of`)


@dataclass(frozen=True)
class DockEvent:
    """A connector's docking event.

    Attributes:
        time: [s]. strut, end: the connector. node: the node it docked to or left.
        kind: ``"dock"``, ``"undock"`` (commanded) or ``"break"`` (load over strength).
        load: filtered connection force at the event [N] (breaks only).
    """

    time: float
    strut: str
    end: str
    node: str
    kind: str
    load: float = 0.0


INTERPENETRATION = 0.003
"""Depth [m] past which two module bodies interpenetrate: a self-collision. Their
contacts (:data:`_BODY_SOLREF`) let bodies pressed together sink in by a fraction of
that."""

_BODY_SOLREF = (0.005, 1.0)
"""MuJoCo ``solref`` (time constant [s], damping ratio) of contacts between module
bodies: a quarter of MuJoCo's default 20 ms (2.5 physics steps; MuJoCo asks for at
least 2), so a strut end pushed on a shell by its magnet and the connection strength
sinks about 1 mm, not the 4 mm that read as interpenetration. A soft contact's depth
under a load goes with the time constant squared. Contacts with the floor keep the
default (the ground's ``priority`` makes its parameters the contact's)."""


@dataclass(frozen=True)
class Interpenetration:
    """Two module bodies interpenetrating past :data:`INTERPENETRATION`.

    Attributes:
        a, b: the modules (sorted). time: when they first did [s]. depth: how deep then
            [m]. deepest: the deepest since [m].
    """

    a: str
    b: str
    time: float
    depth: float
    deepest: float

    def __str__(self) -> str:
        return (f"{self.a} and {self.b} interpenetrate by {1000 * self.depth:.1f} mm at "
                f"t={self.time:.2f} s (deepest {1000 * self.deepest:.1f} mm)")


@dataclass(frozen=True)
class Accuracy:
    """What a module's sensors are stated to measure to (their data sheets; a report
    carries it as a ROS sensor message carries its covariance): the report filter
    (:mod:`.filtering`) takes its gains from these, never from the readings' truth.

    Attributes:
        angle: standard deviation of every reported angle (IMU tilt, magnetic
            localisation, strut attitude) per axis [rad], white per report.
        slip: standard deviation of a connector's encoded rolling per radian rolled
            [rad / rad]. drift: its random walk [rad / sqrt(s)].
        gyro_noise: the node gyro's angle random walk [rad / sqrt(s)].
        gyro_bias: standard deviation of its bias left after calibration [rad/s].
        gyro_walk: the random walk of that bias [rad/s / sqrt(s)].
    """

    angle: float = 0.0
    slip: float = 0.0
    drift: float = 0.0
    gyro_noise: float = 0.0
    gyro_bias: float = 0.0
    gyro_walk: float = 0.0


@dataclass(frozen=True)
class NodeReport:
    """What a node module reports (section 2.1).

    Attributes:
        tilt: rotation (3, 3) of the node in its own horizontal frame (IMU; yaw-free).
        connectors: ``"<strut>:<end>"`` -> unit vector (3,) in the node frame where that
            connector sits (magnetic localisation).
        gyro: the node's angular rate (3,) in its own frame [rad/s], averaged over the
            last step, with the gyro's bias, drift and noise.
        accuracy: what its sensors are stated to measure to.
        turned: the gyro's delta-angle counter: the rotation (3, 3) its rates integrated
            since the module started, node frame then -> now (``Q <- Q exp([w dt])`` per
            step, the reported ``w``), so ``Q_0^T Q_1`` is what it measured between two
            readings however many reports lay between (as
            :attr:`StrutReport.rolled` is for the encoders).
        stamp: the module's clock [s] when ``turned`` and ``gyro`` were read (``None``:
            a report without one; the report filter then assumes every report is new).
        step: the length [s] of the last step, the one ``gyro`` averages, ending at
            ``stamp``.
    """

    tilt: np.ndarray
    connectors: dict[str, np.ndarray]
    gyro: np.ndarray = field(default_factory=lambda: np.zeros(3))
    accuracy: Accuracy = Accuracy()
    turned: np.ndarray = field(default_factory=lambda: np.eye(3))
    stamp: float | None = None
    step: float = 0.0


@dataclass(frozen=True)
class StrutReport:
    """What a strut module reports (section 4.2, Fig. 11a).

    Attributes:
        docked: per end, the node the connector is docked to, or ``None``.
        attitude: per docked end, the strut's rotation (3, 3) in that node's horizontal
            frame (IMU + odometry); its ``z`` column is the strut axis from end a to b.
        tilt: the strut's rotation in its own horizontal frame (IMU alone).
        magnet: per end, ``"neutral"``, ``"extended"`` or ``"retracted"``.
        events: docking events of its connectors since the previous report.
        rolled: per docked end, the strut's rotation (3, 3) on its node since the end
            docked, in the node frame, as the connector's wheel encoders count it
            (``E(t) E(t_dock)^T``, ``E`` the strut's rotation in the node frame): relative
            only, with the connector's slip and drift, no localisation noise.
        accuracy: what its sensors are stated to measure to.
    """

    docked: dict[str, str | None]
    attitude: dict[str, np.ndarray]
    tilt: np.ndarray
    magnet: dict[str, str]
    events: tuple[DockEvent, ...] = ()
    rolled: dict[str, np.ndarray] = field(default_factory=dict)
    accuracy: Accuracy = Accuracy()


def _inertia_rod(mass: float, radius: float, length: float) -> list[float]:
    across = mass * (3 * radius**2 + length**2) / 12.0
    return [across, across, 0.5 * mass * radius**2]


class FreeSNWorld(MujocoWorld[tuple[str, str, str], DockEvent]):
    """One configuration of FreeSN modules in MuJoCo (its welds keyed ``(strut, end, node)``).

    Args:
        config: the starting configuration (nodes, struts with ``z``); its docked
            strut ends start docked.
        spec: the robot description (``node`` and ``strut`` geometry).
        options: the run's options.
    """

    options: SimOptions
    _holder: np.ndarray   # each end's node's one holder, or -1 (set by every servo step)

    def __init__(self, config: Configuration, spec: RobotSpec, options: SimOptions):
        super().__init__(options, seat=_SEAT)
        self.phys = phys = Physical.from_spec(spec, options)
        self._differential = options.connector_drive == "differential"
        self.placement = place(config, phys.strut_length, phys.node_radius, phys.strut_radius)
        self.nodes = [v for v in config.vertices() if not config.is_virtual(v)]
        self.struts = [e.id for e in config.edges()]
        self.ends = [(s, e) for s in self.struts for e in ENDS]
        self.compile(self._build(self.placement))
        m = self.model
        self._node_body = np.array([m.body(f"node/{n}").id for n in self.nodes], dtype=int)
        self._strut_body = np.array([m.body(f"strut/{s}").id for s in self.struts], dtype=int)
        self.bodies = {name: int(body) for name, body in
                       [*zip(self.nodes, self._node_body, strict=True),
                        *zip(self.struts, self._strut_body, strict=True)]}
        self._conn_body = np.array([m.body(f"connector/{s}/{e}").id for s, e in self.ends],
                                   dtype=int)
        joints = [m.joint(f"ball/{s}/{e}") for s, e in self.ends]
        self._qadr = np.array([j.qposadr[0] for j in joints], dtype=int)
        self._dadr = np.array([j.dofadr[0] for j in joints], dtype=int)
        self._sign = np.array([END_SIGN[e] for _, e in self.ends])
        self._node_index = {n: i for i, n in enumerate(self.nodes)}
        self._strut_index = {s: j for j, s in enumerate(self.struts)}
        self._end_index = {end: k for k, end in enumerate(self.ends)}
        k = len(self.ends)
        self.docked: list[str | None] = [None] * k
        self.magnet = ["neutral"] * k
        self._target = np.tile(np.eye(3), (k, 1, 1))   # believed node->strut rotation target
        self._has_target = np.zeros(k, dtype=bool)
        self._ball_target = np.tile(np.array([1.0, 0, 0, 0]), (k, 1))
        self._conn_node = np.tile(np.eye(3), (k, 1, 1))  # connector->node rotation while docked
        self._eps = np.zeros(k)                            # odometry heading error [rad]
        self._fix = np.zeros((k, 3))                       # localisation error, node frame [rad]
        self._imu: dict[int, np.ndarray] = {}              # node tilt readings this tick
        self._attitude = np.zeros((len(self.nodes), 3))   # node attitude error [rad]
        self._fused_at: dict[int, float] = {}              # node -> time of its last fusion [s]
        self._load = np.zeros(k)
        self._eq = np.full(k, -1, dtype=int)               # active weld of each end, or -1
        self._driven = np.zeros(0, dtype=int)             # docked ends with a target
        self._torque = np.zeros((k, 2))                    # wheel motor torques [N m]
        self._turning = np.zeros(k, dtype=bool)            # turning toward a target
        self._backwards = np.zeros(k, dtype=bool)          # ... to roll there backwards
        self._twist_free = np.zeros(k, dtype=bool)         # target twist left to the turns
        self._ride = np.full((k, 2), np.nan)   # axle as docked: (cos, sin) from level
        self._integral = np.zeros((k, 3))                  # position loop's error integral [rad s]
        self._effort = np.ones(k)                          # fraction of the torque limit
        self._braked = np.zeros(k, dtype=bool)             # held by command_brake
        self._saturated_since = np.full(k, np.nan)        # start of each saturation streak [s]
        self._net_torque = np.zeros(k)                     # low-passed motor torque net of EMF
        self._axle = np.array([m.joint(f"axle/{s}/{e}").dofadr[0] for s, e in self.ends],
                              dtype=int)
        self._wheel = np.zeros(k)                          # commanded wheel speed [rad/s]
        self._travel = np.zeros((k, 2))                    # node wheel's travel: along, across
        self._swerved = np.zeros(k, dtype=bool)            # twist set by _swerve this servo step
        self._spin_lag = np.zeros(k)                       # wheel spin asked - measured [rad]
        self._node_rate = 3 + np.array([m.joint(f"free/{n}").dofadr[0] for n in self.nodes])
        self._index_drives(self.ends if self._differential else [])
        self._still = np.zeros(k, dtype=bool)              # at its target: wheels braked
        self._aim = np.zeros((k, 3))                       # last commanded direction, horizontal
        self._dofs = self._dadr[:, None] + np.arange(3)
        self._tau = np.zeros((k, 3))                       # holonomic connectors' torques
        self._grip_at = np.array([[[x, y, sign * phys.node_radius] for x, y in _ANCHORS]
                                  for sign in self._sign])   # (k, 3, 3), strut axes
        self._last_ball = np.tile(np.array([1.0, 0, 0, 0]), (k, 1))
        self._index_geoms()
        self.interpenetrations: dict[tuple[str, str], Interpenetration] = {}
        self._init_gyros(options)
        self._accuracy = Accuracy(options.noise, options.slip, options.drift,
                                  options.gyro_noise, options.gyro_bias, options.gyro_walk)
        self._encoded: dict[int, tuple[str, np.ndarray]] = {}  # end -> (node, E at dock)
        self._node_rot = np.tile(np.eye(3), (len(self.nodes), 1, 1))
        mujoco.mj_forward(self.model, self.data)
        for s, (a, b) in self.placement.ends.items():
            for end, node in zip(ENDS, (a, b), strict=True):
                if node is not None:
                    self._dock(self._end_index[(s, end)], node, event=False)
        mujoco.mj_forward(self.model, self.data)
        self._record_interpenetrations()

    def _index_geoms(self) -> None:
        """Each module's index in ``_modules`` by its geom's id (-1: not a module's)."""
        m = self.model
        self._modules = [*self.nodes, *self.struts]
        self._geom_module = np.full(m.ngeom, -1, dtype=int)
        self._geom_module[[m.geom(f"sphere/{n}").id for n in self.nodes]] = \
            np.arange(len(self.nodes))
        self._geom_module[[m.geom(f"capsule/{s}").id for s in self.struts]] = \
            len(self.nodes) + np.arange(len(self.struts))

    def _index_drives(self, drives: list[tuple[str, str]]) -> None:
        """The ids of the differential drives' wheel motors (k, 2), tendon anchors (k, 3:
        ``_GRIPS``) and brake tendons (k, 2: rolling, turning)."""
        m = self.model
        self._motor = np.array([[m.actuator(f"wheel/{s}/{e}/{side}").id
                                 for side in ("left", "right")] for s, e in drives],
                               dtype=int).reshape(-1, 2)
        self._grip_site = np.array([[m.site(f"{t}/{s}/{e}").id for t in _GRIPS]
                                    for s, e in drives], dtype=int).reshape(-1, 3)
        self._brake = np.array([[m.tendon(f"{t}/{s}/{e}").id for t in _GRIPS[1:]]
                                for s, e in drives], dtype=int).reshape(-1, 2)

    def _init_gyros(self, options: SimOptions) -> None:
        """The node gyros: a seeded bias each; the reports' draws (``"gy"``) and the
        servo's samples (``"sg"``) from generators of their own."""
        self._gyro_rng, self._servo_gyro_rng = (np.random.default_rng([options.seed, tag])
                                                for tag in (0x6779, 0x7367))
        self._gyro_bias = self._gyro_rng.normal(0.0, options.gyro_bias, (len(self.nodes), 3))
        self._gyro = np.zeros((len(self.nodes), 3))        # last reported rates [rad/s]
        self._turned = np.tile(np.eye(3), (len(self.nodes), 1, 1))   # delta-angle counters
        self._gyro_step = 0.0                              # the step those rates average [s]

    # -- building ---------------------------------------------------------------------

    def _build(self, placement: Placement) -> mujoco.MjSpec:
        p = self.phys
        spec = self.new_spec("freesn")
        spec.geom("ground").priority = 1   # the floor's contact parameters are its own
        shell = 2.0 / 3.0 * p.node_mass * p.node_radius**2  # thin steel shell
        for node in self.nodes:
            body = spec.worldbody.add_body(name=f"node/{node}", pos=placement.nodes[node],
                                           mass=p.node_mass, inertia=[shell] * 3,
                                           explicitinertial=True, ipos=[0, 0, 0],
                                           iquat=[1, 0, 0, 0])
            body.add_freejoint(name=f"free/{node}")
            body.add_geom(name=f"sphere/{node}", type=mujoco.mjtGeom.mjGEOM_SPHERE,
                          size=[p.node_radius, 0, 0], friction=GROUND_FRICTION, mass=0,
                          solref=list(_BODY_SOLREF), rgba=[0.6, 0.6, 0.65, 1.0])
        tip = 0.5 * p.strut_length - p.node_radius - _GAP
        segment = max(tip - p.strut_radius, 1e-4)
        rod = p.strut_mass - 2.0 * p.connector_mass
        if rod <= 0:
            raise ExecutionError("strut mass must exceed the mass of its two connectors")
        inertia = np.array(_inertia_rod(rod, p.strut_radius, 2 * tip))
        inertia[:2] += 2.0 * p.connector_mass * tip**2
        reach = 0.5 * p.strut_length - p.node_radius + _WHEEL_PROUD - p.wheel_radius
        wheel_inertia = 0.5 * _WHEEL_MASS * p.wheel_radius**2
        for strut in self.struts:
            centre, rotation = placement.struts[strut]
            quat = Rotation.from_matrix(rotation).as_quat(scalar_first=True)
            body = spec.worldbody.add_body(name=f"strut/{strut}", pos=centre, quat=quat,
                                           mass=p.strut_mass, inertia=inertia.tolist(),
                                           explicitinertial=True, ipos=[0, 0, 0],
                                           iquat=[1, 0, 0, 0])
            body.add_freejoint(name=f"free/{strut}")
            body.add_geom(name=f"capsule/{strut}", type=mujoco.mjtGeom.mjGEOM_CAPSULE,
                          fromto=[0, 0, -segment, 0, 0, segment], size=[p.strut_radius, 0, 0],
                          friction=GROUND_FRICTION, mass=0, solref=list(_BODY_SOLREF),
                          rgba=[0.9, 0.55, 0.1, 1.0])
            for end in ENDS:
                roller = body.add_body(name=f"connector/{strut}/{end}",
                                       pos=[0, 0, -END_SIGN[end] * 0.5 * p.strut_length],
                                       mass=_ROLLER_MASS, inertia=[1e-7] * 3,
                                       explicitinertial=True, ipos=[0, 0, 0],
                                           iquat=[1, 0, 0, 0])
                roller.add_joint(name=f"ball/{strut}/{end}", type=mujoco.mjtJoint.mjJNT_BALL,
                                 damping=0.0 if self._differential else p.damping,
                                 armature=_ARMATURE)
                if self._differential:
                    self._add_drive(spec, body, roller, strut, end)
                wheel = body.add_body(name=f"wheel/{strut}/{end}",
                                      pos=[0, 0, -END_SIGN[end] * reach],
                                      mass=_WHEEL_MASS, inertia=[wheel_inertia] * 3,
                                      explicitinertial=True, ipos=[0, 0, 0],
                                      iquat=[1, 0, 0, 0])
                wheel.add_joint(name=f"axle/{strut}/{end}", type=mujoco.mjtJoint.mjJNT_HINGE,
                                axis=[0, 1, 0], damping=p.wheel_damping,
                                armature=_WHEEL_ARMATURE)
                wheel.add_geom(name=f"wheels/{strut}/{end}", type=mujoco.mjtGeom.mjGEOM_CYLINDER,
                               fromto=[0, -0.5 * p.wheel_base, 0, 0, 0.5 * p.wheel_base, 0],
                               size=[p.wheel_radius, 0, 0], mass=0, contype=0, conaffinity=0,
                               rgba=[0.15, 0.15, 0.15, 1.0])
                spec.add_pair(name=f"floor/{strut}/{end}", geomname1=f"wheels/{strut}/{end}",
                              geomname2="ground", condim=3, friction=_WHEEL_FRICTION)
        for strut in self.struts:
            for end in ENDS:
                for node in self.nodes:
                    self.add_weld(spec, (strut, end, node), f"dock/{strut}/{end}/{node}",
                                  f"connector/{strut}/{end}", f"node/{node}")
        return spec

    def _add_drive(self, spec: mujoco.MjSpec, strut_body: mujoco.MjsBody,
                   roller: mujoco.MjsBody, strut: str, end: str) -> None:
        """A connector's differential drive on its ball joint (Fig. 11): two wheel motors
        and the wheels' side grip.

        Each wheel motor is a velocity actuator on the ball joint in the strut's frame
        (``jointinparent``, the wheels sit on the strut end) with gear ``rho y -+ tau z``
        (``rho = R / r`` wheel radians per radian rolled about the node centre, ``tau =
        b / 2r`` per radian turned about the strut axis): its velocity is the wheel's
        speed and its gain the motor's back-EMF damping ``D_w``, integrated implicitly;
        :meth:`_drive` bounds its torque. The grip is Coulomb friction on a spatial
        tendon from the wheels' contact point on the node (a strut site) to a point one
        lever sideways along the axle on the node (a connector site that
        :meth:`_place_grips` keeps there): the tendon's rate is the sideways slip of the
        contact, held at zero up to ``grip`` newtons (``frictionloss``, solved as a
        constraint), skidding beyond.
        """
        p = self.phys
        sign = END_SIGN[end]
        contact = -sign * (0.5 * p.strut_length - p.node_radius)
        strut_body.add_site(name=f"contact/{strut}/{end}", pos=[0.0, 0.0, contact])
        strut_body.add_site(name=f"ahead/{strut}/{end}", pos=[_GRIP_LEVER, 0.0, contact])
        for name, start, at in zip(_GRIPS, ("contact", "contact", "ahead"), _ANCHORS,
                                   strict=True):   # the anchors move: _place_grips
            roller.add_site(name=f"{name}/{strut}/{end}", pos=[*at, sign * p.node_radius])
            friction = p.grip if name == "grip" else 0.0   # the brakes: _hold_wheels
            tendon = spec.add_tendon(name=f"{name}/{strut}/{end}", frictionloss=friction,
                                     solimp_friction=_GRIP_SOLIMP)
            tendon.wrap_site(f"{start}/{strut}/{end}")
            tendon.wrap_site(f"{name}/{strut}/{end}")
        for side, turn in (("left", -1.0), ("right", 1.0)):
            motor = spec.add_actuator(name=f"wheel/{strut}/{end}/{side}",
                                      target=f"ball/{strut}/{end}",
                                      trntype=mujoco.mjtTrn.mjTRN_JOINTINPARENT,
                                      gear=[0.0, p.roll_ratio, turn * p.turn_ratio, 0, 0, 0])
            motor.set_to_velocity(kv=0.5 * p.wheel_damping)

    # -- docking ----------------------------------------------------------------------

    def _dock(self, k: int, node: str, *, event: bool = True) -> None:
        strut, end = self.ends[k]
        # the connector where it is now; the magnet then draws it onto the node's centre
        eq = self.weld((strut, end, node), self._conn_body[k],
                       self._node_body[self._node_index[node]])
        self._eq[k] = eq
        self.docked[k] = node
        self._conn_node[k] = Rotation.from_quat(self.model.eq_data[eq, 6:10],
                                                scalar_first=True).as_matrix()
        self.magnet[k] = "neutral"   # back to the origin after the dock (section 4.2)
        self._load[k] = 0.0
        self._hold(k)
        if event:
            self.events.append(DockEvent(self.time, strut, end, node, "dock"))

    def _release(self, k: int, kind: str) -> None:
        node = self.docked[k]
        if node is None:
            return
        strut, end = self.ends[k]
        self.welds.off(self.data, (strut, end, node))
        self._eq[k] = -1
        self._set_effort(k, 1.0)
        self.docked[k] = None
        self._encoded.pop(k, None)   # a new dock starts a new count
        self._has_target[k] = False
        self._ride[k] = np.nan
        self._braked[k] = False
        self._refresh_driven()
        self._eps[k] = 0.0
        self._fix[k] = 0.0
        self._turning[k] = self._backwards[k] = False
        self.events.append(DockEvent(self.time, strut, end, node, kind, float(self._load[k])))
        self._load[k] = 0.0

    def _hold(self, k: int) -> None:
        """Brake connector ``k`` where it believes it is."""
        self._target[k] = self._believed(np.array([k]))[0]
        self._has_target[k] = True
        self._twist_free[k] = False
        self._refresh_driven()

    def _refresh_driven(self) -> None:
        self._driven = np.flatnonzero(self._has_target & (self._eq >= 0))
        idle = np.ones(len(self._integral), dtype=bool)
        idle[self._driven] = False
        self._integral[idle] = 0.0
        self._spin_lag[idle] = 0.0

    def command_stop(self, strut: str) -> None:
        """Stop ``strut``'s connectors where they are now (motors braked)."""
        for end in ENDS:
            k = self._end(strut, end)
            self._wheel[k] = 0.0
            self._travel[k] = 0.0
            self._braked[k] = False
            if self.docked[k] is not None:
                self._set_effort(k, 1.0)
                self._hold(k)

    def command_wheels(self, strut: str, end: str, speed: float) -> None:
        """Run the wheel pair of ``strut``'s ``end`` at ``speed`` [rad/s] (see :mod:`.commands`).

        Bounded by the wheel motors' top speed. Setting ``0`` on a docked connector that
        was spinning brakes its twist where it is now.
        """
        k = self._end(strut, end)
        speed = float(np.clip(speed, -self.phys.max_wheel_speed, self.phys.max_wheel_speed))
        was = self._wheel[k]
        self._wheel[k] = speed
        if self.docked[k] is not None and (not self._has_target[k] or (was and not speed)):
            self._hold(k)

    def command_travel(self, strut: str, end: str, along: float, across: float) -> None:
        """The body's commanded translation at the node ``strut``'s ``end`` spins as a
        wheel, ``along`` the way the wheel rolls it and ``across`` along the strut's plan
        direction, in its wheel speed's scale (see :mod:`.commands`; both 0: none). The
        differential connectors steer that node's other struts by it (:meth:`_swerve`)."""
        self._travel[self._end(strut, end)] = (float(along), float(across))

    def wheel_speed(self, strut: str, end: str) -> float:
        """The speed [rad/s] ``strut``'s ``end`` runs its wheel pair at (0: not running)."""
        return float(self._wheel[self._end(strut, end)])

    def command_dock(self, strut: str, end: str) -> None:
        """Extend the magnet array of ``strut``'s ``end`` (kept until it docks)."""
        k = self._end(strut, end)
        if self.docked[k] is None:
            self.magnet[k] = "extended"

    def command_undock(self, strut: str, end: str) -> None:
        """Retract the magnet array of ``strut``'s ``end``: the connection is released."""
        k = self._end(strut, end)
        self.magnet[k] = "retracted"
        self._release(k, "undock")

    def command_brake(self, strut: str, end: str, effort: float = 1.0) -> None:
        """Brake a docked connector where it is on its node (kept while repeated: the
        pose when the brake began), at ``effort``; ignored when the end is free."""
        k = self._end(strut, end)
        if self.docked[k] is None:
            return
        self._set_effort(k, effort)
        if not self._braked[k]:
            self._hold(k)
            self._braked[k] = True

    def command_target(self, strut: str, end: str, target: ConnectorTarget) -> None:
        """Drive a docked connector to a connection vector (and forward vector) given in
        the horizontal frame of its node; ignored when the end is free."""
        k = self._end(strut, end)
        node = self.docked[k]
        if node is None:
            return
        direction, forward, effort = target
        self._aim[k] = direction
        self._set_effort(k, effort)
        self._braked[k] = False
        to_node = self._node_tilt(self._node_index[node])   # horizontal -> node frame
        self._localise(k)
        self._level_fix(k)
        want = to_node @ direction
        current = self._believed(np.array([k]))[0]   # node -> strut, believed
        u = self._sign[k] * _EZ
        if forward is None:
            # a leaf strut's connector keeps the twist it holds (its wheels braked in
            # that rotation) rather than the one it was pushed to: the morphology of
            # its free end's wheels, or the leg of a foot (a leaf node), which would
            # otherwise let the foot roll sideways by twisting the leg; a strut in a loop
            # follows its other end's pull. A leaf strut rolling on its free end's wheels
            # holds their axle level (:func:`_level`), not the twist it was built with
            far = self._end_index[(strut, "b" if end == "a" else "a")]
            other = self.docked[far]
            leaf = other is None or self.docked.count(other) == 1
            keep = leaf and self._has_target[k] and not self._wheel[k]
            level = None
            ride = self._ride_of(k, to_node @ _EZ)
            if keep and other is None and self._wheel[far]:   # rolling on its free wheels
                level = _level(self._sign[k] * want, to_node @ _EZ, ride)
            if keep:
                current = self._target[k]
            have = current @ u
            self._target[k] = _minimal(have, want) @ current if level is None else level
            self._twist_free[k] = not keep   # else the turns on the way set its twist
        else:
            self._target[k] = _frame(self._sign[k] * want, to_node @ forward)
            self._twist_free[k] = False
        self._has_target[k] = True
        self._refresh_driven()

    def _set_effort(self, k: int, effort: float) -> None:
        """Connector ``k``'s torque fraction; ``0`` coasts: its drivers off, so neither
        drive nor back-EMF damping (the ball joint turns freely; a differential drive's
        wheels still grip sideways)."""
        self._effort[k] = effort
        if not self._differential:
            self.model.dof_damping[self._dofs[k]] = self.phys.damping if effort > 0.0 else 0.0
            return
        kv = 0.5 * self.phys.wheel_damping if effort > 0.0 else 0.0
        self.model.actuator_gainprm[self._motor[k], 0] = kv
        self.model.actuator_biasprm[self._motor[k], 2] = -kv

    def _end(self, strut: str, end: str) -> int:
        try:
            return self._end_index[(strut, end)]
        except KeyError:
            raise ExecutionError(f"no connector {strut}:{end} in this world (struts: "
                                 f"{', '.join(self.struts)})") from None

    # -- state ------------------------------------------------------------------------

    def _ball(self, ks: np.ndarray) -> np.ndarray:
        return self.data.qpos[self._qadr[ks][:, None] + np.arange(4)]

    def _ride_of(self, k: int, up: np.ndarray) -> np.ndarray:
        """How docked connector ``k``'s free wheels ride, as it was built or docked: the
        cosine and sine (2,) of its axle's turn about the strut's axis ``z`` from the level
        axle ``up x z`` toward ``z x (up x z)`` (both in the node frame); ``(+-1, 0)``, level
        on that side, for an axle within ``_AXLE_LEVEL`` of level (S4N1's legs); the turn
        itself for one built tilted (S6N3's tripod legs, 27-45 deg). Read from its held
        target at its first command after the dock (``nan`` while its axis is within
        ``_AZIMUTH_FROM`` of ``up``: no level axle there).

        A property of the build, not of the twist the way leaves: a leaf strut's kept
        twist composes minimal rotations, which turn its axle by the solid angle its aim
        sweeps as the hub's shell spins under it (65 deg a turn at S4N1's 55 deg), and at
        4 deg + 10 % S4N1's legs reached their wheels' start 11-15 deg off level (seeds 13
        and 17): taken by the current tilt for a pair built tilted, they were not levelled,
        their axles twisted on past the vertical while they drove, and, level again on the
        reversed side, held there: every wheel rolled backwards (issue 31, stop 50)."""
        if np.isnan(self._ride[k, 0]):
            held = self._target[k]
            z = held @ (self._sign[k] * _EZ)
            side = np.cross(up, z)
            norm = float(np.linalg.norm(side))
            if norm >= _AZIMUTH_FROM:
                axle, side = held[:, 1], side / norm
                if abs(float(axle @ up)) <= _AXLE_LEVEL:
                    self._ride[k] = (1.0 if float(axle @ side) >= 0.0 else -1.0, 0.0)
                else:
                    turn = np.arctan2(float(axle @ np.cross(z, side)), float(axle @ side))
                    self._ride[k] = (np.cos(turn), np.sin(turn))
        return self._ride[k]

    def _node_tilt(self, i: int) -> np.ndarray:
        """Node frame from node ``i``'s horizontal frame (3, 3), as its connectors get
        it: the transpose of its attitude estimate (the node's rotation in its horizontal
        frame; one estimate per node and tick, shared by its connectors). The node's IMU
        fuses each accelerometer reading, with the reports' noise, into its gyro-propagated
        attitude as the connectors fuse their fixes: the estimate's error is the readings'
        error low-passed, ``a <- (1 - b) (a + g dt) + b n`` (``b`` the option ``fusion``;
        ``g dt`` the node gyro's bias over the time since the last fusion, the drift the
        reading corrects). A raw reading per tick would make every connector chase a fresh
        2 deg jitter and the loop a chain closes would never settle (fig21's last dock,
        issue 31); at ``b`` = 0.2 fig22(j)'s held top sank at 4 deg (issue 31, stop 47).

        The shell of a node its connectors hold is free under them, so it ends where each
        estimate puts it: it takes every estimate's error for good, and any torque its
        connectors pass on (node wheels' reaction), and rolls away. Near upside down its
        horizontal frame, the frame every command is in, is singular (the twist about the
        vertical, :func:`~msrr.core.freeform.mujoco.heading`): fig18's hub rolled over in
        16-60 s at 4 deg of noise, its frame spun under the commands and a hub connection
        broke. A non-root node's frame cancels out of its commands (they turn by its
        measured heading relative to the root's) only while the report filter follows its
        heading, which it does not past its upright bound (issue 31, stop 57). So the
        connectors of a root, or of a node its struts hold up, that holds three or more of
        them and spins on none (not a foot, not a wheel: rolling its shell would move it)
        aim as if its
        shell were ``_LEVEL_GAIN`` of its tilt past ``_LEVEL_FROM`` nearer upright (at
        most ``_LEVEL_STEP`` a command): the shell turns back, the struts stay where the
        rest of the structure holds them. Past 100 deg only: fig20's and fig21's nodes
        tilt up to 91 and 76 deg in exact runs, which this leaves to the bit; levelling
        every held node moved fig22's exact node wheels (0.560 -> 0.526 m, 0.4 -> 6.1
        deg)."""
        if i not in self._imu:
            body = self._node_body[i]
            tilt = rot_z(-float(heading(self.data.xquat[body])))
            if self.noise.std:
                sample = self.noise.rng.normal(0.0, self.noise.std, 3)
                drift = tilt @ self.data.xmat[body].reshape(3, 3) @ self._gyro_bias[i] * (
                    self.time - self._fused_at.get(i, self.time))
                self._fused_at[i] = self.time
                b = self.options.fusion
                self._attitude[i] += drift + b * (sample - self._attitude[i] - drift)
                tilt = Rotation.from_rotvec(self._attitude[i]).as_matrix() @ tilt
            attitude = tilt @ self.data.xmat[body].reshape(3, 3)   # node in horizontal frame
            fitted = self._fitted(i)
            self._imu[i] = (self._levelled(i, attitude) @ attitude).T if fitted is None \
                else fitted
        return self._imu[i]

    def _fitted(self, i: int) -> np.ndarray | None:
        """The frame (3, 3), node from horizontal, in which node ``i``'s legs stand where
        they are asked to, as near as a rotation brings them (Wahba's problem, solved by
        SVD): for a node whose every connector (three or more) holds a leaf strut driving
        on its free end's wheels (the strut wheels, Fig. 18(d)-(f)), else ``None``.

        Such legs cannot move sideways on the node (their turn would steer their wheels,
        :meth:`_steer`), so only their rolls are free; the node's tilt under them is then
        free too: any tilt has rolls that put every leg at its commanded elevation, and
        the feet, on the floor, settle the body at the tilt the rolls imply. Aimed through
        the IMU's attitude the legs kept whatever tilt the body had sagged to, and their
        places on the node, fixed since the move, stood 4-9 deg sideways of their aims
        (S4N1's spider, differential connectors, stop 48). Aimed through the frame that
        fits the legs' believed places on the node (localisation, never the simulator's
        state) to their commanded directions (``_aim``, the last command of each), the
        rolls bring the body to the tilt at which those places are where the shape asks;
        the part no rotation can fit stays."""
        if not self._differential:
            return None
        node = self.nodes[i]
        ks = np.array([k for k, n in enumerate(self.docked) if n == node], dtype=int)
        if len(ks) < 3 or not self._has_target[ks].all():
            return None
        far = ks ^ 1
        if (self._eq[far] >= 0).any() or (self._wheel[far] == 0.0).any():
            return None
        have = np.einsum("nij,nj->ni", self._believed(ks), self._sign[ks, None] * _EZ)
        u, _, vt = np.linalg.svd(have.T @ self._aim[ks])
        u[:, 2] *= np.sign(np.linalg.det(u @ vt))
        return u @ vt

    def _levelled(self, i: int, attitude: np.ndarray) -> np.ndarray:
        """The turn (3, 3) toward upright that node ``i``'s connectors take its estimated
        ``attitude`` (3, 3) through (:meth:`_node_tilt`): the identity unless it is held by
        ``_LEVEL_HOLDS`` or more connectors, none spinning it, is tilted past ``_LEVEL_FROM``
        and is its group's root (most connectors docked, then the first id:
        :func:`.recognizer.root_order`) or a node its struts hold up (one commanded at least
        ``_LEVEL_BELOW`` down from it, the last command's aim). The root alone was levelled
        until issue 31, stop 57: past the report filter's upright bound (120 deg) a node's
        heading runs on its gyro, so a non-root node's frame no longer cancels out of its
        commands, and fig22(j)'s top node ``n4``, upside down for 25 s, was commanded 5-8 deg
        off, its connectors saturated and the top sagged. Not a node standing on the floor
        under its struts: its shell rolls on the floor when turned (levelling every held node
        stalled fig22's move after R6's undock, floor nodes ``n2``, ``n3`` turned 5 deg a
        command). Not a chain's node (two connectors: the squirm's root ``n0``, by
        id), which lies on the floor and rolls as the chain moves, past 100 deg half the
        time: levelled, the hump strut its connector drives swung sideways in the steps it
        was tilted past the bound, the hump bent 10-24 deg at the raised node under 2 deg
        of noise and the body turned about as much (issue 31, stop 49)."""
        up = attitude[:, 2]
        excess = float(np.arccos(np.clip(up[2], -1.0, 1.0))) - _LEVEL_FROM
        if excess <= 0.0:
            return np.eye(3)
        node = self.nodes[i]
        ks = [k for k, n in enumerate(self.docked) if n == node]
        if len(ks) < _LEVEL_HOLDS or any(self._wheel[k] for k in ks):
            return np.eye(3)
        group = next(g for g in self.groups() if node in g)
        degree = {n: self.docked.count(n) for n in self.nodes if n in group}
        root = node == min(degree, key=lambda n: (-degree[n], n))
        # another node only if its struts hold it up (one commanded below the horizontal):
        # a node standing on the floor rolls on it when its shell turns (issue 31, stop 57)
        if not root and not any(self._has_target[k] and self._aim[k][2] < _LEVEL_BELOW
                                for k in ks):
            return np.eye(3)
        rotvec = Rotation.from_matrix(_minimal(up, _EZ)).as_rotvec()
        step = min(_LEVEL_GAIN * excess, _LEVEL_STEP)
        return Rotation.from_rotvec(rotvec * step / np.linalg.norm(rotvec)).as_matrix()

    def _localise(self, k: int) -> None:
        """Connector ``k`` takes a magnetic-localisation fix (the reports' noise, node
        frame) and fuses it with its encoders: its pose error is the fixes' error
        low-passed, ``f <- (1 - b) f + b n`` per fix (``b`` the option ``fusion``; the
        encoders do not drift in swing here: the wheels' slip is the twist ``eps``)."""
        if self.noise.std:
            sample = self.noise.rng.normal(0.0, self.noise.std, 3)
            self._fix[k] += self.options.fusion * (sample - self._fix[k])

    def _level_fix(self, k: int) -> None:
        """Connector ``k`` corrects its twist about the strut axis by its strut's
        accelerometer: gravity in the strut's frame gives the roll about a non-vertical
        axis with the reports' noise, so the encoders' random walk (``eps``, slip and
        drift) is low-passed toward that reading's error, ``e <- (1 - b) e + b n`` with
        ``b = _TWIST_FUSION sin^2`` (the axis's angle from the vertical: about a vertical axis
        gravity says nothing)."""
        if not (self.noise.std or self._eps[k]):
            return
        axis_z = float(self.data.xmat[self._strut_body[k // 2]][8])
        seen = 1.0 - axis_z * axis_z
        if seen < _AZIMUTH_FROM**2:
            return
        sample = self.noise.rng.normal(0.0, self.noise.std) if self.noise.std else 0.0
        self._eps[k] += _TWIST_FUSION * seen * (sample - self._eps[k])

    def _believed(self, ks: np.ndarray) -> np.ndarray:
        """Node -> strut rotations (n, 3, 3) as the connectors believe them: the truth
        off by the last localisation fix's error (node frame) and the odometry error
        ``eps`` (about the strut axis), ``F R E``."""
        r_c = Rotation.from_quat(self._ball(ks), scalar_first=True).as_matrix()
        true = np.einsum("nji,nkj->nik", self._conn_node[ks], r_c)  # (R_c R_cn)^T
        fix = Rotation.from_rotvec(self._fix[ks]).as_matrix()
        return fix @ true @ Rotation.from_rotvec(self._eps[ks, None] * _EZ).as_matrix()

    def _update_ball_targets(self, ks: np.ndarray | None = None) -> None:
        """The ball-joint targets of connectors ``ks`` (default: all with a target)."""
        ks = np.flatnonzero(self._has_target) if ks is None else ks
        if not len(ks):
            return
        fix = Rotation.from_rotvec(-self._fix[ks]).as_matrix()
        true = fix @ self._target[ks] \
            @ Rotation.from_rotvec(-self._eps[ks, None] * _EZ).as_matrix()   # F^T T E^T
        r_c = np.einsum("nij,njk->nik", self._conn_node[ks], true).transpose(0, 2, 1)
        self._ball_target[ks] = Rotation.from_matrix(r_c).as_quat(scalar_first=True)

    # -- stepping ---------------------------------------------------------------------

    def _before_step(self) -> None:
        """The connectors' joint targets from their commands."""
        self._update_ball_targets()
        self._imu.clear()
        self._node_rot = self.data.xmat[self._node_body].reshape(-1, 3, 3).copy()

    def _period_done(self, steps: int) -> None:
        """Connections over their strength break, then fresh docks seat; interpenetrating
        bodies are noted."""
        self._check_loads(steps)
        super()._period_done(steps)
        self._record_interpenetrations()

    def _docking(self) -> bool:
        """Whether a magnet array is extended."""
        return "extended" in self.magnet

    def _after_step(self, duration: float) -> None:
        """The connectors' odometry errors grow by what they rolled; the gyros read."""
        self._odometry(duration)
        self._read_gyros(duration)

    def _read_gyros(self, duration: float) -> None:
        """Each node's mean body rate over the step just taken, as its gyro reads it."""
        now = self.data.xmat[self._node_body].reshape(-1, 3, 3)
        turned = np.einsum("nji,njk->nik", self._node_rot, now)   # R_before^T R_after
        rate = Rotation.from_matrix(turned).as_rotvec() / duration
        o, rng = self.options, self._gyro_rng
        self._gyro_bias += rng.normal(0.0, o.gyro_walk * np.sqrt(duration), self._gyro.shape)
        self._gyro = rate + self._gyro_bias + rng.normal(0.0, o.gyro_noise / np.sqrt(duration),
                                                          self._gyro.shape)
        self._turned = self._turned @ Rotation.from_rotvec(self._gyro * duration).as_matrix()
        self._gyro_step = duration

    def _gyro_sample(self, i: int, period: float) -> np.ndarray:
        """Node ``i``'s gyro (3,) [rad/s, node frame] as a servo loop samples it once per
        ``period`` [s]: the body rate, its bias and the white noise of a ``period``-long
        average (a generator of its own, so the reports' draws stay as they were)."""
        rate = self.data.qvel[self._node_rate[i]:self._node_rate[i] + 3]
        return rate + self._gyro_bias[i] + self._servo_gyro_rng.normal(
            0.0, self.options.gyro_noise / np.sqrt(period), 3)

    def _servo(self) -> None:
        """The connectors' motor loops (``servo_rate``): magnets pull, driven connectors
        steer (:meth:`_steer`), every wheel motor gets its command (:meth:`_drive`), the
        grips follow their contact points."""
        self._attract()
        self._holder = self._hung_once()
        hung = self._holder >= 0
        if self._differential:
            self._swerve(hung)
        self._follow_spins(hung)
        ks = self._driven
        if not self._differential:
            self._servo_torques(ks)
            return
        self._follow_node_turns(hung)
        speed = np.zeros((len(self.ends), 2))
        held = np.zeros((len(self.ends), 2), dtype=bool)
        if len(ks):
            speed[ks], held[ks] = self._steer(ks)
        self._hold_wheels(held)
        self._drive(speed)
        self._track_saturation(ks, np.max(np.abs(self._torque[ks]), axis=1)
                               / (0.5 * self.phys.wheel_torque))
        self._place_grips()

    def _follow_spins(self, hung: np.ndarray) -> None:
        """The targets of the connectors on a node that docked wheels spin (not wheeling
        themselves) turn with the node about the wheels' strut axes: by the node's rotation
        over the servo period as its gyro samples it (:meth:`_gyro_sample`) projected onto
        the span of those axes as the wheeling connectors believe them (:meth:`_believed`:
        their localisation and odometry errors), so only the commanded spin is followed;
        not the connectors ``hung`` on a node one strut holds, which follow its whole
        rotation (:meth:`_follow_node_turns`).

        Only wheels on a strut docked at its other end spin their node (the node wheels of
        fig22(j)): the strut is held there, so the wheels' turn goes into the node. A strut
        free at its other end is itself the wheel (a roller, fig22(e)): its wheels turn
        the strut and the node's other connectors hold the node, as they did before the
        following (followed, the floor nodes rolled with the chords and the structure
        drifted sideways 9-11 % of its speed, with the sideways part the same sign both
        ways; held, 3 %)."""
        wheeling = self._node_wheels()
        followers = self._spin_followers(hung)
        if not followers.any():
            return
        period = self._every * self.options.timestep
        moved = []
        for node in sorted({self.docked[k] for k in np.flatnonzero(followers)}):
            mine = np.flatnonzero(followers & np.array([n == node for n in self.docked]))
            ks = wheeling[[self.docked[k] == node for k in wheeling]]
            axes = self._believed(ks)[:, :, 2].T   # (3, m): strut axes, node frame
            rate = self._gyro_sample(self._node_index[node], period)
            spin = axes @ np.linalg.lstsq(axes, rate, rcond=None)[0]
            turn = Rotation.from_rotvec(-spin * period).as_matrix()
            self._target[mine] = turn @ self._target[mine]
            moved.extend(mine)
        if moved:
            self._update_ball_targets(np.array(moved))

    def _swerve(self, hung: np.ndarray) -> None:
        """Steer the floor nodes like swerve wheels: on a node a node wheel ``W`` spins
        with a commanded travel (:meth:`command_travel`: the body's translation, not its
        turn, which the wheels' speeds alone carry), every spin follower ``F``
        (:meth:`_spin_followers`) on a strut docked at both ends gets, at both its ends,
        the twist that leaves the node rolling along that travel (:func:`swerve_heading`).

        A docked differential connector grips about its heading (its strut's ``x``), so a
        node two such struts hold turns relative to them only about ``x_W x x_F`` and
        rolls along one direction, which their twists set: the kiwi drive's travel
        oblique to it left the body one motion, a turn, and the wheels stalled (fig22(j):
        17 % of the travel asked, stop 52). Everything here is as the modules sense it:
        the travel from the behavior's command in ``W``'s own horizontal frame, the
        vertical from the node's attitude estimate (:meth:`_vertical`), the struts'
        axes from the connectors' beliefs (:meth:`_believed`); the far end takes the
        twist through its own belief of the strut. Those ends are marked ``_swerved`` for
        this servo step: :meth:`_steer` never turns them toward an aim error (their turn
        is the twist's): left a degree off their aims sideways, ``s8``'s ends turned the
        strut up to 90 deg off its twist and back at the wheels' top speed, and each turn
        on the top node pushed its other connectors off their aims until ``s9`` broke
        there (fig22, stop 53)."""
        self._swerved[:] = False
        wheels = self._node_wheels()
        wheels = wheels[self._travel[wheels].any(axis=1)]
        if not len(wheels):
            return
        k = np.arange(len(self.ends))
        follows = self._spin_followers(hung) & (self._eq[k ^ 1] >= 0)
        moved = []
        for kw in wheels:
            node = self.docked[kw]
            mine = [kf for kf in np.flatnonzero(follows) if self.docked[kf] == node]
            if not mine:
                continue
            up = self._vertical(self._node_index[node])
            wheel = self._believed(np.array([kw]))[0]
            travel = node_travel(wheel[:, 2], up, *self._travel[kw])
            for kf in mine:
                seen = self._believed(np.array([kf, kf ^ 1]))
                heading = swerve_heading(wheel[:, 0], seen[0], travel)
                if heading is None:
                    continue
                for kk, belief in zip((kf, kf ^ 1), seen, strict=True):
                    self._target[kk] = _frame(self._target[kk][:, 2], belief @ heading)
                    self._twist_free[kk] = False
                    self._swerved[kk] = True
                    moved.append(kk)
        if moved:
            self._update_ball_targets(np.array(moved))

    def _vertical(self, i: int) -> np.ndarray:
        """The vertical (3,) in node ``i``'s frame as its IMU estimates it now: the truth
        off by the attitude estimate's last error (:meth:`_node_tilt`'s, which this
        neither draws nor caches: a servo period's vertical, not the tick's frame the
        commands share; cached here, the commands took a spinning node's frame a tick
        old and every target on it was off by the turn since)."""
        body = self._node_body[i]
        tilt = Rotation.from_rotvec(self._attitude[i]).as_matrix() @ rot_z(
            -float(heading(self.data.xquat[body])))
        return (tilt @ self.data.xmat[body].reshape(3, 3)).T @ _EZ

    def _node_wheels(self) -> np.ndarray:
        """The connectors (m,) whose wheels are commanded on a strut docked at both ends:
        node wheels, which spin their node (fig22(j), fig18(a))."""
        k = np.arange(len(self.ends))
        return np.flatnonzero((self._wheel != 0.0) & (self._eq >= 0) & (self._eq[k ^ 1] >= 0))

    def _spin_followers(self, hung: np.ndarray) -> np.ndarray:
        """Which connectors (k,) follow a node wheel's spin of their node
        (:meth:`_follow_spins`): docked with a target, their own wheels not commanded, not
        ``hung`` on a node one strut holds (:meth:`_hung_once`), on a node that a node
        wheel (:meth:`_node_wheels`) spins."""
        spun = {self.docked[k] for k in self._node_wheels()}
        followers = (self._eq >= 0) & self._has_target & (self._wheel == 0.0) & ~hung
        return followers & np.array([n in spun for n in self.docked], dtype=bool)

    def _hung_once(self) -> np.ndarray:
        """The connector (k,) that alone holds the node of each free strut's connector (a
        strut free at its other end, its wheels not commanded, with a target) when one
        docked strut alone holds that node (a strut docked at both ends), else -1; all -1
        with holonomic connectors (:meth:`_follow_node_turns`, :meth:`_steer`)."""
        k = len(self.ends)
        holder = np.full(k, -1)
        if not self._differential:
            return holder
        docked = self._eq >= 0
        other = self._eq[np.arange(k) ^ 1] >= 0
        free = docked & ~other & self._has_target & (self._wheel == 0.0)
        if not free.any():
            return holder
        holders: dict[str, list[int]] = {}
        for j in np.flatnonzero(docked & other):
            holders.setdefault(self.docked[j], []).append(int(j))
        for j in np.flatnonzero(free):
            mine = holders.get(self.docked[j], [])
            if len(mine) == 1:
                holder[j] = mine[0]
        return holder

    def _follow_node_turns(self, hung: np.ndarray) -> None:
        """The targets of the free struts' connectors ``hung`` (:meth:`_hung_once`) turn
        against their node's rotation over the servo period as its gyro samples it
        (:meth:`_gyro_sample`): their aims, commanded in the horizontal frame, stay there
        between commands. Such a node hangs on one connector's grip and turns under its
        free struts' reaction; with their targets fixed on the shell they chased it (fig22
        after the undock of ``n0-s0b``: ``n4`` turned at a median 71 deg/s under ``s0``
        and ``s1``, their aims ran away on it and ``s0:a``'s twist swept through 360 deg;
        stop 48). A node two or more struts hold turns with the structure, and one with no
        holder is the body its legs carry (the spider's frame, :meth:`_fitted`): neither
        is followed. The whole rotation is followed, a docked wheel pair's spin of that
        node included (:meth:`_follow_spins` leaves these connectors alone)."""
        if not hung.any():
            return
        period = self._every * self.options.timestep
        moved = []
        for node in sorted({self.docked[k] for k in np.flatnonzero(hung)}):
            mine = np.flatnonzero(hung & np.array([n == node for n in self.docked]))
            rate = self._gyro_sample(self._node_index[node], period)
            turn = Rotation.from_rotvec(-rate * period).as_matrix()
            self._target[mine] = turn @ self._target[mine]
            moved.extend(mine)
        self._update_ball_targets(np.array(moved))

    def _spin_speed(self, ks: np.ndarray, asked: np.ndarray, axis: np.ndarray,
                    wheeling: np.ndarray) -> np.ndarray:
        """Spin commands (n,) [rad/s] of connectors ``ks`` with the wheel speed loop: the
        spin ``asked`` plus ``_SPIN_GAIN`` times its integrated lag behind the measured
        spin (the ball joint's rate about the strut ``axis``, (n, 3), connector frame),
        the integral bounded to the spin rate; for the ``wheeling`` ones only."""
        rate = np.einsum("ni,ni->n", self.data.qvel[self._dofs[ks]], axis)
        bound = self.phys.max_spin_rate / _SPIN_GAIN
        lag = np.clip(self._spin_lag[ks] + (asked - rate) * self._every * self.options.timestep,
                      -bound, bound)
        self._spin_lag[ks] = np.where(wheeling, lag, 0.0)
        return np.where(wheeling, asked + _SPIN_GAIN * self._spin_lag[ks], asked)

    def _servo_torques(self, ks: np.ndarray) -> None:
        """Holonomic connectors (``connector_drive="holonomic"``): three motor torques on
        each ball joint, the rotation error split into rolling (bounded by the roll rate)
        and spinning (by the spin rate), under the torque limit, against the passive
        back-EMF damping ``D`` of the ball joint (see docs/freesn.md, Actuation)."""
        p = self.phys
        tau = self._tau
        tau[:] = 0.0
        if len(ks):
            q = self._ball(ks)
            relative = quat_mul(quat_conj(q), self._ball_target[ks])   # child frame
            w, x, y, z = q.T   # strut axis in the connector frame: row 3 of R(q), signed
            axis = self._sign[ks, None] * np.column_stack(
                [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)])
            wheeling = self._wheel[ks] != 0.0
            if wheeling.any():   # the twist is under the wheels: servo the swing alone
                relative[wheeling] = _swing(relative[wheeling], axis[wheeling])
            error = quat_log(relative)
            omega = self.options.position_gain * error
            if self.options.integral_gain > 0.0:
                integral = self._integral[ks] + self._beyond_band(
                    error, self._integral[ks], ks) * (self._every * self.options.timestep)
                size = np.sqrt(np.einsum("ni,ni->n", integral, integral))
                integral *= np.minimum(1.0, self._integral_bound / np.maximum(size, 1e-12)
                                       )[:, None]
                integral[self._wheel_legs(ks)] = 0.0
                self._integral[ks] = integral
                omega = omega + self.options.integral_gain * integral
            spin = np.einsum("ni,ni->n", omega, axis)
            roll = omega - spin[:, None] * axis
            # wheels in opposition turn the node, and the connector welded to it, about
            # the strut's +z = sign * axis relative to the strut
            spin = np.where(wheeling, self._sign[ks] * self._wheel[ks] * p.wheel_radius
                            / (0.5 * p.wheel_base), spin)
            norm = np.sqrt(np.einsum("ni,ni->n", roll, roll))
            limit = p.max_torque * self._effort[ks]
            scale = np.minimum(1.0, p.max_roll_rate / np.maximum(norm, 1e-12))
            scale *= np.minimum(1.0, limit / np.maximum(p.damping * norm * scale, 1e-12))
            spin = np.minimum(np.maximum(spin, -p.max_spin_rate), p.max_spin_rate)
            if wheeling.any():
                spin = self._spin_speed(ks, spin, axis, wheeling)
            # a reduced effort softens the position loop of a loop-closing connector; its
            # wheels, when commanded, still run at the full torque
            spin_limit = np.where(wheeling, p.max_torque, limit)
            t_spin = np.minimum(np.maximum(p.damping * spin, -spin_limit), spin_limit)
            tau[ks] = (p.damping * scale)[:, None] * roll + t_spin[:, None] * axis
        torque = self._tau[ks] - p.damping * self.data.qvel[self._dofs[ks]]
        self._track_saturation(ks, np.sqrt(np.einsum("ni,ni->n", torque, torque)) / p.max_torque)
        self.data.qfrc_applied[self._dofs] = tau
        self._drive_free_wheels()

    def _beyond_band(self, error: np.ndarray, integral: np.ndarray | None = None,
                     ks: np.ndarray | None = None) -> np.ndarray:
        """The part (n, 3) of servo errors ``error`` (n, 3) [rad] the integral action takes:
        what lies beyond ``integral_band`` times the rms error the connector's own estimates
        put in it (its node's attitude and its fix, each ``noise b / sqrt(1 - (1 - b)^2)``
        per axis, ``b`` = ``fusion``). Within it the connector cannot tell a load's offset
        from its estimates' wander; integrated, that wander pushes the loops a structure
        closes against each other (issue 31, stop 48). The whole error without noise.

        The band stops the integral growing, never shrinking: the error within it also
        takes back the part of ``integral`` (n, 3) [rad s] it opposes. A transient winds an
        integral to its bound, whose push the position loop then balances at an error of
        the roll rate over the position gain (2.1 deg), inside the band at 4 deg of noise:
        never unwound, it held its connector that far off in the transient's direction,
        and fig21's open ring missed its closing dock (issue 31, stop 49).

        Connectors ``ks`` (n,) of a structure pressing a dock (:meth:`_pressing`) take
        their whole error: the press's goal lies past the node (``S_extr``), so what is
        left of it is load, not wander, and a dock needs the last degrees of every joint
        on the way (fig21 at 4 deg: the band held the closing magnet 21-31 mm short, its
        connectors within 1 deg of their targets, stop 49)."""
        band = self._band()
        if band <= 0.0:
            return error
        size = np.sqrt(np.einsum("ni,ni->n", error, error))
        beyond = error * (np.maximum(size - band, 0.0) / np.maximum(size, 1e-12))[:, None]
        if integral is not None:
            held = np.sqrt(np.einsum("ni,ni->n", integral, integral))
            unit = integral / np.maximum(held, 1e-12)[:, None]
            back = np.minimum(np.einsum("ni,ni->n", error - beyond, unit), 0.0)
            beyond += back[:, None] * unit
        if ks is not None:
            beyond = np.where(self._pressing(ks)[:, None], error, beyond)
        return beyond

    def _wheel_legs(self, ks: np.ndarray) -> np.ndarray:
        """Whether each of connectors ``ks`` (n,) holds a leg whose foot is a node its
        strut's other end drives as a wheel, in a structure standing on four such wheels
        or more (Fig. 18(a)-(c)), under noise (an integral band, :meth:`_beyond_band`).
        Such a leg takes no integral action: a stance on more wheels than three carries
        its weight in a split the legs' loops set, not the floor, and an integral on each
        leg's error, which under noise is its estimates' wander, moves load between the
        wheels for as long as it holds. The wheels that carry more grip more, and the body
        crabs toward their rolling, which the odometry (the mean of the feet's rolling)
        cannot see (issue 31, stop 50: fig18 at 2 deg + 5 %, seed 15, one diagonal pair of
        wheels at 6.7 N and the other at 4.9 N for the whole behavior, the body 14-22 deg
        off the travel its rolling showed, its heading estimate within 1.1 deg). Exact,
        the integral takes the leg's true error and sets the designed split (without it
        the exact run sags 1.5 deg and ends 1.7 deg off its heading, 0.4 deg with it), so
        it is kept there; three wheels (fig22(j)) carry a split the floor sets."""
        out = np.zeros(len(ks), dtype=bool)
        if not self._wheel.any() or self._band() <= 0.0:
            return out
        other = ks ^ 1
        legs = (self._wheel[ks] == 0.0) & (self._wheel[other] != 0.0) & np.array(
            [self.docked[k] is not None for k in other], dtype=bool)
        if not legs.any():
            return out
        for group in self.groups():
            wheels = {self.docked[k] for k in np.flatnonzero(self._wheel != 0.0)
                      if self.docked[k] in group and self.docked[k ^ 1] is not None}
            if len(wheels) >= 4:
                out |= legs & np.array([self.ends[k][0] in group for k in ks], dtype=bool)
        return out

    def _band(self) -> float:
        """The integral band [rad] (:meth:`_beyond_band`): ``integral_band`` times the rms
        error a connector's estimates put in its servo error; 0 without noise."""
        o = self.options
        return o.integral_band * np.sqrt(6.0) * self.noise.std * o.fusion / np.sqrt(
            1.0 - (1.0 - o.fusion) ** 2)

    def _pressing(self, ks: np.ndarray) -> np.ndarray:
        """Whether each of connectors ``ks`` (n,) is in a structure with an extended free
        magnet (a dock commanded and not yet made: its connect phase presses it on)."""
        out = np.zeros(len(ks), dtype=bool)
        struts = {self.ends[k][0] for k, m in enumerate(self.magnet) if m == "extended"}
        if not struts:
            return out
        for group in self.groups():
            if struts & group:
                out |= np.array([self.ends[k][0] in group for k in ks], dtype=bool)
        return out

    @property
    def _integral_bound(self) -> float:
        """The bound of an integral [rad s]: its command at most ``integral_bound`` of the
        roll rate (anti-windup)."""
        o = self.options
        return o.integral_bound * self.phys.max_roll_rate / o.integral_gain

    def _steer(self, ks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Wheel speeds (n, 2) [rad/s] (left, right) that take connectors ``ks`` to their
        targets, turn, then roll (the firmware's turn-then-roll, a unicycle on the
        sphere), and which of their channels (n, 2) (rolling, turning) stop, their wheels
        braked (:meth:`_hold_wheels`).

        In the strut frame the wheels roll the connector about ``y`` (``omega_y``) and
        turn it about ``z`` (``omega_z``); about ``x`` they grip. The error ``E = q_t
        q^-1`` is removed by right factors, so its ZYZ angles ``E = Rz(g) Ry(b) Rz(d)``
        are the plan: turn ``d``, roll ``b``, turn ``g``; ``d`` comes from ``E^T z``'s
        azimuth, taken in ``(-pi/2, pi/2]`` so a connector may roll backwards. Beyond
        ``_TURN_ON`` from its target a connector turns (``omega_z = k d``) and rolls as its
        heading comes within ``_HEADING_GO`` (fully within ``_HEADING_OK``; within
        ``_HEADING_HOLD`` it stops turning, its turn braked, so both wheels push the roll,
        unless its strut is driven at both ends); nearer than
        ``_TURN_OFF`` it only rolls out the error along its heading and corrects its twist
        (the error's ``y`` and ``z`` components; ``x`` is left to the grip), unless the
        twist is free (a strut whose aim alone was commanded, or one whose other end's
        magnet is out to dock); left with a sideways error alone, past ``_STILL_OFF``, it
        turns toward it again. A connector whose strut's free end drives its wheels never
        turns (the turn would steer them; one turning when they start stops), nor does one
        whose twist the swerve sets (:meth:`_swerve`). Within ``_STILL_ON`` of its target (swing and the twist
        asked) it stops until pushed ``_STILL_OFF`` off (:meth:`_stop`); a hung node's
        free struts and its holder's far end likewise (:meth:`_waits`, :meth:`_pinned`). Each channel is
        the position loop ``k e + k_i int e`` (``position_gain``, ``integral_gain``); a
        channel asked for nothing stops, its wheels braked (a turn in place holds its
        rolling); wheels commanded in opposition set ``omega_z`` themselves, and that
        connector rolls ``b cos d`` whatever its heading (it cannot turn toward it). The wheel
        speeds: :meth:`_commands`.
        """
        p = self.phys
        swing, heading, error = self._way(ks)
        twist, spun = self._twist(ks, error)
        # a connector left with a sideways error alone, which rolling cannot remove, turns
        # toward it again; never one whose strut's free end drives its wheels (the strut
        # wheels), which stops a turn it began before they ran: the turn steers those
        # wheels (the spider's legs turned 50-90 % of the time, their axles 30 deg off level)
        steers = (self._eq[ks ^ 1] < 0) & (self._wheel[ks ^ 1] != 0.0)
        # nor the far end of a strut that wheels a node with free struts (_pinned), nor a
        # wheeling one (its twist is its wheels'; _common_turn gave its turn to the far end),
        # nor one whose twist the swerve sets (_swerve: its turns undid the steering; stop 53)
        wheeling = self._wheel[ks] != 0.0
        pinned = self._pinned(ks)
        steers |= pinned | wheeling | self._swerved[ks]
        twist = np.where(pinned | wheeling, 0.0, twist)
        aside = (np.abs(error[:, 1]) < _STILL_ON) & (np.abs(twist) < _STILL_ON)
        self._turning[ks] = ~steers & np.where(
            self._turning[ks], np.abs(swing) > _TURN_OFF,
            (np.abs(swing) > _TURN_ON) | (aside & (np.abs(swing) > _STILL_OFF)))
        turning = self._turning[ks]
        gate = np.clip((_HEADING_GO - np.abs(heading)) / (_HEADING_GO - _HEADING_OK), 0.0, 1.0)
        # a wheeling connector cannot turn (its wheels' difference is its commanded spin):
        # it rolls out the part of its swing along its heading, which the spin sweeps round
        roll = np.where(turning | wheeling,
                        swing * np.cos(heading) * np.where(wheeling, 1.0, gate), error[:, 1])
        # turning, a connector whose heading is within _HEADING_HOLD rolls and asks no turn:
        # its turn is braked and both wheels push the roll; a turn loop on the last degree
        # took one wheel's torque from a loaded roll (fig20's legs; at 5 deg the turn stopped
        # so abruptly that a wheel overran its top speed). Not an end of a strut driven at
        # both (they turn as one, _common_turn)
        alone = ~np.isin(ks ^ 1, ks)
        aligned = alone & (np.abs(heading) < _HEADING_HOLD)
        turn = np.where(turning, np.where(aligned, 0.0, heading), twist)
        still = self._stop(ks, np.hypot(swing, twist), wheeling) | self._waits(ks)
        roll = np.where(still, 0.0, roll)
        turn = self._common_turn(ks, np.where(still, 0.0, turn),
                                 np.abs(swing) * turning * self._effort[ks], spun)
        channels = np.column_stack([roll, np.where(wheeling, 0.0, turn)])
        # a channel asked for nothing (a stopped connector, a turn in place, a straight roll
        # whose twist is free) brakes its wheels: it holds instead of being servoed
        held = (channels == 0.0) & ~np.column_stack([wheeling, wheeling])
        omega = self._position_loop(ks, channels, held)
        omega[:, 1] = np.where(wheeling, self._wheel[ks] / p.turn_ratio, omega[:, 1])
        return self._commands(ks, omega, ~turning & ~wheeling, wheeling), held

    def _position_loop(self, ks: np.ndarray, channels: np.ndarray, held: np.ndarray
                       ) -> np.ndarray:
        """Rates (n, 2) [rad/s] (rolling, turning) of connectors ``ks`` for their
        ``channels`` (n, 2) [rad] (:meth:`_steer`): ``k e + k_i int e`` (``position_gain``,
        ``integral_gain``), zero where ``held``. The integral is bounded
        (:meth:`_integral_bound`), times the connector's effort on a node that ``_HUB`` or
        more docked connectors hold. A soft follower (effort ``FOLLOW_EFFORT``, an end
        off the driving tree, :func:`~msrr.plugins.freesn.sim.controller.driving_ends`)
        pushes with its wheels' full torque (:meth:`_drive`), and with a whole integral it
        held its aim as stiffly as the tree: on the hubs of fig20's S6N3, the two ends of
        ``s4`` wound against each other to their bounds and spent them when they moved
        again (-+1.44 rad/s of roll against a fresh 0.42), and the last move stalled at 31
        deg (stops 53-54). On a chain's node, held by the strut's end and the next strut's
        alone, a soft end carries the chain's load: capped there too, the squirm ended 29
        deg off its heading (stop 54)."""
        o = self.options
        omega = o.position_gain * channels
        if o.integral_gain > 0.0:
            cap = self._integral_bound * np.where(self._on_hubs(ks), self._effort[ks], 1.0)
            integral = np.clip(self._integral[ks, 1:] + channels * self._every * o.timestep,
                               -cap[:, None], cap[:, None])
            self._integral[ks, 1:] = integral
            omega = np.where(held, 0.0, omega + o.integral_gain * integral)
        return omega

    def _on_hubs(self, ks: np.ndarray) -> np.ndarray:
        """Which connectors ``ks`` (n,) are docked on a node ``_HUB`` or more docked
        connectors hold (each node counts its own magnets' docks)."""
        held: dict[str, int] = {}
        for k in np.flatnonzero(self._eq >= 0):
            held[self.docked[k]] = held.get(self.docked[k], 0) + 1
        return np.array([held.get(self.docked[k], 0) >= _HUB for k in ks], dtype=bool)

    def _twist(self, ks: np.ndarray, error: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The twist corrections (n,) [rad] connectors ``ks`` servo, from their errors'
        rotation vectors ``error`` (n, 3) in the strut frame, and which of them follow a
        node wheel's spin (n,) (:meth:`_spin_followers`). None where the twist is free
        (the aim alone commanded) or the strut's other end's magnet is out to dock (spun,
        that end would scrub the node it meets and turn it askew); a spin follower turns
        with its node about its own axis, its twist free or not: braked, it held the
        node's spin, and its strut, held at its far end by a brake no stronger, turned with
        the node (fig22(j)'s floor nodes, stop 52)."""
        docking = np.array([self.magnet[k ^ 1] == "extended" for k in ks], dtype=bool)
        spun = self._spin_followers(self._holder >= 0)[ks]
        return np.where((self._twist_free[ks] & ~spun) | docking, 0.0, error[:, 2]), spun

    def _waits(self, ks: np.ndarray) -> np.ndarray:
        """Which connectors ``ks`` (n,) hold still, their wheels braked, for the one
        connector that holds their node (:meth:`_hung_once`): a free strut's connector
        while that holder turns about its strut's axis (not spinning the node as a wheel).
        Such a turn spins the node and its free struts about that axis, nothing else
        holding it, and the free struts chased their aims round it: ``n4`` at 40-93 deg/s
        after fig22's undock of ``n0-s0b`` (stop 49)."""
        holder = self._holder[ks]
        j = np.maximum(holder, 0)
        return (holder >= 0) & self._turning[j] & (self._wheel[j] == 0.0)

    def _pinned(self, ks: np.ndarray) -> np.ndarray:
        """Which connectors ``ks`` (n,) are the far end of a strut that alone holds a node
        carrying free struts (:meth:`_hung_once`) while its end on that node spins the
        node as a wheel. That end cannot turn against the far end's turn (its wheels'
        difference is its commanded spin), so the turn spins the node and its free struts
        round the strut's axis: in fig22's node wheels ``s11:a``'s turn on ``n2`` spun
        ``n4`` at 144 deg/s and broke ``s11:b`` (stop 49). It turns neither toward an error
        nor for its twist; what it cannot roll out is left, as for the strut wheels' legs
        (stop 47)."""
        holds = np.zeros(len(self.ends), dtype=bool)
        holds[self._holder[self._holder >= 0]] = True
        return holds[ks ^ 1] & (self._wheel[ks ^ 1] != 0.0)

    def _way(self, ks: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Connectors ``ks``' way to their targets (:meth:`_steer`): the signed swing (n,)
        [rad] (negative rolling backwards), the heading to turn (n,) [rad] and the error's
        rotation vector (n, 3) in the strut frame."""
        e_q = quat_mul(self._ball_target[ks], quat_conj(self._ball(ks)))
        w, x, y, z = e_q.T
        u = np.column_stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)])
        swing = np.arccos(np.clip(u[:, 2], -1.0, 1.0))
        ahead = _wrap(np.pi - np.arctan2(u[:, 1], u[:, 0]))
        behind = _wrap(ahead - np.pi)
        # forwards or backwards, whichever needs the smaller turn; the way chosen is
        # kept until the other is _HEADING_GO better, so noise does not flip it, and while
        # turning on a swing under _TURN_ON until it is _WAY_KEPT better: a small sideways
        # error's direction swings by degrees with the node's motion, which flipped its way
        # and the turn's sense (fig22's s7:a, 1.6 deg off, turned at -96 deg, then +73 deg,
        # at the wheels' top speed, and broke off n2; stop 51)
        was = self._backwards[ks]
        kept = np.where(self._turning[ks] & (swing < _TURN_ON), _WAY_KEPT, _HEADING_GO)
        back = np.where(was, np.abs(behind) < np.abs(ahead) + kept,
                        np.abs(behind) + kept < np.abs(ahead))
        self._backwards[ks] = back
        return np.where(back, -swing, swing), np.where(back, behind, ahead), quat_log(e_q)

    def _wheel_speeds(self, omega: np.ndarray, near: np.ndarray) -> np.ndarray:
        """Wheel speeds (n, 2) [rad/s] for the rolling and turning rates ``omega`` (n, 2)
        [rad/s], ``rho omega_y -+ tau omega_z`` within the wheels' top speed; a connector
        ``near`` its target rolls first and turns (its twist) with the speed left, so a long
        twist correction does not hold the strut off its aim."""
        p = self.phys
        top = p.max_wheel_speed
        rolling = np.clip(p.roll_ratio * omega[:, 0], -top, top)
        turn = p.turn_ratio * omega[:, 1]
        left = top - np.abs(rolling)
        turn = np.where(near, np.clip(turn, -left, left), turn)
        speed = np.column_stack([rolling - turn, rolling + turn])
        fastest = np.max(np.abs(speed), axis=1, keepdims=True)
        return speed * np.minimum(1.0, top / np.maximum(fastest, 1e-12))

    def _commands(self, ks: np.ndarray, omega: np.ndarray, near: np.ndarray,
                  wheeling: np.ndarray) -> np.ndarray:
        """Wheel commands (n, 2) [rad/s] of connectors ``ks`` for the rates ``omega`` (n, 2):
        a wheeling one's (its wheels commanded) by :meth:`_wheeling_speeds`, any other's by
        :meth:`_wheel_speeds`."""
        speed = self._wheel_speeds(omega, near)
        if wheeling.any():
            speed[wheeling] = self._wheeling_speeds(ks[wheeling], omega[wheeling])
        self._spin_lag[ks[~wheeling]] = 0.0
        return speed

    def _wheeling_speeds(self, ks: np.ndarray, omega: np.ndarray) -> np.ndarray:
        """Wheel commands (n, 2) [rad/s] of wheeling connectors ``ks`` (their wheels
        commanded: a roller, spinning a strut free at its other end, fig22(e)'s chords and
        fig18(g)'s legs; a node wheel, spinning its node under a strut docked at both ends,
        fig22(j), fig18(a)) for the rolling and spin rates ``omega`` (n, 2) [rad/s].

        Each wheel's torque ``D_w (u - v)`` is split in two. The aim's rolling part, the
        position loop's, comes first but takes at most ``_ROLLER_AIM`` of the wheel torque;
        the spin gets what the wheel's current and voltage leave, through the speed loop
        of the holonomic model's docked wheels (:meth:`_spin_speed`: the spin's lag behind
        its command, on the wheels' encoders, integrated, times ``_SPIN_GAIN`` added to
        it, the lag bounded so the command reaches twice the top speed; the voltage ``u``
        likewise). Scaled together within the top speed (:meth:`_wheel_speeds`) the aim
        took the wheels' voltage from the spin: fig22(e)'s rollers spun at a third of their
        command and slipped, the structure at 16 % of the asked speed (stop 50); a node
        wheel's motors, a voltage within the top speed, gave 0.065 of their 0.144 N m
        stalled, and fig22(j)'s node wheels spun their nodes at 6 % or less (stop 51)."""
        p = self.phys
        kv, limit, top = 0.5 * p.wheel_damping, 0.5 * p.wheel_torque, p.max_wheel_speed
        v = self.data.actuator_velocity[self._motor[ks]]
        lo = np.maximum(-limit, kv * (-2.0 * top - v))   # each wheel's torque now
        hi = np.minimum(limit, kv * (2.0 * top - v))
        aim = _ROLLER_AIM * limit
        roll = kv * (np.clip(p.roll_ratio * omega[:, 0], -top, top) - v.mean(axis=1))
        roll = np.clip(np.clip(roll, -aim, aim), lo.max(axis=1), hi.min(axis=1))
        had = 0.5 * (v[:, 1] - v[:, 0])
        asked = p.turn_ratio * omega[:, 1]
        bound = top / _SPIN_GAIN
        self._spin_lag[ks] = np.clip(self._spin_lag[ks] + (asked - had) * self._every
                                     * self.options.timestep, -bound, bound)
        spin = kv * (asked + _SPIN_GAIN * self._spin_lag[ks] - had)
        spin = np.clip(spin, np.maximum(roll - hi[:, 0], lo[:, 1] - roll),
                       np.minimum(roll - lo[:, 0], hi[:, 1] - roll))
        return v + np.column_stack([roll - spin, roll + spin]) / kv

    def _stop(self, ks: np.ndarray, error: np.ndarray, wheeling: np.ndarray) -> np.ndarray:
        """Which connectors ``ks`` stand at their targets (n,): within ``_STILL_ON`` of it
        (``error`` [rad]), until pushed ``_STILL_OFF`` off it (the firmware's connector
        stops at its target, there within 2 deg); never one whose wheels are commanded."""
        still = ~wheeling & (error < np.where(self._still[ks], _STILL_OFF, _STILL_ON))
        self._still[ks] = still
        return still

    def _hold_wheels(self, held: np.ndarray) -> None:
        """Brake the wheels of the channels ``held`` (k, 2) (rolling, turning): a stopped
        wheel neither turns nor is turned (a gear train the load does not back-drive), so
        its contact grips the shell as it grips sideways, up to the wheels' friction: the
        roll tendon's ``frictionloss`` the grip, the turn tendon's the two wheels' friction
        couple ``grip b / 2`` through its lever. A connector at a reduced effort (one that
        closes a loop and follows softly) holds its rolling with that fraction of the
        friction, as its motors push: braked in full, the loops of fig22 strained until a
        connection broke (s4:a at n0, 20.1 N at 2.3 s); its turning stays braked in full,
        since a strut's turn about its own axis moves no connection vector and strains no
        loop, while a node free to turn under it let the S6N3-2.1 triangle on the floor
        creep 47 mm/s. Coasting connectors and free ends hold nothing."""
        p = self.phys
        held = held & (self._eq >= 0)[:, None] & (self._effort > 0.0)[:, None]
        force = np.column_stack([p.grip * self._effort,
                                 np.full(len(held), p.grip * p.wheel_base / (2.0 * _GRIP_LEVER))])
        self.model.tendon_frictionloss[self._brake] = np.where(held, force, 0.0)

    def _common_turn(self, ks: np.ndarray, turn: np.ndarray, lead: np.ndarray,
                     own: np.ndarray) -> np.ndarray:
        """One turn for both ends of a strut docked and driven at both (FreeSN paper,
        Fig. 6(c)): a turn spins the strut about its axis, on both nodes at once, so the
        other end steers opposite (in its own wheels' sense) and the nodes stay put. The
        end that leads (larger ``lead``: its swing while turning, times its effort) sets
        the turn of both; when neither turns, the mean of their twist corrections, unless
        either end's is its ``own`` (n,): a spin follower's twist (:meth:`_steer`) turns
        it with its node, not the strut, so each end keeps its own."""
        where = np.full(len(self.ends), -1)
        where[ks] = np.arange(len(ks))
        partner = where[ks ^ 1]
        pair = partner >= 0
        other = np.where(pair, partner, np.arange(len(ks)))
        mine = lead >= lead[other]
        chosen = np.where(mine, turn, turn[other])
        neither = (lead == 0.0) & (lead[other] == 0.0)
        shared = np.where(own | own[other], turn, 0.5 * (turn + turn[other]))
        return np.where(pair, np.where(neither, shared, chosen), turn)

    def _drive(self, speed: np.ndarray) -> None:
        """Every wheel motor toward ``speed`` (k, 2) [rad/s]: a DC motor's torque ``D_w
        (speed - v)`` at the wheel speed ``v`` now, bounded by the wheel torque, passed as
        the velocity actuator's control ``v + torque / D_w`` so the back-EMF stays
        implicit; free ends' wheel hinges likewise. A reduced effort (a connector that
        closes a loop) does not weaken the wheels, only ``0`` (coasting) stops them: a
        node is held by its connectors' wheels, whose turning is weak already (its
        back-EMF ``2 D_w tau^2``), and with softened wheels the nodes of S6N3's triangle
        spun under its legs' loads."""
        p = self.phys
        kv = 0.5 * p.wheel_damping
        v = self.data.actuator_velocity[self._motor]
        limit = 0.5 * p.wheel_torque
        torque = np.clip(kv * (speed - v), -limit, limit)
        self._torque = torque * (self._effort > 0.0)[:, None]
        self.data.ctrl[self._motor] = v + torque / kv
        self._drive_free_wheels()

    def _drive_free_wheels(self) -> None:
        """Free ends' wheel hinges toward their commanded speeds (a bounded DC motor)."""
        p = self.phys
        free = np.array([node is None for node in self.docked])
        drive = np.clip(p.wheel_damping * self._wheel, -p.wheel_torque, p.wheel_torque)
        self.data.qfrc_applied[self._axle] = np.where(free, drive, 0.0)

    def _place_grips(self) -> None:
        """Each friction tendon's node end at its anchor (``_ANCHORS``: the connector frame
        of the strut-axes point ``_grip_at``), so the grip tendon's rate is the contact's
        sideways slip, the roll tendon's its rolling slip, the turn tendon's the turn about
        the contact normal times the lever."""
        inverse = Rotation.from_quat(quat_conj(self._ball(np.arange(len(self.ends)))),
                                     scalar_first=True)
        for j in range(3):
            self.model.site_pos[self._grip_site[:, j]] = inverse.apply(self._grip_at[:, j])

    def _track_saturation(self, ks: np.ndarray, load: np.ndarray) -> None:
        """Start or end each connector's saturation streak: a driven connector ``ks`` at
        full effort whose motors deliver (drive minus back-EMF: stalled against a load)
        at least ``_SATURATED`` of their torque limit (``load``, (n,), that fraction now),
        low-passed over ``_SATURATION_FILTER`` so contact chatter does not break a
        streak."""
        net = np.zeros(len(self.ends))
        net[ks] = load * (self._effort[ks] >= 1.0)
        alpha = min(1.0, self._every * self.options.timestep / _SATURATION_FILTER)
        self._net_torque += alpha * (net - self._net_torque)
        saturated = self._net_torque >= _SATURATED
        self._saturated_since = np.where(saturated, np.fmin(self._saturated_since, self.time),
                                         np.nan)

    def _check_loads(self, steps: int = 1) -> None:
        d = self.data
        docked = self._eq >= 0
        ks = np.flatnonzero(docked)
        load = np.zeros(len(ks))
        if len(ks):  # equality rows come first, six per weld, in the order of the equality ids
            n = 6 * len(ks)
            by_weld = np.zeros((self.model.neq, 3))
            by_weld[d.efc_id[:n:6]] = d.efc_force[:n].reshape(-1, 6)[:, :3]
            on_connector = by_weld[self._eq[ks]]   # force on each docked connector [N]
            # outward, node centre -> strut: the strut's +z at end a, -z at end b
            out = self._sign[ks, None] * d.xmat[self._strut_body[ks // 2]].reshape(-1, 3, 3)[
                :, :, 2]
            pressed = np.maximum(np.einsum("ni,ni->n", on_connector, out), 0.0)
            held = on_connector - pressed[:, None] * out   # pull-off and shear
            load = np.sqrt(np.einsum("ni,ni->n", held, held))
        alpha = min(1.0, steps * self.options.timestep / self.options.break_filter)
        self._load[docked] += alpha * (load - self._load[docked])
        self._load[~docked] = 0.0
        for k in np.flatnonzero(self._load > self.phys.strength):
            self._release(int(k), "break")

    def _magnets(self) -> list[tuple[int, int, np.ndarray, np.ndarray, float, float]]:
        """Every extended free magnet near a node, nearest node first per end (not the
        strut's other node): ``(k, i, tip, toward, gap, angle)`` with ``k`` the end,
        ``i`` the node index, ``tip`` (3,) the magnet face's centre, ``toward`` (3,) the
        unit vector from it to the node centre. ``gap`` [m] is the magnet face's
        distance to the node surface beyond the docked stand-off (0 when seated, down to
        ``-_GAP`` pressed on the shell); ``angle`` [rad] is between the strut axis and
        the line to the node centre."""
        d, p = self.data, self.phys
        out = []
        centres = d.xpos[self._node_body]
        for k, state in enumerate(self.magnet):
            if state != "extended" or self.docked[k] is not None:
                continue
            strut, end = self.ends[k]
            other = self.docked[self._end_index[(strut, "b" if end == "a" else "a")]]
            inward = -self._sign[k] * d.xmat[self._strut_body[k // 2]].reshape(3, 3)[:, 2]
            tip = d.xpos[self._conn_body[k]] - (p.node_radius + _GAP) * inward
            offset = centres - tip
            dist = np.linalg.norm(offset, axis=1)
            gap = dist - p.node_radius - _GAP
            for i in np.argsort(dist):
                if gap[i] > p.dock_tolerance:
                    break
                if self.nodes[i] == other:
                    continue
                toward = offset[i] / dist[i]
                angle = float(np.arccos(np.clip(toward @ inward, -1.0, 1.0)))
                out.append((k, int(i), tip, toward, float(gap[i]), angle))
        return out

    def _attract(self) -> None:
        """Extended free magnets pull on the nodes within ``dock_tolerance`` of their face
        and in front of it (``_ATTRACTION_CONE``), with :func:`magnet_pull` at the strut
        tip toward the node centre, and back on the node."""
        d = self.data
        d.xfrc_applied[self._strut_body] = 0.0
        d.xfrc_applied[self._node_body] = 0.0
        for k, i, tip, toward, gap, angle in self._magnets():
            if angle > _ATTRACTION_CONE:
                continue
            force = magnet_pull(gap, angle, self.phys.strength) * toward
            body = self._strut_body[k // 2]
            d.xfrc_applied[body, :3] += force
            d.xfrc_applied[body, 3:] += np.cross(tip - d.xipos[body], force)
            d.xfrc_applied[self._node_body[i], :3] -= force

    def _check_docks(self) -> None:
        """An extended free magnet docks on a node it touches (its face within
        ``_CONTACT`` of the seated stand-off) squarely (strut axis within ``_ALIGNMENT``
        of the node centre)."""
        for k, i, _, _, gap, angle in self._magnets():
            if gap <= _CONTACT and angle <= _ALIGNMENT and self.docked[k] is None:
                self._dock(k, self.nodes[i])

    def _odometry(self, duration: float) -> None:
        ball = self._ball(np.arange(len(self.ends)))
        moved = 2.0 * np.arccos(np.clip(np.abs(np.einsum("ni,ni->n", ball, self._last_ball)),
                                        0.0, 1.0))
        self._last_ball = ball.copy()
        docked = np.array([d is not None for d in self.docked])
        o = self.options
        if o.slip or o.drift:
            noise = self.rng.standard_normal((2, len(self.ends)))
            self._eps += docked * (o.slip * moved * noise[0] + o.drift * np.sqrt(duration)
                                   * noise[1])

    # -- reading ----------------------------------------------------------------------

    def reports(self) -> dict[str, NodeReport | StrutReport]:
        """Every module's report, with the run's noise; events since the previous call."""
        d = self.data
        node_rot = d.xmat[self._node_body].reshape(-1, 3, 3)
        node_yaw = heading(d.xquat[self._node_body])
        strut_rot = d.xmat[self._strut_body].reshape(-1, 3, 3)
        eps_rot = Rotation.from_rotvec(self._eps[:, None] * _EZ).as_matrix()
        located: dict[str, dict[str, np.ndarray]] = {n: {} for n in self.nodes}
        out: dict[str, NodeReport | StrutReport] = {}
        new = self.new_events()
        for j, strut in enumerate(self.struts):
            docked, attitude, magnet, rolled = {}, {}, {}, {}
            for end in ENDS:
                k = self._end_index[(strut, end)]
                node = self.docked[k]
                docked[end], magnet[end] = node, self.magnet[k]
                if node is None:
                    continue
                i = self._node_index[node]
                axis = self._sign[k] * strut_rot[j][:, 2]
                located[node][f"{strut}:{end}"] = self.noise.vector(node_rot[i].T @ axis)
                attitude[end] = self.noise.rotation(
                    rot_z(-node_yaw[i]) @ strut_rot[j] @ eps_rot[k])
                rolled[end] = self._encoders(k, node, node_rot[i].T @ strut_rot[j] @ eps_rot[k])
            tilt = rot_z(-float(heading(d.xquat[self._strut_body[j]]))) @ strut_rot[j]
            out[strut] = StrutReport(docked, attitude, self.noise.rotation(tilt), magnet,
                                     tuple(e for e in new if e.strut == strut), rolled,
                                     self._accuracy)
        for i, node in enumerate(self.nodes):
            out[node] = NodeReport(self.noise.rotation(rot_z(-node_yaw[i]) @ node_rot[i]),
                                   located[node], self._gyro[i].copy(), self._accuracy,
                                   self._turned[i].copy(), self.time, self._gyro_step)
        return out

    def _encoders(self, k: int, node: str, encoded: np.ndarray) -> np.ndarray:
        """Connector ``k``'s encoded rolling on ``node`` since it docked there, node frame
        (:attr:`StrutReport.rolled`): ``encoded`` (3, 3) is the strut's rotation in the
        node frame with the connector's odometry error; the first report after a dock
        fixes where its count starts."""
        start = self._encoded.get(k)
        if start is None or start[0] != node:
            start = self._encoded[k] = (node, encoded)
        return encoded @ start[1].T

    def ground_truth(self, root: str | None = None, *, name: str = "") -> Configuration:
        """The configuration the bodies form, from the simulator's state (never from reports).

        Vectors in the horizontal frame of ``root``, by default the world's: the judge
        turns a behavior's commanded direction onto it and measures the shift in the world
        (a node's frame turns with its shell, which its connectors roll on: fig22's
        rollers spun them by radians, issue 31); free strut ends are virtual vertices
        ``"<strut>:<end>"``.
        """
        d = self.data
        yaw = 0.0 if root is None else float(
            heading(d.xquat[self._node_body[self._node_index[root]]]))
        frame = rot_z(-yaw)
        config = Configuration("freesn", name=name)
        for node in self.nodes:
            config.add_module(node, "node")
        for j, strut in enumerate(self.struts):
            ends = []
            for end in ENDS:
                node = self.docked[self._end_index[(strut, end)]]
                if node is None:
                    node = f"{strut}:{end}"
                    config.add_virtual(node)
                ends.append(node)
            rot = frame @ d.xmat[self._strut_body[j]].reshape(3, 3)
            config.connect(ends[0], ends[1], id=strut, kind="strut", z=rot[:, 2], x=rot[:, 0])
        return config

    def saturation(self) -> dict[str, float]:
        """Connectors whose motors are saturated now: ``"<strut>:<end>"`` -> how long
        without a break [s] (see :meth:`_track_saturation`)."""
        return {f"{strut}:{end}": self.time - float(t)
                for (strut, end), t in zip(self.ends, self._saturated_since, strict=True)
                if not np.isnan(t)}

    def penetrations(self, depth: float = INTERPENETRATION) -> list[tuple[str, str, float]]:
        """Module bodies that interpenetrate by more than ``depth`` [m] now, from
        MuJoCo's contacts: ``(module, module, deepest penetration [m])``, each pair once,
        sorted. Every module body collides with every other (see
        :meth:`_record_interpenetrations`), so this is all the self-collision there is;
        the ground is not a module."""
        d = self.data
        n = d.ncon
        if not n:
            return []
        geoms = d.contact.geom[:n]
        dist = d.contact.dist[:n]
        module = self._geom_module[geoms]
        hit = (dist < -depth) & (module >= 0).all(axis=1)
        out: dict[tuple[str, str], float] = {}
        for (i, j), gap in zip(module[hit], dist[hit], strict=True):
            key = tuple(sorted((self._modules[i], self._modules[j])))
            out[key] = max(out.get(key, 0.0), float(-gap))
        return [(a, b, v) for (a, b), v in sorted(out.items())]

    def _record_interpenetrations(self) -> None:
        """Note each module pair that interpenetrates past :data:`INTERPENETRATION`
        (:attr:`interpenetrations`: when it first did, and its deepest since).

        Collision is not filtered: the only geoms that share a joint are a connector's
        wheels and the node they roll on (the spherical joint, a weld and a ball joint),
        and the wheels touch nothing but the floor. A strut's capsule stops ``_GAP``
        short of its node's shell, so a docked end never touches its own node, and
        meeting it is a magnet face landing on the shell; two struts on one node are
        two connectors on one shell and collide like any other bodies."""
        for a, b, depth in self.penetrations():
            seen = self.interpenetrations.get((a, b))
            if seen is None:
                self.interpenetrations[(a, b)] = Interpenetration(a, b, self.time, depth,
                                                                  depth)
            elif depth > seen.deepest:
                self.interpenetrations[(a, b)] = replace(seen, deepest=depth)

    def groups(self) -> list[frozenset[str]]:
        """Modules of each physically separate system (connected through docks)."""
        return connected_groups([*self.nodes, *self.struts],
                                ((self.ends[k][0], node) for k, node in enumerate(self.docked)
                                 if node is not None))


def magnet_pull(gap: float, tilt: float, strength: float, *, falloff: float = _MAGNET_FALLOFF,
                half_width: float = _MAGNET_HALF_WIDTH) -> float:
    """A magnet array's pull on a steel shell [N]: bounded by ``strength``, falling with
    the air gap; an askew face pressed on the shell pulls less than a square one.

    Maxwell's pull ``dF = B^2 / (2 mu0) dA`` with the flux density of a magnet of length
    ``l_m`` across an air gap ``g`` in series, ``B = B_r l_m / (l_m + mu_r g)`` (a
    magnetic circuit without leakage), is a pressure ``p(g) = p0 (g0 / (g0 + g))^2``,
    ``g0 = l_m / mu_r`` (``falloff``). A flat face of width ``2 w`` (``half_width``)
    tilted by ``tilt`` to the shell has a gap growing linearly across it, from ``g1`` at
    its near edge to ``g2 = g1 + 2 w sin(tilt)``; the face never goes nearer than
    touching (``g1 >= 0``). Averaged over the face::

        F = S g0^2 / ((g0 + g1) (g0 + g2)),   g1 = max(gap - w sin(tilt), 0)

    which is ``S (g0 / (g0 + gap))^2`` face-on, ``S`` (the connection strength) only
    when seated face-on, and ``S g0 / (g0 + 2 w sin(tilt))`` pressed on the shell askew
    (0.59 ``S`` at 10 deg). Farther out a tilt brings the near edge closer, so it pulls
    a little more than face-on (at most the face-on pull at the near edge's gap). The
    magnitudes (``S``, ``g0``, ``w``) are assumptions: no FreeSN source gives the
    magnet's size or its pull against the gap.

    Args:
        gap: the face centre's gap beyond the docked stand-off [m] (0 when seated;
            negative, pressed on the shell, counts as touching).
        tilt: angle between the face's normal (the strut axis) and the line to the node
            centre [rad].
        strength: the pull when seated face-on [N].
        falloff: ``g0`` [m]. half_width: ``w`` [m].
    """
    spread = half_width * np.sin(abs(tilt))
    near = max(gap - spread, 0.0)
    return float(strength * falloff**2 / ((falloff + near) * (falloff + near + 2.0 * spread)))


def _swing(q: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """The swing of quaternions ``(w, x, y, z)`` (n, 4) after removing their twist about
    unit ``axis`` (n, 3): ``q = swing * twist`` (swing-twist decomposition)."""
    along = np.einsum("ni,ni->n", q[:, 1:], axis)[:, None] * axis
    twist = np.column_stack([q[:, 0], along])
    norm = np.linalg.norm(twist, axis=1, keepdims=True)
    twist = np.where(norm > 1e-12, twist / np.maximum(norm, 1e-12), np.array([1.0, 0, 0, 0]))
    return quat_mul(q, quat_conj(twist))


def _wrap(angle: np.ndarray) -> np.ndarray:
    """Angles [rad] wrapped into ``(-pi, pi]``."""
    return np.pi - np.mod(np.pi - angle, 2.0 * np.pi)


def _minimal(v: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Minimal rotation (3, 3) taking unit ``v`` onto unit ``w``."""
    axis = np.cross(v, w)
    s = np.linalg.norm(axis)
    c = float(np.dot(v, w))
    if s < 1e-12:
        if c > 0:
            return np.eye(3)
        perp = np.cross(v, [1.0, 0, 0] if abs(v[0]) < 0.9 else [0, 1.0, 0])
        return Rotation.from_rotvec(np.pi * perp / np.linalg.norm(perp)).as_matrix()
    return Rotation.from_rotvec(axis / s * np.arctan2(s, c)).as_matrix()


def _level(z: np.ndarray, up: np.ndarray, ride: np.ndarray) -> np.ndarray | None:
    """Rotation (3, 3) with columns ``y x z``, ``y``, ``z``: unit ``z`` the strut's axis
    and ``y``, its wheels' axle, turned from the level axle ``l = up x z / |up x z|``
    (``up`` unit) as it was built (``ride``, the cosine and sine (2,) of the turn about
    ``z`` toward ``z x l``: :meth:`FreeSNWorld._ride_of`): level, on the side it was built
    on, for S4N1's legs; ``None`` where ``z`` lies within ``_AZIMUTH_FROM`` of the
    vertical (no level axle is defined there) or the ride is not known (``nan``).

    A leaf strut driving on its free connector's wheels, both on the floor, holds their
    axle level: then they roll along the leg's vertical plane, as S4N1's ``strut-wheels``
    gains assume (legs at any azimuth, their axles tangential, Fig. 18(d)), whatever twist
    the leg was built with (a few degrees off) or the turns on the way would give it; a
    kept twist turned those degrees of axle into tens of degrees of course (issue 31).
    The side and the tilt are the build's, not the axle's now: an axle the way turned
    past the vertical, levelled on its own side, rolls its wheels backwards, and a pair
    built tilted whose kept twist the way brought within 10 deg of level was levelled
    (issue 31, stop 50)."""
    y = np.cross(up, z)
    norm = np.linalg.norm(y)
    if norm < _AZIMUTH_FROM or np.isnan(ride[0]):
        return None
    y = y / norm
    y = ride[0] * y + ride[1] * np.cross(z, y)
    return np.column_stack([np.cross(y, z), y, z])


def node_travel(axis: np.ndarray, up: np.ndarray, along: float, across: float) -> np.ndarray:
    """The commanded travel (3,) of a node a node wheel spins, unit (zero for none), from
    the wheel's strut ``axis`` (3,) and the vertical ``up`` (3,) in one frame, and the
    travel's parts (any common scale): ``along`` the way the wheel rolls the node,
    ``d = axis x up`` made unit, and ``across`` along the strut's plan direction
    ``h = up x d`` (:mod:`.commands`)."""
    d = np.cross(axis, up)
    norm = float(np.linalg.norm(d))
    if norm < 1e-9:
        return np.zeros(3)
    d /= norm
    travel = along * d + across * np.cross(up, d)
    size = float(np.linalg.norm(travel))
    return travel / size if size > 1e-12 else np.zeros(3)


def swerve_heading(heading: np.ndarray, follower: np.ndarray, travel: np.ndarray
                   ) -> np.ndarray | None:
    """The heading (3,) [strut frame of ``follower``] that leaves a node held by a node
    wheel's strut, heading ``heading`` (3,), and by ``follower`` (3, 3: the strut's
    rotation, node frame) rolling along ``travel`` (3,, unit, level; node frame).

    Held by two differential connectors, the node turns only about ``n = x_W x x_F``
    (each grips about its heading) and so rolls along ``n x up``; that is ``travel``
    when ``n . travel = x_F . (travel x x_W) = 0``: ``x_F`` along ``z_F x (travel x
    x_W)``, of the two senses the one nearer the follower's heading now. ``None`` when
    there is no travel or any heading does (``travel`` along ``x_W``, or ``travel x
    x_W`` along ``z_F``)."""
    want = np.cross(follower[:, 2], np.cross(travel, heading))
    norm = float(np.linalg.norm(want))
    if norm < 1e-6:
        return None
    want /= norm
    want = want if float(want @ follower[:, 0]) >= 0.0 else -want
    return follower.T @ want


def _frame(z: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Rotation with columns ``x`` (made perpendicular), ``z x x``, ``z``."""
    z = z / np.linalg.norm(z)
    x = x - np.dot(x, z) * z
    norm = np.linalg.norm(x)
    if norm < 1e-9:
        x = np.cross(z, [1.0, 0, 0] if abs(z[0]) < 0.9 else [0, 1.0, 0])
        norm = np.linalg.norm(x)
    x = x / norm
    return np.column_stack([x, np.cross(z, x), z])
