"""Typed robot defaults: ``RobotDefaults`` and ``ShapeTolerance`` refuse a wrong value
when built, with one line naming the field; ``RobotSpec`` takes nothing else; the
built-in robots declare theirs typed."""

from __future__ import annotations

import math
from dataclasses import FrozenInstanceError

import pytest

from msrr.core import (
    MsrrError,
    PluginError,
    RobotDefaults,
    RobotSpec,
    ShapeTolerance,
    plugins,
)

BUILT_IN = ("freebot", "freesn", "mmrp", "snailbot")


def _refused(field: str, build: object) -> str:
    """The one-line message of ``build()``, which must be a PluginError naming ``field``."""
    with pytest.raises(PluginError) as caught:
        build()  # type: ignore[operator]
    message = str(caught.value)
    assert field in message and "\n" not in message
    return message


@pytest.mark.parametrize("value", [3, "", b"spherical", ("spherical",)])
def test_joint_mode_must_be_a_name(value: object) -> None:
    _refused("RobotDefaults.joint_mode", lambda: RobotDefaults(joint_mode=value))


@pytest.mark.parametrize("field", ["planar", "stay_connected", "median_yaw"])
@pytest.mark.parametrize("value", [1, "yes", None, 0.0])
def test_flags_must_be_booleans(field: str, value: object) -> None:
    message = _refused(f"RobotDefaults.{field}", lambda: RobotDefaults(**{field: value}))
    assert repr(value) in message


@pytest.mark.parametrize("value", [{"position": 0.02, "heading": 0.06}, (0.02, 0.06), 0.1])
def test_shape_tolerance_must_be_typed(value: object) -> None:
    _refused("RobotDefaults.shape_tolerance", lambda: RobotDefaults(shape_tolerance=value))


@pytest.mark.parametrize("bound", ["position", "heading"])
@pytest.mark.parametrize("value", [-1, 0, 0.0, math.nan, math.inf, True, "0.1", None])
def test_tolerance_bounds_are_finite_positive_numbers(bound: str, value: object) -> None:
    good = {"position": 0.02, "heading": 0.06}
    message = _refused(f"ShapeTolerance.{bound}",
                       lambda: ShapeTolerance(**{**good, bound: value}))
    assert ("[m]" if bound == "position" else "[rad]") in message


def test_defaults_are_frozen_keyword_only_and_closed() -> None:
    tolerance = ShapeTolerance(position=1, heading=2)
    assert (tolerance.position, tolerance.heading) == (1.0, 2.0)
    assert all(type(v) is float for v in (tolerance.position, tolerance.heading))
    defaults = RobotDefaults()
    assert defaults == RobotDefaults(joint_mode=None, shape_tolerance=None, planar=False,
                                     stay_connected=False)
    with pytest.raises(FrozenInstanceError):
        defaults.planar = True  # type: ignore[misc]
    with pytest.raises(FrozenInstanceError):
        tolerance.position = 3.0  # type: ignore[misc]
    with pytest.raises(TypeError):
        ShapeTolerance(0.02, 0.06)  # type: ignore[misc]  # which is [m], which [rad]?
    for unread in ("control_rate", "simulator"):
        with pytest.raises(TypeError, match=unread):
            RobotDefaults(**{unread: 1})


def test_a_spec_takes_only_typed_defaults() -> None:
    assert RobotSpec("r", "R", ()).defaults == RobotDefaults()
    with pytest.raises(PluginError, match=r"robot 'r': defaults must be a RobotDefaults"):
        RobotSpec("r", "R", (), defaults={"planar": True})  # type: ignore[arg-type]
    assert issubclass(PluginError, MsrrError)


def test_the_built_in_robots_declare_typed_defaults() -> None:
    robots = plugins.robots()
    for name in BUILT_IN:
        defaults = robots[name].defaults
        assert type(defaults) is RobotDefaults, name
        if defaults.joint_mode is not None:  # names a joint mode the robot registers
            robot = plugins.resolve(name)
            assert robot.default_joint_mode() is robot.joint_modes[defaults.joint_mode]
    assert robots["mmrp"].defaults == RobotDefaults(
        planar=True, shape_tolerance=ShapeTolerance(position=0.02, heading=0.06))
    assert [robots[n].defaults.joint_mode for n in ("freebot", "freesn", "snailbot")] == [
        "rolling_contact", "opposite_steering", "spherical"]
