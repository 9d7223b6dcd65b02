"""The payloads of the run event hooks (DESIGN section 5).

The executor builds these and fires them through :data:`msrr.core.plugins.emit`;
listeners (the rerun timeline, progress bars, loggers) read them and never change
them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

from .configuration import Configuration
from .driver import ModuleCommand, Observation
from .plan import Action, ConnectionChange, Plan
from .robot import RobotSpec
from .shape import ShapeVerdict

if TYPE_CHECKING:  # the executor imports this module, never the witness channel
    from .witness import Witness

__all__ = ["GROUND_TRUTH", "REPORTED", "ActionStatus", "BehaviorVerdict", "EventSink",
           "FaultEvent", "GoalVerdict", "NoEvents", "Phase", "Run", "RunResult", "Tick",
           "TopologyEvent"]


class ActionStatus(StrEnum):
    """Statuses an action goes through, in ``msrr_on_action(run, action, status)``."""

    STARTED = "started"
    SUCCEEDED = "succeeded"
    RETRYING = "retrying"
    REDOCKING = "redocking"
    FAILED = "failed"


class Phase(StrEnum):
    """Stage of an action's execution (FreeSN paper, Figs. 9-10).

    ``release``: undock commands sent, waiting for the disconnection to be detected;
    ``move``: moving to the target without topology change;
    ``approach``: moving to the pre-connection configuration S_conn;
    ``connect``: dock commands armed while pushing to the extruded S_extr;
    ``behavior``: a mapping behavior's module commands sent every tick while the shape
    is held, for its duration or distance (sections 4.3, 6.3);
    ``flow``: a flow's leaf moves over its parent, still docked, until it touches the
    new parent (section 4.1, Flow; no dock or undock is sent);
    ``handover``: the leaf docks to the new parent and undocks from the old at once,
    until both changes are detected.
    """

    RELEASE = "release"
    BEHAVIOR = "behavior"
    MOVE = "move"
    APPROACH = "approach"
    CONNECT = "connect"
    FLOW = "flow"
    HANDOVER = "handover"


@dataclass
class Run:
    """One execution of a plan: what listeners need to know about it.

    Attributes:
        robot: the robot's name.
        scenario: scenario name, or ``"custom"`` for ``--from/--to`` runs.
        plan: the plan being executed (start, goal, actions in the start's ids).
        spec: the robot's description; listeners draw modules from its module kinds'
            ``ports`` and ``geometry``.
        driver: name of the driver.
        rate: control rate [Hz].
        seed: seed of the run.
        out_dir: folder the run writes to, or ``None``.
        recording: path of the rerun recording to write, or ``None`` for no log.
    """

    robot: str
    scenario: str
    plan: Plan
    spec: RobotSpec
    driver: str = ""
    rate: float = 10.0
    seed: int = 0
    out_dir: Path | None = None
    recording: Path | None = None

    @property
    def start(self) -> Configuration:
        return self.plan.start

    @property
    def goal(self) -> Configuration:
        return self.plan.goal


@dataclass(frozen=True)
class Tick:
    """The state of one executed control tick.

    Attributes:
        index: tick number from 0.
        time: driver time after the tick [s].
        action_index: index of the action in the plan.
        action: the action being executed.
        phase: its stage.
        observation: what the driver reported at the start of the tick.
        configuration: the recognized configuration (from the filtered reports, where the
            recognizer filters them: :func:`~msrr.core.estimation.report_filter_for`).
        commands: the module commands sent.
        errors: per-module distance to its goal [m] as the controller measures it.
        witness: the simulator's own state after the tick, for the recording (``None``
            as the executor sends it: ``platform run`` adds it for its listeners; see
            :mod:`msrr.core.witness`).
    """

    index: int
    time: float
    action_index: int
    action: Action
    phase: Phase
    observation: Observation
    configuration: Configuration
    commands: Mapping[str, ModuleCommand]
    errors: Mapping[str, float]
    witness: Witness | None = None


@dataclass(frozen=True)
class TopologyEvent:
    """A connection made (``"dock"``) or broken (``"undock"``), as recognized.

    Attributes:
        kind: ``"dock"`` or ``"undock"``.
        change: the connection, with its ports.
        tick: tick index at which it was detected.
        time: driver time [s].
        action_index: the action running then (``-1`` outside any action).
        expected: whether the running action asked for it.
    """

    kind: str
    change: ConnectionChange
    tick: int
    time: float
    action_index: int
    expected: bool

    def __str__(self) -> str:
        return f"{self.kind} {self.change}"


@dataclass(frozen=True)
class FaultEvent:
    """A fault that happened during a run: injected (``--faults``) or caught by the guard.

    Attributes:
        kind: ``dropout``, ``loss``, ``latency``, ``dock-fail``, ``noise``, ``nan``,
            ``deadline`` or ``connector broke`` (see :mod:`msrr.core.faults`).
        text: one line on what happened ("module 3 stopped responding").
        time: driver time [s].
        recovered: whether the run carries on normally (``False``: it may stop).
    """

    kind: str
    text: str
    time: float
    recovered: bool = True

    def __str__(self) -> str:
        return f"{self.kind}: {self.text} at t={self.time:.1f} s"


GROUND_TRUTH = "ground truth"
"""The basis of a verdict made on the simulator's own state."""

