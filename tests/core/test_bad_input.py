"""Bad inputs end in one clean line (issue 11, deliverables 1, 5 and 6): strict JSON,
literal printing, numeric options, bounded output, plugins that break the contract,
and the numeric refusals of IK, FK and the isomorphism search."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner
from tiny_robot import NAME, SPEC, chain, hookimpl, installed, swap_plan

from msrr.core import plugins, save_configuration
from msrr.core.app.cli import get_cli
from msrr.core.configuration import Configuration
from msrr.core.errors import (
    MAX_MESSAGE,
    ConfigurationError,
    MsrrError,
    PluginError,
    one_line,
    short_source,
)
from msrr.core.files import MAX_DEPTH, read_json
from msrr.core.io import load_configuration
from msrr.core.matching import MatchingError
from msrr.core.matching.iso_search import iso_search
from msrr.core.plan import load_plan, save_plan
from msrr.core.robot import RobotSpec


def run(*args: str):
    return CliRunner().invoke(get_cli(), list(args))


@pytest.fixture
def tiny(tmp_path: Path):
    with installed(tmp_path) as plugin:
        yield plugin


def _good(tmp_path: Path, name: str = "good.json") -> Path:
    path = tmp_path / name
    save_configuration(chain(("a", "b"), ("b", "c"), name="abc"), path)
    return path


def _error(call) -> str:
    with pytest.raises(MsrrError) as info:
        call()
    text = str(info.value)
    assert "\n" not in text and len(text) <= MAX_MESSAGE
    return text


# -- strict JSON ----------------------------------------------------------------------------


@pytest.mark.parametrize(("text", "expected"), [
    ('{"a": 1, "a": 2}', "(document): repeated key 'a'"),
    ('{"m": [{"id": "x", "id": "y"}]}', "m[0]: repeated key 'id'"),
    ('{"p": [0, NaN]}', "p[1]: NaN is not a finite number"),
    ('{"p": -Infinity}', "p: -Infinity is not a finite number"),
    ('{"p": 1e400}', "p: number 1e400 is too large"),
    ('{"n": 1' + "0" * 30 + "}", "n: integer of 31 digits is too large"),
    ('{"name": "a\\ud800"}', "name: a lone surrogate escape is not text"),
    ('{"a": ' + "[" * (MAX_DEPTH + 5) + "]" * (MAX_DEPTH + 5) + "}",
     f"nested deeper than {MAX_DEPTH} levels"),
    ('{"a": ' + "[" * 5000 + "]" * 5000 + "}", f"nested deeper than {MAX_DEPTH} levels"),
    ("[" * 5000 + "]" * 5000, f"nested deeper than {MAX_DEPTH} levels"),
    ("[" * (MAX_DEPTH + 5) + "]" * (MAX_DEPTH + 5), "holds a list, not a JSON object"),
    ('{"a": [1, 2', "invalid JSON at line 1 column 12"),
    ("", "invalid JSON at line 1 column 1"),
])
def test_read_json_refuses_what_json_lets_through(tmp_path: Path, text: str, expected: str
                                                  ) -> None:
    path = tmp_path / "f.json"
    path.write_text(text)
    message = _error(lambda: read_json(path))
    assert message.startswith(f"{path}: ") and expected in message


def test_read_json_accepts_ordinary_documents_and_surrogate_pairs(tmp_path: Path) -> None:
    path = tmp_path / "f.json"
    path.write_text('{"a": [1, 2.5, -9223372036854775807], "e": "\\ud83d\\ude00 \\u00e9"}')
    assert read_json(path) == {"a": [1, 2.5, -9223372036854775807], "e": "\U0001F600 é"}


def test_non_utf8_and_directories_are_one_line(tmp_path: Path) -> None:
    path = tmp_path / "f.json"
    path.write_bytes(b'{"a": "\xff"}')
    assert _error(lambda: read_json(path)) == f"{path}: not UTF-8 text (byte 7)"
    assert _error(lambda: read_json(tmp_path)) == f"{tmp_path}: is a directory, expected a " \
                                                  "JSON file"


@pytest.mark.parametrize(("field", "value", "expected"), [
    ("schema_version", True, "schema_version: Value error, must be a number, not a boolean"),
    ("position", [0.0, True, 0.0], "modules[0].position[1]: Input should be a valid number"),
    ("position", [0.0, "1", 0.0], "modules[0].position[1]: Input should be a valid number"),
    ("position", [0.0, 1e300 * 1e10, 0.0], "modules[0].position[1]: number 1e400 is too large"),
    ("position", [0.0, 1e300, 0.0], "modules[0].position[1]: Input should be less than or "
                                    "equal to 1000000"),
])
def test_configurations_refuse_booleans_and_non_finite_numbers(tmp_path: Path, field: str,
                                                               value, expected: str) -> None:
    path = _good(tmp_path)
    data = json.loads(path.read_text())
    if field == "position":
        data["modules"][0]["position"] = value
        text = json.dumps(data).replace("Infinity", "1e400")
    else:
        data[field] = value
        text = json.dumps(data)
    path.write_text(text)
    assert expected in _error(lambda: load_configuration(path))


def test_errors_are_one_line_of_at_most_300_characters() -> None:
    error = ConfigurationError("x\n" * 500, source="/a/" + "d" * 400 + "/f.json",
                               field="modules[3]." + "k" * 200)
    text = str(error)
    assert "\n" not in text and len(text) <= MAX_MESSAGE and "f.json" in text
    assert one_line("a\ud800b") == "a\\ud800b"


def test_a_long_path_is_shortened_in_its_folders_never_in_the_file_name() -> None:
    name = "in [red] 00259 fig18-struts-as-wheels-start.json"
    for folders in ("/tmp", "/tmp/" + "d" * 300):
        text = str(ConfigurationError("bad", source=f"{folders}/{name}", field="modules[2].id"))
        assert name in text and len(text) <= MAX_MESSAGE and text.startswith("/tmp")
    assert short_source("/" + "n" * 300).endswith("n") and len(short_source("/" + "n" * 300)) <= 120


# -- literal output -------------------------------------------------------------------------


def test_names_and_paths_with_markup_print_literally(tiny, tmp_path: Path) -> None:
    folder = tmp_path / "q[ [red]x"
    folder.mkdir()
    config = chain(("a", "b"), modules="ab", name="[/red]")
    config.description = "[bold]vector [nan, 0.0, 1.0]"
    save_configuration(config, folder / "[red]f.json")
    result = run("show", str(folder / "[red]f.json"))
    assert result.exit_code == 0, result.output
    assert f"{folder / '[red]f.json'} — [/red] (tiny): 2 modules, 1 connection\n" \
        "[bold]vector [nan, 0.0, 1.0]" in result.output
    result = run("validate", str(folder / "[red]f.json"))
    assert result.output.startswith(f"valid {folder / '[red]f.json'}: tiny")


def test_validate_names_every_bad_file(tiny, tmp_path: Path) -> None:
    good = _good(tmp_path)
    other = tmp_path / "robot[x].json"
    other.write_text(good.read_text().replace('"tiny"', '"warp[/red]"'))
    result = run("validate", str(good), str(other))
    assert result.exit_code == 1
    assert f"invalid {other}: robot: unknown robot 'warp[/red]'" in result.stderr


def test_show_output_is_bounded_for_huge_files(tiny, tmp_path: Path) -> None:
    config = Configuration(NAME, name="many")
    for i in range(3000):
        config.add_module(f"m{i}", "cube")
    for i in range(1, 3000):
        config.connect(f"m{i - 1}", f"m{i}", ports=("T", "B"))
    path = tmp_path / "many.json"
    save_configuration(config, path)
    result = run("show", str(path))
    assert result.exit_code == 0, result.output[-300:]
    assert "Modules (3000)" in result.output and "… 2800 more rows not shown" in result.output
    assert "Connections (2999)" in result.output and "… 2799 more rows not shown" \
        in result.output
    assert len(result.output) < 60_000
    assert max(len(line) for line in result.output.splitlines()) <= 400


@pytest.mark.parametrize("args", [
    ["library", "build", "s.json", "-o", "x.json", "--merge-threshold", "nan"],
    ["library", "build", "s.json", "-o", "x.json", "--merge-threshold", "-1"],
    ["library", "check", "l.json", "--seed", "-1"],
    ["library", "check", "l.json", "--timeout", "inf"],
    ["plan", "--robot", NAME, "a.json", "b.json", "--seed", "-1"],
    ["match", "a.json", "b.json", "--confidence", "nan"],
    ["match", "a.json", "b.json", "--time-budget", "inf"],
    ["match", "a.json", "b.json", "--top", "0"],
])
def test_numeric_options_refuse_non_finite_and_out_of_range_values(args: list[str]) -> None:
    result = run(*args)
    assert result.exit_code == 2 and "Traceback" not in result.output
    assert "Invalid value for" in result.output


def test_outputs_that_are_folders_are_refused_before_any_work(tiny, tmp_path: Path) -> None:
    path = _good(tmp_path)
    result = run("plan", "--robot", NAME, str(path), str(path), "--json", str(tmp_path))
    assert result.exit_code == 1
    assert result.stderr == f"Error: {tmp_path}: --json: is a folder, expected a file\n"


# -- plans ----------------------------------------------------------------------------------


def test_plan_files_are_validated_on_load(tiny, tmp_path: Path) -> None:
    path = tmp_path / "plan.json"
    save_plan(swap_plan(), path)
    assert plugins.load_plan(path).docks == 1
    good = json.loads(path.read_text())

    def broken(change) -> Path:
        data = json.loads(json.dumps(good))
        change(data)
        path.write_text(json.dumps(data).replace('"__nan__"', "NaN"))
        return path

    def goal(d):
        d["actions"][1]["goals"] = {"c": ["__nan__", 0.0, 0.0]}

    def change(d):
        d["actions"][0]["changes"][0]["source"] = "z"

    def kind(d):
        d["actions"][0]["target"]["modules"] = [{"id": "a", "kind": "warpdrive"}]
        d["actions"][1]["target"] = {"modules": [{"id": "a", "kind": "cube"}]}  # and back

    def cost(d):
        d["actions"][0]["cost"] = -1

    assert "actions[1].goals.c[0]: NaN is not a finite number" in _error(
        lambda: load_plan(broken(goal)))
    assert "actions[0].changes[0]: module 'z' is not in the action's target" in _error(
        lambda: load_plan(broken(change)))
    assert "actions[0].target: module a: unknown module kind 'warpdrive'" in _error(
        lambda: plugins.load_plan(broken(kind)))
    assert "actions[0].cost: Input should be greater than or equal to 0" in _error(
        lambda: load_plan(broken(cost)))


# -- plugins --------------------------------------------------------------------------------


class Raising:
    @hookimpl
    def msrr_robot(self):
        raise RuntimeError("boom")


class Stringly:
    @hookimpl
    def msrr_robot(self):
        return "tiny"


class Claimer:
    @hookimpl
    def msrr_robot(self):
        return RobotSpec(NAME, "Another tiny", SPEC.module_kinds)


@pytest.mark.parametrize(("plugin", "reason"), [
    (Raising(), "msrr_robot: RuntimeError: boom"),
    (Stringly(), "msrr_robot: returned str, expected one RobotSpec or None"),
])
def test_a_plugin_that_breaks_msrr_robot_is_named(tiny, tmp_path: Path, plugin,
                                                  reason: str) -> None:
    path = _good(tmp_path)
    with plugins.temporary(plugin, "broken"):
        assert NAME in plugins.robots()  # the robots of the others keep working
        assert plugins.load_configuration(path).robot == NAME
        result = run("plugins")
        assert result.exit_code == 0
        assert f"plugin 'broken' (registered in code, test_bad_input) failed in {reason}" \
            in " ".join(result.output.split())
        assert run("robots").exit_code == 0 and run("validate", str(path)).exit_code == 0
    assert plugins.problems() == []


class BrokenRules:
    @hookimpl
    def msrr_docking_rules(self, robot):
        raise RuntimeError("rules table missing")


def test_a_plugin_whose_docking_rules_raise_makes_every_command_on_its_robot_refuse(
        tiny, tmp_path: Path) -> None:
    """Never "valid" under permissive rules, never "unknown robot": one line naming the
    plugin, where it came from, the hook and the exception; ``platform plugins`` says so."""
    path = _good(tmp_path)
    line = ("plugin 'rules' (registered in code, test_bad_input) failed in msrr_docking_rules "
            "for robot 'tiny': RuntimeError: rules table missing")
    with plugins.temporary(BrokenRules(), "rules"):
        result = run("validate", str(path))
        assert result.exit_code != 0 and line in result.output
        assert "Traceback" not in result.output and "valid" not in result.output.replace(
            "invalid", "")
        for args in (("run", "--robot", NAME, "--from", str(path), "--to", str(path),
                      "--out", str(tmp_path / "run")),
                     ("plan", "--robot", NAME, str(path), str(path))):
            refused = run(*args)
            assert refused.exit_code != 0 and line in " ".join(refused.output.split()), args
        assert not (tmp_path / "run").exists()
        listed = run("plugins").output
        assert "failed: msrr_docking_rules" in listed and f"failed {line}" in listed
        from msrr.core.app.testing import ConformanceError, check_robot
        with pytest.raises(ConformanceError, match="cannot be resolved: plugin 'rules'"):
            check_robot(NAME)
    assert run("validate", str(path)).exit_code == 0


def test_two_plugins_describing_one_robot_refuse_only_that_robot(tiny, tmp_path: Path) -> None:
    path = _good(tmp_path)
    with plugins.temporary(Claimer(), "claimer"):
        assert NAME not in plugins.robots() and "freesn" in plugins.robots()
        message = _error(lambda: plugins.load_configuration(path))
        assert message == (f"{path}: robot: robot 'tiny' is described by plugins 'claimer', "
                           "'tiny-robot'; it is refused until one of them is removed")
        with pytest.raises(PluginError):
            plugins.resolve(NAME)
        assert "robot tiny refused: described by another plugin too" in run("plugins").output
        assert run("robots").exit_code == 0
    assert plugins.load_configuration(path).robot == NAME


# -- function: the isomorphism search ------------------------------------------------------


def test_iso_search_refuses_an_edge_module_without_z() -> None:
    system = Configuration(NAME, name="sys")
    for m in "ab":
        system.add_module(m, "cube")
    system.connect("a", "b", id="e", kind="strut")
    with pytest.raises(MatchingError, match="system sys: connection e \\(strut\\) has no z"):
        next(iso_search(system, system))


@pytest.mark.parametrize("option, says", [("bogus=1", "unknown option 'bogus'"),
                                          ("connector_drive=tracked", "connector_drive"),
                                          ("noise", "is not KEY=VALUE")])
def test_library_check_refuses_a_driver_option_its_driver_does_not_take(
        tmp_path: Path, option: str, says: str) -> None:
    out = tmp_path / "check.json"
    library = Path(__file__).resolve().parents[2] / "plugins/freesn/libraries/S4N1.json"
    result = run("library", "check", str(library), "-o", str(out),
                 "--driver-option", option)
    assert result.exit_code != 0 and "Traceback" not in result.output
    assert says in result.output and "--driver-option" in result.output
    assert not out.exists()
