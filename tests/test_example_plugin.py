"""The third-party example plugin in examples/ installs and works like a built-in robot."""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, distribution

from click.testing import CliRunner

from msrr.core import plugins
from msrr.core.app.cli import get_cli
from msrr.core.plugins import load_configuration

from msrr_test_support import ROOT

EXAMPLE = ROOT / "examples/msrr-example-hinge"


def test_example_is_installed_as_its_own_distribution() -> None:
    try:
        dist = distribution("msrr-example-hinge")
    except PackageNotFoundError as exc:
        raise AssertionError("install it with the README's install command") from exc
    assert any(ep.group == "msrr.plugins" and ep.name == "hinge" for ep in dist.entry_points)


def test_platform_robots_lists_the_example_robot() -> None:
    result = CliRunner().invoke(get_cli(), ["robots"])
    assert result.exit_code == 0
    assert "hinge" in result.output and "Hinge chain (example)" in result.output


def test_example_configurations_validate() -> None:
    files = sorted(EXAMPLE.glob("msrr_example_hinge/configs/*.json"))
    assert len(files) == 4
    for path in files:
        assert load_configuration(path).robot == "hinge"
    result = CliRunner().invoke(get_cli(), ["validate", *map(str, files)])
    assert result.exit_code == 0, result.output


def test_example_scenario_points_at_shipped_files() -> None:
    scenario = plugins.scenarios("hinge")["reverse"]
    assert load_configuration(scenario.start).signature() == load_configuration(scenario.goal).signature()


CUBE = ROOT / "examples/msrr-example-cube"


def test_the_cube_example_is_installed_and_described_only() -> None:
    dist = distribution("msrr-example-cube")
    assert any(ep.group == "msrr.plugins" and ep.name == "cube" for ep in dist.entry_points)
    sources = sorted(p.name for p in CUBE.glob("msrr_example_cube/*.py"))
    assert sources == ["__init__.py", "plugin.py"]  # a description, no simulation code
    capabilities = plugins.capabilities("cube")
    assert "mujoco" in capabilities.drivers and capabilities.drivers["mujoco"].generic