REPORTED = "what the modules report (the driver has no ground truth)"
"""The basis of a verdict made where the driver has no ground truth (hardware)."""


@dataclass(frozen=True)
class GoalVerdict:
    """A goal judged where it was reached (or where the run ended).

    Attributes:
        name: the goal's name (``"S6N3-4.1"``).
        action_index: the action that ended at it (``None`` for the run's end).
        time: driver time of the verdict [s].
        topology: whether the topology is the goal's.
        shape: the shape figure, or ``None`` when there is none to measure.
        basis: what it was judged on (:data:`GROUND_TRUTH` or :data:`REPORTED`).
        success: reached.
        reason: one line when not.
    """

    name: str
    action_index: int | None
    time: float
    topology: bool
    shape: ShapeVerdict | None
    basis: str
    success: bool
    reason: str = ""

    def summary(self) -> dict[str, object]:
        """JSON-ready (``summary.json``)."""
        return {"name": self.name, "action": self.action_index, "time_s": round(self.time, 3),
                "topology": self.topology,
                "shape": None if self.shape is None else self.shape.summary(),
                "basis": self.basis, "success": self.success, "reason": self.reason}


@dataclass(frozen=True)
class BehaviorVerdict:
    """What a behavior did (FreeSN paper, section 7.3), against what it was asked.

    Attributes:
        name: the behavior (``"wheeled-move(speed=0.05, yaw_rate=0)"``).
        first_action: index of its first action.
        actions: actions it ran.
        duration: driver time it ran [s].
        distance: horizontal distance the centre of the modules moved [m].
        along: that motion along the commanded direction [m], ``None`` when the
            behavior states no direction.
        asked: the distance asked [m] (``distance``, or ``speed`` x ``duration``),
            ``None`` when it asks none.
        heading_error: angle [rad] between the direction travelled and the commanded
            one, ``None`` when either is unknown or it moved under 1 cm.
        basis: what it was judged on.
        success: it did what was asked.
        reason: one line when not.
    """

    name: str
    first_action: int
    actions: int
    duration: float
    distance: float
    along: float | None
    asked: float | None
    heading_error: float | None
    basis: str
    success: bool
    reason: str = ""

    def summary(self) -> dict[str, object]:
        """JSON-ready (``summary.json``)."""
        return {"behavior": self.name, "first_action": self.first_action,
                "actions": self.actions, "duration_s": round(self.duration, 3),
                "distance_m": round(self.distance, 4),
                "along_m": None if self.along is None else round(self.along, 4),
                "asked_m": None if self.asked is None else round(self.asked, 4),
                "heading_error_deg": None if self.heading_error is None
                else round(math.degrees(self.heading_error), 2),
                "basis": self.basis, "success": self.success, "reason": self.reason}


