"""Fault injection and the guard every run's driver goes through.

Two :class:`~msrr.core.driver.Driver` wrappers, both transparent when nothing happens:

* :class:`FaultyDriver` injects the faults of a ``--faults`` SPEC (:func:`parse_faults`),
  seeded, so a faulty run is repeatable;
* :class:`GuardedDriver` sits outside it (and around every driver of ``platform run``):
  it replaces non-finite readings (tracked poses, sensors) with the module's last
  finite one (the controller never sees a NaN), stops the run when the overall
  deadline of driver time has passed, reports each connection the simulator broke
  under its load, and stops the run at the first self-collision the simulator saw
  (module bodies interpenetrating).

Both report what happened as :class:`~msrr.core.events.FaultEvent` s through a callback
(``platform run`` fires ``msrr_on_fault`` with each, so the timeline logs them under
``events/faults``).

SPEC syntax: fault items separated by ``;``, each ``KIND`` or ``KIND:KEY=VALUE,...``;
times are driver time [s]:

=============  ==============================================  ==========================
kind           keys (default)                                  effect
=============  ==============================================  ==========================
``dropout``    ``module`` (required), ``at`` (0), ``for`` (inf)  the module ignores every
                                                               command (stops) from ``at``
                                                               for ``for`` seconds
``loss``       ``p`` (required, 0 <= p <= 1)                   each module's command of a
                                                               tick is lost with
                                                               probability ``p`` (it stops)
``latency``    ``ticks`` (required, >= 1)                      commands arrive ``ticks``
                                                               control ticks late
``dock-fail``  ``count`` (1), ``ticks`` (20)                   the first ``count`` dock
                                                               attempts do not latch for
                                                               ``ticks`` ticks
``noise``      ``sigma`` (required, [m]), ``yaw`` (0, [rad])   Gaussian noise on every
                                                               tracked position (heading):
                                                               a pose sensor's (MMRP)
``nan``        ``at`` (0), ``module`` (all), ``ticks`` (1),    the readings are NaN from
               ``reading`` (``pose`` or ``sensors``)           ``at`` for ``ticks``
                                                               observations: tracked poses, or
                                                               every number in the modules'
                                                               sensor data
=============  ==============================================  ==========================

Example: ``dropout:module=3,at=5;loss:p=0.05;latency:ticks=2;dock-fail:count=1;``
``noise:sigma=0.01;nan:at=3``.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass, field, fields, is_dataclass, replace
from functools import cache
from typing import Any

import numpy as np

from .configuration import Configuration
from .driver import Driver, ModuleCommand, Observation, Pose
from .errors import ConfigurationError, ExecutionError
from .events import FaultEvent
from .watchdog import DriverStalled
from .witness import Witness

__all__ = ["BREAK", "FAULT_KINDS", "SELF_COLLISION", "Fault", "FaultyDriver", "GuardedDriver",
           "check_fault_modules", "parse_faults"]

# kind -> {key: default}; ``None``: required
FAULT_KINDS: dict[str, dict[str, float | str | None]] = {
    "dropout": {"module": None, "at": 0.0, "for": math.inf},
    "loss": {"p": None},
    "latency": {"ticks": None},
    "dock-fail": {"count": 1, "ticks": 20},
    "noise": {"sigma": None, "yaw": 0.0},
    "nan": {"at": 0.0, "module": "", "ticks": 1, "reading": "pose"},
}
_TEXT_KEYS = {"module", "reading"}
_CHOICES = {"reading": ("pose", "sensors")}
_INTEGER_KEYS = {"ticks", "count"}

OnFault = Callable[[FaultEvent], None]

BREAK = "connector broke"
"""The kind of the :class:`FaultEvent` of a connection the driver saw break under its
load (its reason in :meth:`~msrr.core.driver.Driver.faults` and in library checks)."""

SELF_COLLISION = "self-collision"
"""The kind of the :class:`FaultEvent` of module bodies the driver saw interpenetrate
(its reason in :meth:`~msrr.core.driver.Driver.faults` and in library checks): the run
fails there."""


@dataclass(frozen=True)
class Fault:
    """One parsed fault item.

    Attributes:
        kind: one of :data:`FAULT_KINDS`.
        params: every key of the kind, defaults filled in.
    """

    kind: str
    params: Mapping[str, float | str] = field(default_factory=dict)

    def __str__(self) -> str:
        shown = ",".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}"
                         for k, v in self.params.items() if v != "" and v != math.inf)
        return f"{self.kind}:{shown}" if shown else self.kind


def _value(kind: str, key: str, text: str, where: str) -> float | str:
    if key in _TEXT_KEYS:
        if not text:
            raise ConfigurationError(f"{where}: {key} is empty", field="--faults")
        if key in _CHOICES and text not in _CHOICES[key]:
            raise ConfigurationError(f"{where}: {key} must be one of "
                                     f"{', '.join(_CHOICES[key])}, got {text!r}", field="--faults")
        return text
    try:
        value = float(text)
    except ValueError:
        raise ConfigurationError(f"{where}: {key}={text!r} is not a number",
                                 field="--faults") from None
    if math.isnan(value) or (math.isinf(value) and key != "for"):
        raise ConfigurationError(f"{where}: {key} must be finite, got {text!r}", field="--faults")
    if value < 0:
        raise ConfigurationError(f"{where}: {key} must be >= 0, got {text!r}", field="--faults")
    if key in _INTEGER_KEYS:
        if value != int(value) or value < 1:
            raise ConfigurationError(f"{where}: {key} must be a whole number >= 1, got {text!r}",
                                     field="--faults")
        return float(int(value))
    if key == "p" and value > 1:
        raise ConfigurationError(f"{where}: p must be at most 1, got {text!r}", field="--faults")
    return value


def parse_faults(spec: str, kinds: Mapping[str, Mapping[str, float | str | None]] = FAULT_KINDS
                 ) -> tuple[Fault, ...]:
    """``"loss:p=0.05;nan:at=3"`` -> the faults, defaults filled in (syntax: module docstring).

    ``kinds`` (default :data:`FAULT_KINDS`) lists the kinds and their keys another
    injector accepts in the same syntax (the link emulator's faults).

    Raises:
        ConfigurationError: an unknown kind or key, a missing required key, a repeated
            key, or a value out of range; the message names the item.
    """
    faults: list[Fault] = []
    for number, item in enumerate(part.strip() for part in spec.split(";")):
        if not item:
            continue
        kind, _, body = item.partition(":")
        kind = kind.strip()
        where = f"fault {number + 1} ({item!r})"
        if kind not in kinds:
            raise ConfigurationError(f"{where}: unknown kind {kind!r}; known: "
                                     f"{', '.join(kinds)}", field="--faults")
        known = kinds[kind]
        given: dict[str, float | str] = {}
        for pair in (p.strip() for p in body.split(",")) if body.strip() else ():
            key, sep, text = pair.partition("=")
            key = key.strip()
            if not sep:
                raise ConfigurationError(f"{where}: {pair!r} is not KEY=VALUE", field="--faults")
            if key not in known:
                raise ConfigurationError(f"{where}: unknown key {key!r}; {kind} takes "
                                         f"{', '.join(known)}", field="--faults")
            if key in given:
                raise ConfigurationError(f"{where}: {key} given twice", field="--faults")
            given[key] = _value(kind, key, text.strip(), where)
        missing = [k for k, default in known.items() if default is None and k not in given]
        if missing:
            raise ConfigurationError(f"{where}: {kind} needs {', '.join(missing)}",
                                     field="--faults")
        params = {k: given.get(k, default) for k, default in known.items()}
        faults.append(Fault(kind, params))  # type: ignore[arg-type]
    if not faults:
        raise ConfigurationError("no fault given (e.g. 'loss:p=0.05')", field="--faults")
    return tuple(faults)


def check_fault_modules(faults: Sequence[Fault], modules: Collection[str]) -> None:
    """Refuse a fault that names a module the run does not have (``dropout:module=99``).

    Args:
        faults: from :func:`parse_faults`.
        modules: the module ids of the run's start configuration.

    Raises:
        ConfigurationError: naming ``--faults``, the item and the modules there are.
    """
    for number, fault in enumerate(faults):
        module = fault.params.get("module")
        if isinstance(module, str) and module and module not in modules:
            known = sorted(modules, key=lambda m: (len(m), m))
            shown = ", ".join(known[:24]) + (", ..." if len(known) > 24 else "")
            raise ConfigurationError(f"fault {number + 1} ({fault}): no module {module!r} in "
                                     f"the run's start configuration (modules: {shown})",
                                     field="--faults")


class _Wrapper(Driver):
    """A driver that forwards everything to ``inner``."""

    def __init__(self, inner: Driver, on_fault: OnFault | None = None):
        self.inner = inner
        self.name = inner.name  # type: ignore[misc]
        self.description = inner.description  # type: ignore[misc]
        self.on_fault = on_fault or (lambda event: None)
        self.events: list[FaultEvent] = []

    def _report(self, kind: str, text: str, recovered: bool = True) -> None:
        event = FaultEvent(kind, text, self.inner.time, recovered)
        self.events.append(event)
        self.on_fault(event)

    @property
    def is_connected(self) -> bool:
        return self.inner.is_connected

    def connect(self) -> None:
        self.inner.connect()

    def disconnect(self) -> None:
        self.inner.disconnect()

    def reset(self, start: Configuration) -> None:
        self.inner.reset(start)

    def get_observation(self) -> Observation:
        return self.inner.get_observation()

    def send_action(self, commands: Mapping[str, ModuleCommand]) -> None:
        self.inner.send_action(commands)

    def step(self, dt: float) -> None:
        self.inner.step(dt)

    @property
    def time(self) -> float:
        return self.inner.time

    def witness(self) -> Witness | None:
        return self.inner.witness()

    def ground_truth(self) -> Configuration | None:
        return self.inner.ground_truth()

    def faults(self) -> list[str]:
        return self.inner.faults()

    def constraint_events(self) -> dict[str, int]:
        return self.inner.constraint_events()


class FaultyDriver(_Wrapper):
    """``inner`` with the faults of a SPEC injected, seeded.

    Args:
        inner: the driver to wrap.
        faults: from :func:`parse_faults`.
        seed: seed of the random faults (loss, noise).
        on_fault: called with a :class:`FaultEvent` each time a fault starts (and when
            a timed one ends).
    """

    def __init__(self, inner: Driver, faults: tuple[Fault, ...], *, seed: int = 0,
                 on_fault: OnFault | None = None):
        super().__init__(inner, on_fault)
        self.faults_spec = faults
        self.rng = np.random.default_rng(seed)
        self._queue: deque[dict[str, ModuleCommand]] = deque()
        self._state: dict[int, str] = {}  # per fault index: "", "active", "over"
        self._dock_attempts = 0
        self._dock_block: dict[tuple[str, str], int] = {}  # armed port -> ticks still blocked
        self._nan_left: dict[int, int] = {}

    def reset(self, start: Configuration) -> None:
        super().reset(start)
        self._queue.clear()
        self._state.clear()
        self._dock_attempts = 0
        self._dock_block.clear()
        self._nan_left.clear()

    def _of(self, kind: str) -> list[tuple[int, Fault]]:
        return [(i, f) for i, f in enumerate(self.faults_spec) if f.kind == kind]

    # -- commands -----------------------------------------------------------------------

    def send_action(self, commands: Mapping[str, ModuleCommand]) -> None:
        out = dict(commands)
        now = self.inner.time
        for index, fault in self._of("dropout"):
            module, at = str(fault.params["module"]), float(fault.params["at"])
            end = at + float(fault.params["for"])
            state = self._state.get(index, "")
            if at <= now < end:
                if state != "active":
                    self._state[index] = "active"
                    self._report("dropout", f"module {module} stopped responding"
                                 + ("" if math.isinf(end) else f" for {end - at:g} s"),
                                 recovered=False)
                out.pop(module, None)
            elif now >= end and state == "active":
                self._state[index] = "over"
                self._report("dropout", f"module {module} responds again")
        for _, fault in self._of("loss"):
            p = float(fault.params["p"])
            lost = [m for m in sorted(out) if self.rng.random() < p]
            for module in lost:
                del out[module]
            if lost:
                self._report("loss", f"commands of {', '.join(lost)} lost")
        out = self._fail_docks(out)
        for _, fault in self._of("latency"):
            self._queue.append(out)
            ticks = int(fault.params["ticks"])
            if len(self._queue) <= ticks:
                if len(self._queue) == 1:
                    self._report("latency", f"commands delayed by {ticks} ticks")
                out = {}
            else:
                out = self._queue.popleft()
            break  # one latency: the queue is shared
        self.inner.send_action(out)

    def _fail_docks(self, commands: dict[str, ModuleCommand]) -> dict[str, ModuleCommand]:
        faults = self._of("dock-fail")
        if not faults:
            return commands
        fault = faults[0][1]
        count, ticks = int(fault.params["count"]), int(fault.params["ticks"])
        armed = {(m, p) for m, c in commands.items() for p in c.dock}
        for port in list(self._dock_block):
            if port not in armed:
                del self._dock_block[port]  # the attempt ended
        blocked: set[tuple[str, str]] = set()
        for port in sorted(armed):
            if port not in self._dock_block and self._dock_attempts < count:
                self._dock_attempts += 1
                self._dock_block[port] = ticks
                self._report("dock-fail", f"dock of {port[0]} port {port[1]} fails for "
                             f"{ticks} ticks")
            left = self._dock_block.get(port, 0)
            if left > 0:
                self._dock_block[port] = left - 1
                blocked.add(port)
        if not blocked:
            return commands
        return {m: replace(c, dock=tuple(p for p in c.dock if (m, p) not in blocked))
                for m, c in commands.items()}

    # -- readings -----------------------------------------------------------------------

    def get_observation(self) -> Observation:
        observation = self.inner.get_observation()
        poses = dict(observation.tracked)
        for index, fault in self._of("noise"):
            sigma, yaw_sigma = float(fault.params["sigma"]), float(fault.params["yaw"])
            if self._state.get(index) != "active":
                self._state[index] = "active"
                self._report("noise", f"Gaussian noise on every reading: {sigma:g} m"
                             + (f", {yaw_sigma:g} rad" if yaw_sigma else ""))
            for module in sorted(poses):
                pose = poses[module]
                position = pose.position + self.rng.normal(0.0, sigma, 3) * (1, 1, 0)
                orientation = pose.orientation
                if yaw_sigma > 0:
                    turned = Pose.planar(0, 0, float(self.rng.normal(0.0, yaw_sigma)))
                    orientation = _quat_mul(turned.orientation, orientation)
                poses[module] = Pose(position, orientation)
        sensors = observation.sensors
        for index, fault in self._of("nan"):
            if observation.time + 1e-9 < float(fault.params["at"]):
                continue
            left = self._nan_left.setdefault(index, int(fault.params["ticks"]))
            if left <= 0:
                continue
            self._nan_left[index] = left - 1
            target = str(fault.params["module"])
            if fault.params["reading"] == "sensors":
                if isinstance(sensors, Mapping):
                    hit = [m for m in sorted(sensors) if not target or m == target]
                    sensors = {m: _poisoned(r) if m in hit else r for m, r in sensors.items()}
                else:
                    hit, sensors = ["every module"], _poisoned(sensors)
            else:
                hit = [m for m in sorted(poses) if not target or m == target]
                for module in hit:
                    poses[module] = Pose(np.full(3, np.nan), np.full(4, np.nan))
            if left == int(fault.params["ticks"]):
                self._report("nan", f"NaN {fault.params['reading']} reading of "
                             f"{', '.join(hit) or 'no module'}")
        if sensors is not observation.sensors:
            return replace(observation, tracked=poses, sensors=sensors)
        return replace(observation, tracked=poses)


def _poisoned(value: Any) -> Any:
    """``value`` with every float (also in arrays, mappings, sequences and dataclasses)
    replaced by NaN."""
    if isinstance(value, np.ndarray) and value.dtype.kind == "f":
        return np.full_like(value, np.nan)
    if isinstance(value, float):
        return math.nan
    if isinstance(value, Mapping):
        return {k: _poisoned(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return type(value)(_poisoned(v) for v in value)
    if is_dataclass(value) and not isinstance(value, type):
        return replace(value, **{f.name: _poisoned(getattr(value, f.name))
                                 for f in fields(value) if f.init})
    return value


def _finite(value: Any, depth: int = 0) -> bool:
    """Whether every number in ``value`` (arrays, mappings, sequences, dataclasses) is
    finite."""
    if depth > 20 or value is None or isinstance(value, str | int):  # the common leaves
        return True
    if isinstance(value, float):
        return math.isfinite(value)
    if isinstance(value, np.ndarray):    # before the Mapping check (an ABC's is slow)
        if value.dtype.kind == "f" and value.size <= 16:  # a pose: plain floats are faster
            return all(map(math.isfinite, value.ravel().tolist()))
        return value.dtype.kind not in "fc" or bool(np.isfinite(value).all())
    if isinstance(value, list | tuple):
        return all(_finite(v, depth + 1) for v in value)
    if isinstance(value, dict | Mapping):
        return all(_finite(v, depth + 1) for v in value.values())
    names = _field_names(type(value))
    return all(_finite(getattr(value, name), depth + 1) for name in names)


@cache
def _field_names(kind: type) -> tuple[str, ...]:
    """The field names of a dataclass type (none for another type), found once per type
    (the guard reads every module's report every tick)."""
    return tuple(f.name for f in fields(kind)) if is_dataclass(kind) else ()


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of quaternions ``(x, y, z, w)``."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz])


class GuardedDriver(_Wrapper):
    """``inner`` with sanitized readings, an overall deadline of driver time and of wall
    time, and its calls watched.

    A pose, or a module's sensor data (``sensors[module]``: every float in its arrays,
    mappings, sequences and dataclasses), with a non-finite number is replaced by the
    module's last finite one (a ``"nan"`` :class:`FaultEvent` reports it, once per run of
    bad readings); a module that has never had a finite reading stops the run
    (:class:`ExecutionError`). A :meth:`step` past ``deadline`` seconds of driver time
    (or of steps asked for, should the driver's clock stop), or past ``wall_deadline``
    seconds of wall time since the guard was made, stops the run likewise, and so does
    a self-collision the driver saw (``"self-collision: ..."`` of
    :meth:`~msrr.core.driver.Driver.faults`, since the reset: the start's own overlaps
    too), checked after every step: a ``"self-collision"`` :class:`FaultEvent` names
    the bodies, how deep and when, and the :class:`ExecutionError` carries the same
    line. :attr:`busy` names the call in progress, for the
    :class:`~msrr.core.watchdog.Watchdog` that ends one that does not return; once it has set :attr:`stopped`, every further call but
    the clean-up's (``send_action``, ``disconnect``) raises.

    Args:
        inner: the driver to wrap.
        deadline: driver time [s] after which :meth:`step` raises; ``inf`` for none.
        wall_deadline: wall time [s] after which :meth:`step` raises; ``inf`` for none.
        on_fault: called with each :class:`FaultEvent`.

    Attributes:
        busy: ``(call, since)`` while a call of ``inner`` runs (``since`` on
            :func:`time.monotonic`), else ``None``.
        stopped: why the watchdog stopped the driver (``""``: it did not).
    """

    def __init__(self, inner: Driver, *, deadline: float = math.inf,
                 wall_deadline: float = math.inf, on_fault: OnFault | None = None):
        super().__init__(inner, on_fault)
        self.deadline = deadline
        self.wall_deadline = wall_deadline
        self.wall_end = time.monotonic() + wall_deadline
        self.busy: tuple[str, float] | None = None
        self.stopped = ""
        self._stepped = 0.0
        self._switches: dict[str, int] = {}
        self._broke: set[str] = set()
        self._last: dict[tuple[str, str], Any] = {}
        self._bad: set[tuple[str, str]] = set()

    def extend(self, driver_time: float, wall_time: float) -> None:
        """Move the deadlines ``driver_time`` and ``wall_time`` seconds later (a phase
        granted the time its controller says it needs)."""
        self.deadline += driver_time
        self.wall_deadline += wall_time
        self.wall_end += wall_time

    def _call(self, name: str, call: Callable[..., Any], *args: Any, clean_up: bool = False
              ) -> Any:
        """``call(*args)`` with :attr:`busy` set; refused once the watchdog stopped the
        driver, unless ``clean_up``."""
        if self.stopped and not clean_up:
            raise DriverStalled(self.stopped)
        self.busy = (name, time.monotonic())
        try:
            return call(*args)
        finally:
            self.busy = None

    def connect(self) -> None:
        self._call("connect", self.inner.connect)

    def disconnect(self) -> None:
        self._call("disconnect", self.inner.disconnect, clean_up=True)

    def send_action(self, commands: Mapping[str, ModuleCommand]) -> None:
        self._call("send_action", self.inner.send_action, commands, clean_up=not commands)

    def reset(self, start: Configuration) -> None:
        self._call("reset", self.inner.reset, start)
        self._stepped = 0.0
        self._switches = {}
        self._broke = set()
        self._last.clear()
        self._bad.clear()

    def _hold(self, what: str, readings: Mapping[str, Any], time: float,
              finite: Callable[[Any], bool]) -> dict[str, Any]:
        """``readings`` with each non-finite one replaced by the module's last finite one."""
        out: dict[str, Any] = {}
        bad: list[str] = []
        for module, reading in readings.items():
            key = (what, module)
            if finite(reading):
                out[module] = self._last[key] = reading
                self._bad.discard(key)
                continue
            if key not in self._last:
                self._report("nan", f"non-finite {what} of module {module} and no earlier "
                             "reading to hold", recovered=False)
                raise ExecutionError(f"non-finite {what} reading of module {module} at "
                                     f"t={time:.1f} s with no earlier finite one")
            out[module] = self._last[key]
            if key not in self._bad:
                bad.append(module)
                self._bad.add(key)
        if bad:
            self._report("nan", f"non-finite {what} of {', '.join(bad)} ignored; last finite "
                         f"{what} held")
        return out

    def get_observation(self) -> Observation:
        observation = self._call("get_observation", self.inner.get_observation)
        poses = self._hold("pose", observation.tracked, observation.time,
                           lambda p: _finite(p.position) and _finite(p.orientation))
        sensors = observation.sensors
        if isinstance(sensors, Mapping):
            sensors = self._hold("sensors", sensors, observation.time, _finite)
        elif not _finite(sensors):
            sensors = self._hold("sensors", {"(all)": sensors}, observation.time,
                                 _finite)["(all)"]
        return replace(observation, tracked=poses, sensors=sensors)

    def step(self, dt: float) -> None:
        # the sum of the steps asked for also counts: a driver whose clock stopped
        # cannot keep a run going forever
        self._stepped += dt
        if max(self.inner.time + dt, self._stepped) > self.deadline + 1e-9:
            self._report("deadline", f"run deadline of {self.deadline:g} s of driver time "
                         "reached", recovered=False)
            raise ExecutionError(f"run deadline of {self.deadline:g} s of driver time reached "
                                 "(--deadline)")
        if time.monotonic() > self.wall_end:
            self._report("deadline", f"run deadline of {self.wall_deadline:g} s of wall time "
                         "reached", recovered=False)
            raise ExecutionError(f"run deadline of {self.wall_deadline:g} s of wall time "
                                 "reached (--wall-deadline)")
        self._call("step", self.inner.step, dt)
        self._breaks()
        self._collisions()

    def _collisions(self) -> None:
        """Stop the run at the first self-collision the driver saw (``"self-collision:
        ..."`` of :meth:`~msrr.core.driver.Driver.faults`), reported as a
        ``"self-collision"`` :class:`FaultEvent`."""
        for text in self.inner.faults():
            reason, _, details = text.partition(": ")
            if reason == SELF_COLLISION:
                self._report(SELF_COLLISION, details, recovered=False)
                raise ExecutionError(text)

    def _breaks(self) -> None:
        """Report each connection the driver saw break (``"connector broke: ..."`` of
        :meth:`~msrr.core.driver.Driver.faults`) once, as a ``"connector broke"``
        :class:`FaultEvent`: read when the driver's constraint switches change."""
        switches = self.inner.constraint_events()
        if switches == self._switches:
            return
        self._switches = switches
        for text in self.inner.faults():
            reason, _, details = text.partition(": ")
            if reason == BREAK and text not in self._broke:
                self._broke.add(text)
                self._report(BREAK, details)


def unwrap(driver: Any) -> Any:
    """The innermost driver under any :class:`FaultyDriver`/:class:`GuardedDriver`."""
    while isinstance(driver, _Wrapper):
        driver = driver.inner
    return driver
