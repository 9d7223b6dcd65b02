"""Hook implementations of the FreeSN robot plugin.

Loaded by the command line on every ``--help``: the module imports only the hook
marker; each hook imports what it answers with (the robot, its rules, joints, drivers).
Its planner is the core's ``library`` planner over the libraries it registers.
"""

from __future__ import annotations

from pathlib import Path

from msrr.core import hookimpl

from .timeline import msrr_timeline_views  # noqa: F401 - the timeline's connector plots

CONFIGS = Path(__file__).resolve().parent / "configs" / "library"
"""Every configuration of the shipped libraries as ``<library id>.json``."""

LIBRARIES = Path(__file__).resolve().parent / "libraries"
"""The shipped behavior libraries, one file per sub-library (``S6N3.json``) with its
feasibility check file (``S6N3.check.json``)."""

STARTS = Path(__file__).resolve().parent / "configs" / "scenarios"
"""Start configurations of the figure scenarios: library configurations as newly built
systems report them (relabelled, yawed, tilted; ``generate.py`` there writes them)."""

FIGURES = (
    ("fig20", "fig20-start", ("S6N3-4.1", "S6N3-1.1"),
     "Fig. 20: S6N3 triangle with three legs -> the chain on four legs (d) by retrieval -> "
     "back", True),
    ("fig21", "fig21-start", ("S12N6-7.1", "S12N6-2.1"),
     "Fig. 21: S12N6 hexagonal star -> tree -> hexagonal star, by moves and parallel "
     "connections and disconnections", False),
    ("fig22", "fig22-start",
     (("wheeled-move", 0.05, 60.0), ("node-wheels", 0.03, 60.0), "S12N6-1.1"),
     "Fig. 22: S12N6 octahedron -> wheeled move on its freed chords -> moving with node "
     "modules as wheels -> back to the octahedron, by parallel disconnections and "
     "connections", False),
)
"""``(name, start file, stages in order, description, default)``: the scenarios of the
paper's self-reconfiguration figures; a stage is a goal (a library id) or a behavior
``(name, speed [m/s], duration [s])``."""

LOCOMOTION = (
    ("fig18-node-wheels", "fig18-node-wheels-start", "node-wheels", 0.03, 60.0,
     "Fig. 18(a)-(c): S4N5 stands up, then its four leaf nodes drive as wheels"),
    ("fig18-strut-wheels", "fig18-strut-wheels-start", "strut-wheels", 0.03, 60.0,
     "Fig. 18(d)-(f): S4N1 drives on the wheels of its four leaf struts"),
    ("fig18-struts-as-wheels", "fig18-struts-as-wheels-start", "struts-as-wheels", 0.03, 60.0,
     "Fig. 18(g)-(i): S4N1 rolls its four leaf struts about their axes"),
)
"""``(name, start file, behavior, speed [m/s], duration [s], description)``: the
locomotion scenarios (section 7.3): the path to the behavior's start, then the behavior."""

GAITS = (
    ("fig19-squirm", "fig19-squirm-start", "squirm", 0.55, 30,
     "Fig. 19(a)-(e): S4N5 chain squirms, a fixed stem strut and a planted end leg "
     "alternating front and rear"),
    ("fig19-crawl", "fig19-crawl-start", "crawl", 0.5, 20,
     "Fig. 19(f)-(j): S4N5 stands up, then crawls on its four leaf struts as legs"),
    ("fig19-crawl-s12n6", "fig19-crawl-s12n6-start", "crawl", 0.5, 40,
     "Fig. 19(k)-(o): the S12N6 quadruped crawls on four legs with leaf-node feet, the "
     "diagonal pairs planted in turn"),
)
"""``(name, start file, sequence behavior, distance [m], at most loops, description)``: the
gait scenarios (section 7.3): the path to the behavior's start, then its configuration
sequence looped until the centre moved the distance."""

SCENARIOS = (
    ("s6n3-connect", "S6N3-2.3", "S6N3-3.1", "S6N3: a leg docks to a node (connection)", False),
    ("s6n3-disconnect", "S6N3-3.1", "S6N3-2.3", "S6N3: a docked leg undocks (disconnection)",
     False),
    ("s6n3-crouch", "S6N3-1.1", "S6N3-1.2", "S6N3: the triangle lowers onto its legs (moving)",
     False),
    ("s6n3-fig20", "S6N3-1.1", "S6N3-4.1", "S6N3: fig. 20(a) to 20(d), a leg transfer and an "
     "opening", False),
)
"""``(name, start id, goal id, description, default)``: ``platform run --scenario``."""


@hookimpl
def msrr_robot():
    from .robot import SPEC

    return SPEC


@hookimpl
def msrr_docking_rules(robot: str):
    from .robot import SPEC
    from .rules import FreeSNRules

    return FreeSNRules() if robot == SPEC.name else None


@hookimpl
def msrr_kinematic_nodes(robot: str, register):
    from .robot import SPEC

    if robot == SPEC.name:
        from .joints import JOINT_MODES

        for node_type in JOINT_MODES:
            register(node_type)


@hookimpl
def msrr_libraries(robot: str, register):
    from .robot import SPEC

    if robot == SPEC.name:  # the core's library planner plans with these
        for path in sorted(LIBRARIES.glob("*.json")):
            if not path.name.endswith(".check.json"):
                register(path)


@hookimpl
def msrr_scenarios(robot: str, register):
    from .robot import SPEC

    if robot == SPEC.name:
        from msrr.core.scenario import Scenario, Stage

        def stage(step: str | tuple[str, float, float]) -> Stage:
            if isinstance(step, str):
                return Stage(goal=CONFIGS / f"{step}.json")
            behavior, speed, duration = step
            return Stage(behavior=behavior, parameters=(("speed", speed),), duration=duration)

        for name, start, steps, what, default in FIGURES:
            first = steps[0] if isinstance(steps[0], str) else None
            register(Scenario(name=name, start=STARTS / f"{start}.json",
                              goal=CONFIGS / f"{first}.json" if first else None,
                              description=what, default=default,
                              stages=tuple(stage(s) for s in steps[1 if first else 0:])))
        for name, start, behavior, speed, duration, what in LOCOMOTION:
            register(Scenario(name=name, start=STARTS / f"{start}.json", description=what,
                              stages=(stage((behavior, speed, duration)),)))
        for name, start, behavior, distance, loops, what in GAITS:
            register(Scenario(name=name, start=STARTS / f"{start}.json", description=what,
                              stages=(Stage(behavior=behavior, distance=distance,
                                            loops=loops),)))
        for name, start, goal, what, default in SCENARIOS:
            register(Scenario(name=name, start=CONFIGS / f"{start}.json",
                              goal=CONFIGS / f"{goal}.json", description=what,
                              default=default))


@hookimpl
def msrr_drivers(robot: str, register):
    from .robot import SPEC

    if robot == SPEC.name:
        from .sim import FreeSNMujocoDriver

        register(FreeSNMujocoDriver)


@hookimpl
def msrr_recognizers(robot: str, register):
    from .robot import SPEC

    if robot == SPEC.name:
        from .sim import FreeSNRecognizer

        register(FreeSNRecognizer())


@hookimpl
def msrr_controllers(robot: str, register):
    from .robot import SPEC

    if robot == SPEC.name:
        from .joints import JOINT_MODES
        from .sim import FreeSNController

        for node_type in JOINT_MODES:  # one per joint mode, named as its ``controller``
            register(FreeSNController(node_type.name))