@dataclass
class RunResult:
    """The summary of a run.

    Attributes:
        success: every action finished, the final topology is the goal's and, where the
            robot declares a ``shape_tolerance``, every module is within it (``shape``).
        reason: one line on failure ("action 4 (connection 4T-5B) timed out ...").
        failed_action: index of the failing action, if one failed.
        actions_done: actions that succeeded.
        actions_total: actions in the plan.
        actions_skipped: loops of a sequence behavior left out once its distance was
            covered.
        docks: connections made, counted from what the driver reported.
        undocks: connections broken, likewise.
        flows: flow actions whose handover the driver reported (its undock and dock
            are also counted in ``undocks`` and ``docks``).
        simulator: docks, undocks and flows counted from the simulator's own constraint
            switches (:meth:`~msrr.core.driver.Driver.constraint_events`), ``{}`` where the
            driver cannot tell.
        retries: action attempts repeated after a timeout.
        ticks: control ticks executed.
        sim_time: driver time at the end [s].
        wall_time: wall-clock duration of the execution [s].
        final: the configuration recognized at the end.
        goal: the plan's goal as judged at the end (:mod:`msrr.core.judge`), ``None``
            when the run did not get there.
        faults: the faults met, in order.
        interrupted: the signal that stopped the run (``"SIGINT"``), or ``""``.
        targets: every goal reached on the way (a scenario's stages), judged there.
        locomotion: every behavior run, judged against what it was asked.
        settled: moves that stalled on their last attempt within the executor's settle
            tolerance and were taken as reached, one line each ("action 18 (...) settled
            at 4.2 deg estimated"): the judge, not the move, decides whether they were.
        redocked: connections that broke unplanned (a strut end's load over its
            strength) and were docked again before the action went on, one line each
            ("action 7: n2-s7a broke at 127.6 s, re-docked at 131.2 s").
        timed_out_steps: timed gait steps (the executor's ``gait_step_time``) that ended on
            their time without their stance estimated reached.
    """

    success: bool
    reason: str = ""
    failed_action: int | None = None
    actions_done: int = 0
    actions_total: int = 0
    actions_skipped: int = 0
    docks: int = 0
    undocks: int = 0
    flows: int = 0
    simulator: dict[str, int] = field(default_factory=dict)
    retries: int = 0
    ticks: int = 0
    sim_time: float = 0.0
    wall_time: float = 0.0
    final: Configuration | None = None
    goal: GoalVerdict | None = None
    faults: list[FaultEvent] = field(default_factory=list)
    interrupted: str = ""
    targets: list[GoalVerdict] = field(default_factory=list)
    locomotion: list[BehaviorVerdict] = field(default_factory=list)
    settled: list[str] = field(default_factory=list)
    redocked: list[str] = field(default_factory=list)
    timed_out_steps: int = 0

    def summary(self) -> dict[str, object]:
        """JSON-ready numbers (for ``summary.json``)."""
        return {"success": self.success, "reason": self.reason,
                "failed_action": self.failed_action, "actions_done": self.actions_done,
                "actions_total": self.actions_total,
                "actions_skipped": self.actions_skipped, "docks": self.docks,
                "undocks": self.undocks, "flows": self.flows,
                "simulator_events": dict(self.simulator) or None, "retries": self.retries,
                "ticks": self.ticks,
                "sim_time_s": round(self.sim_time, 3), "wall_time_s": round(self.wall_time, 3),
                "goal": None if self.goal is None else self.goal.summary(),
                "faults": [{"kind": f.kind, "text": f.text, "time_s": round(f.time, 3),
                            "recovered": f.recovered} for f in self.faults],
                "interrupted": self.interrupted or None,
                "targets": [t.summary() for t in self.targets],
                "locomotion": [m.summary() for m in self.locomotion],
                "settled": list(self.settled), "redocked": list(self.redocked),
                "timed_out_steps": self.timed_out_steps}


class EventSink(Protocol):
    """Where a run's events go: the plugin host's event hooks in a run
    (:data:`msrr.core.plugins.emit`), a list in a test. The executor and the run's guard
    send to one; none of them asks the host."""

    def run_start(self, run: Run) -> None: ...

    def tick(self, run: Run, tick: Tick) -> None: ...

    def action(self, run: Run, action: Action, status: ActionStatus) -> None: ...

    def topology_change(self, run: Run, change: TopologyEvent) -> None: ...

    def fault(self, run: Run, fault: FaultEvent) -> None: ...

    def run_end(self, run: Run, result: RunResult) -> None: ...


class NoEvents:
    """An :class:`EventSink` that drops every event."""

    def run_start(self, run: Run) -> None:
        """Dropped."""

    def tick(self, run: Run, tick: Tick) -> None:
        """Dropped."""

    def action(self, run: Run, action: Action, status: ActionStatus) -> None:
        """Dropped."""

    def topology_change(self, run: Run, change: TopologyEvent) -> None:
        """Dropped."""

    def fault(self, run: Run, fault: FaultEvent) -> None:
        """Dropped."""

    def run_end(self, run: Run, result: RunResult) -> None:
        """Dropped."""
