"""Options of one FreeSN simulation run and the physical parameters they resolve to."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

from msrr.core.driver import DriverOption
from msrr.core.errors import ExecutionError
from msrr.core.freeform.mujoco import MujocoOptions
from msrr.core.robot import RobotSpec

__all__ = ["Physical", "SimOptions"]


@dataclass(frozen=True, kw_only=True)
class SimOptions(MujocoOptions):
    """How one simulation runs (a :class:`~msrr.core.freeform.mujoco.MujocoOptions`);
    hardware figures come from the robot spec.

    Attributes:
        timestep: physics step [s].
        noise: standard deviation of every reported angle (localisation, IMU tilt,
            module attitude) [rad], white, per observation.
        drift: random walk of each connector's odometry heading [rad / sqrt(s)].
        slip: heading error of a connector per radian it rolls, standard deviation
            [rad / rad]; the wheels slip unseen by the encoders, so the connector's own
            estimate (and the physical pose it servos to) drifts from the truth.
        strength_factor: connection strength as a fraction of the hardware's; below 1
            as the FreeSN paper's section 6.2 asks, so what passes in simulation holds
            on the robot (the paper gives no factor: 0.5 is assumed).
        torque_factor: connector torque limit as a fraction of the hardware's (6.2;
            0.6 assumed likewise).
        position_gain: connector position loop gain [1/s] (speed command per rad of error).
            The strut firmware's is 25 wheel rad/s per rad, 4.3 1/s of rolling
            (docs/freesn.md, "Hardware parameters and their sources"); 40 is this
            simulation's tuning.
        integral_gain: its integral gain [1/s^2] (speed command per rad s of error;
            bounded by the roll rate), which removes the static error a friction load
            leaves; 0 is a pure position loop. The firmware's is 0.2 wheel rad/s per
            rad s; 400 is this simulation's tuning.
        integral_bound: the integral's anti-windup bound: its speed command at most this
            fraction of the roll rate (issue 31; 1: the whole roll rate, so a connector
            held off its target by a load pushes with the full torque at any error).
        integral_band: the servo error the integral leaves alone, in units of the rms error
            the connector's own estimates put in it (``fusion``'s filtered noise of its
            node's attitude and of its fix, ``sqrt(6) noise b / sqrt(1 - (1 - b)^2)``;
            0 without noise): what lies within it the connector cannot tell from its
            estimates' wander, which, integrated to the bound, pushed the structure's
            loops and feet against each other (issue 31, stop 48: fig18's node wheels at
            fusion 0.05). The band stops an integral growing, not shrinking, and a
            structure pressing a dock takes its whole error (stop 49: fig21's closing
            dock at 4 deg). 0: the whole error, as before.
        servo_rate: rate of the connectors' motor loops and of the load check [Hz]; the
            default 250 is the strut firmware's base control period, 4 ms.
        break_filter: time constant of the connection-load low-pass before the strength
            check [s] (a magnet does not let go on a one-step impulse).
        fusion: weight of a fresh reading in the estimates a connector servos on, fused
            at each command (10 Hz): its node's IMU attitude (the accelerometer into the
            gyro-propagated attitude) and its own pose on the node (a magnetic fix into
            its encoders); the estimate's error is ``e <- (1 - b) (e + drift) + b n``
            (std ``b / sqrt(1 - (1 - b)^2)`` of the noise, about 0.10 at 0.02, 0.16 at
            0.05, 0.33 at 0.2). 0.02 (about 5 s) since issue 31 stop 49: at 0.2 (0.45 s)
            the connectors holding fig22(j) chased their fixes' 1.3 deg jitter at 4 deg
            of noise and its top sank to the floor held still (0.05 from stop 47); at
            0.05 their slower wander still bent the S12N6 crawl's bar and turned the node
            wheels; the gyros' drift over 5 s is 0.14 deg.
        gyro_bias: standard deviation of each node gyro's constant bias per axis
            [rad/s], drawn once per run (what is left after calibrating at rest).
        gyro_walk: random walk of that bias (bias instability) [rad/s / sqrt(s)].
        gyro_noise: the gyro's angle random walk [rad / sqrt(s)] (its white rate noise).
        seed: seed of the noise, drift, slip and gyro generators.
        connector_drive: ``"differential"``: a docked connector is the paper's two-wheel
            differential drive (Fig. 11), which rolls and turns on its node but grips
            sideways; ``"holonomic"``: three torques on its ball joint (the model before
            issue 32 item 6, kept to compare).

    The gyro figures are assumptions of a MEMS IMU calibrated at start-up (the FreeSN
    papers name no part): rate noise about 0.01 deg/s/sqrt(Hz) (1.7e-4 rad/sqrt(s)) as a
    consumer MEMS gyro's data sheet gives, a residual bias of 0.03 deg/s, and a bias
    instability of the same order per minute.
    """

    OPTIONS: ClassVar[tuple[DriverOption, ...]] = MujocoOptions.OPTIONS + (
        DriverOption("connector_drive", str, "docked connectors: two-wheel drives or 3-axis "
                     "torques", choices=("differential", "holonomic")),
        DriverOption("drift", float, "random walk of each connector's odometry heading",
                     "rad/sqrt(s)", 0.0, 1.0),
        DriverOption("slip", float, "heading error of a connector per radian it rolls (std)",
                     "rad/rad", 0.0, 1.0),
        DriverOption("strength_factor", float, "connection strength / the hardware's", "",
                     0.0, 10.0, low_open=True),
        DriverOption("torque_factor", float, "connector torque limit / the hardware's", "",
                     0.0, 10.0, low_open=True),
        DriverOption("integral_gain", float, "connector integral gain", "1/s^2", 0.0, 1e5),
        DriverOption("integral_bound", float, "integral's command / the roll rate", "",
                     0.0, 1.0, low_open=True),
        DriverOption("fusion", float, "weight of a fresh reading in a connector's attitude and "
                     "pose estimates", "", 0.0, 1.0, low_open=True),
        DriverOption("integral_band", float, "error band the integral leaves to the estimates, "
                     "in their rms", "", 0.0, 10.0),
        DriverOption("break_filter", float, "time constant of the connection-load filter", "s",
                     0.0, 10.0, low_open=True),
        DriverOption("gyro_bias", float, "std of each node gyro's constant bias", "rad/s",
                     0.0, 1.0),
        DriverOption("gyro_walk", float, "random walk of the gyro bias", "rad/s/sqrt(s)",
                     0.0, 1.0),
        DriverOption("gyro_noise", float, "gyro angle random walk", "rad/sqrt(s)", 0.0, 1.0),
    )

    connector_drive: str = "holonomic"
    drift: float = 0.0
    slip: float = 0.0
    strength_factor: float = 0.5
    torque_factor: float = 0.6
    position_gain: float = 40.0
    integral_gain: float = 400.0
    integral_bound: float = 1.0
    break_filter: float = 0.05
    fusion: float = 0.02
    integral_band: float = 2.0
    gyro_bias: float = 5e-4
    gyro_walk: float = 1e-4
    gyro_noise: float = 2e-4

    def __post_init__(self) -> None:
        super().__post_init__()
        self._check(positive=("strength_factor", "torque_factor", "break_filter",
                              "integral_bound", "fusion"),
                    non_negative=("drift", "slip", "integral_gain", "integral_band", "gyro_bias", "gyro_walk",
                                  "gyro_noise"))
        if self.connector_drive not in ("differential", "holonomic"):
            raise ExecutionError(f"connector_drive must be 'differential' or 'holonomic', "
                                 f"got {self.connector_drive!r}")


@dataclass(frozen=True)
class Physical:
    """The figures the world is built from: spec geometry scaled by the options.

    Attributes:
        node_radius: [m]. node_mass: [kg].
        strut_length: node centre to node centre of a strut docked at both ends [m].
        strut_radius: [m]. strut_mass: [kg], connectors included.
        connector_mass: [kg] each.
        max_torque: connector torque limit used in simulation [N m].
        max_roll_rate: fastest rolling of a connector over its node [rad/s] about the
            node centre (wheel speed x wheel radius / node radius).
        max_spin_rate: fastest turn of a strut about its axis [rad/s] (the two wheels
            in opposition: 2 x wheel speed x wheel radius / wheel base).
        damping: motor back-EMF damping [N m s/rad] = torque / roll rate (a DC motor's
            linear torque-speed line from stall to no-load speed).
        strength: connection strength used in simulation [N].
        dock_tolerance: range of an extended magnet's pull: its gap to a node surface [m].
        wheel_radius: [m]. wheel_base: distance between a connector's two wheels [m].
        max_wheel_speed: [rad/s], the bound of a ``wheel_speed`` command.
        wheel_torque: torque limit of a connector's wheel pair about its axle [N m]: the
            connector's drive force at the node surface (``max_torque / node_radius``)
            times the wheel radius.
        wheel_damping: back-EMF damping of the wheel pair [N m s/rad] (stall torque over
            no-load speed, as ``damping``).
        roll_ratio: rolling of a docked connector's wheels per radian it rolls about the
            node centre, ``node_radius / wheel_radius`` [rad/rad].
        turn_ratio: wheel radians (each wheel, in opposition) per radian the strut turns
            about its axis, ``wheel_base / (2 wheel_radius)`` [rad/rad].
        grip: side grip of a docked connector's wheels on the node shell [N]: the
            largest sideways force before they skid, the wheels' friction coefficient
            (polyurethane on steel, ``wheel_friction``) times the magnet's pull, the
            connection strength.
    """

    node_radius: float
    node_mass: float
    strut_length: float
    strut_radius: float
    strut_mass: float
    connector_mass: float
    max_torque: float
    max_roll_rate: float
    max_spin_rate: float
    damping: float
    strength: float
    dock_tolerance: float
    wheel_radius: float
    wheel_base: float
    max_wheel_speed: float
    wheel_torque: float
    wheel_damping: float
    roll_ratio: float
    turn_ratio: float
    grip: float

    @classmethod
    def from_spec(cls, spec: RobotSpec, options: SimOptions, *, wheel_friction: float = 1.0
                  ) -> Physical:
        """Read ``spec``'s ``node`` and ``strut`` geometry; errors name the missing key."""
        node = _geometry(spec, "node")
        strut = _geometry(spec, "strut")
        wheel_speed = strut["max_wheel_speed"] * strut["wheel_radius"]  # [m/s] at the surface
        roll = wheel_speed / node["radius"]
        torque = strut["max_torque"] * options.torque_factor
        wheel_torque = torque / node["radius"] * strut["wheel_radius"]
        return cls(
            node_radius=node["radius"], node_mass=node["mass"],
            strut_length=strut["length"], strut_radius=strut["radius"],
            strut_mass=strut["mass"], connector_mass=strut["connector_mass"],
            max_torque=torque, max_roll_rate=roll,
            max_spin_rate=2.0 * wheel_speed / strut["wheel_base"],
            damping=torque / roll,
            strength=strut["connection_strength"] * options.strength_factor,
            dock_tolerance=strut["dock_tolerance"],
            wheel_radius=strut["wheel_radius"], wheel_base=strut["wheel_base"],
            max_wheel_speed=strut["max_wheel_speed"], wheel_torque=wheel_torque,
            wheel_damping=wheel_torque / strut["max_wheel_speed"],
            roll_ratio=node["radius"] / strut["wheel_radius"],
            turn_ratio=0.5 * strut["wheel_base"] / strut["wheel_radius"],
            grip=wheel_friction * strut["connection_strength"] * options.strength_factor,
        )


_NEEDED = {
    "node": ("radius", "mass"),
    "strut": ("length", "radius", "mass", "connector_mass", "wheel_radius", "wheel_base",
              "max_wheel_speed", "max_torque", "connection_strength", "dock_tolerance"),
}


def _geometry(spec: RobotSpec, kind: str) -> Mapping[str, float]:
    geometry = spec.kind(kind).geometry
    for key in _NEEDED[kind]:
        if key not in geometry:
            raise ExecutionError(f"robot {spec.name!r}: module kind {kind!r} has no geometry "
                                 f"{key!r}, which the MuJoCo world needs")
    return {k: float(v) for k, v in geometry.items()}
