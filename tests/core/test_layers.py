"""The core's import graph: layers point down and nothing imports in a circle.

Read from the source with :mod:`ast` (nothing is imported), so a lazy import inside a
function counts the same as one at the top of a module. Imports under
``if TYPE_CHECKING:`` are annotations only and are left out.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import networkx as nx
import pytest

CORE = Path(__file__).resolve().parents[2] / "core"

PURE_LAYERS = ("msrr.core.kinematics", "msrr.core.matching", "msrr.core.library", "msrr.core.io")
"""Packages that receive robots, rules and joint modes as arguments."""


def _module_name(path: Path) -> str:
    parts = path.relative_to(CORE).with_suffix("").parts
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(("msrr", "core", *parts))


def _imports(path: Path, name: str) -> set[str]:
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    tree = ast.parse(path.read_text(), str(path))
    type_only = {id(n) for block in ast.walk(tree) if isinstance(block, ast.If)
                 and ast.unparse(block.test).endswith("TYPE_CHECKING")
                 for n in ast.walk(block)}
    for node in ast.walk(tree):
        if id(node) in type_only:
            continue
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[:len(base) - node.level + 1]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            found.add(module)
            found.update(f"{module}.{alias.name}" for alias in node.names)
    return found


def _graph() -> nx.DiGraph:
    modules = {_module_name(p): p for p in CORE.rglob("*.py")}
    graph = nx.DiGraph()
    graph.add_nodes_from(modules)
    for name, path in modules.items():
        for target in _imports(path, name):
            if target in modules and target != name:
                graph.add_edge(name, target)
    return graph


GRAPH = _graph()


def test_the_core_imports_no_plugin():
    for name, path in ((_module_name(p), p) for p in CORE.rglob("*.py")):
        plugins = sorted(t for t in _imports(path, name) if t.startswith("msrr.plugins"))
        assert not plugins, f"{name} imports {plugins}"


@pytest.mark.parametrize("layer", PURE_LAYERS)
def test_pure_layers_do_not_import_the_plugin_host(layer):
    inside = [m for m in GRAPH if (m == layer or m.startswith(layer + "."))
              and not m.endswith(".plugin")]
    assert inside, f"no module {layer}"
    for module in inside:
        assert "msrr.core.plugins" not in GRAPH.successors(module), (
            f"{module} imports msrr.core.plugins; pass the Robot (or its pieces) as an argument")


def _asks_the_host(module: str) -> bool:
    """The application wing and the built-in capabilities' ``plugin.py`` modules."""
    return module.startswith("msrr.core.app.") or module == "msrr.core.app" or \
        module.endswith(".plugin")


def test_only_the_application_wing_and_built_in_plugins_import_the_host():
    askers = sorted(m for m in GRAPH.predecessors("msrr.core.plugins") if m != "msrr.core")
    assert askers, "nothing imports the plugin host"
    assert [m for m in askers if not _asks_the_host(m)] == []
    builtin = {m for m in askers if m.endswith(".plugin")}
    assert builtin == {"msrr.core.generic.plugin", "msrr.core.library.plugin",
                       "msrr.core.link.plugin", "msrr.core.timeline.plugin"}


def test_the_executor_receives_what_it_needs():
    assert not {"msrr.core.plugins", "msrr.core.app"} & set(nx.descendants(GRAPH,
                                                                            "msrr.core.executor"))


def test_the_host_names_no_robot_and_no_capability():
    source = (CORE / "plugins.py").read_text()
    robots = ["freesn", "mmrp", "freebot", "snailbot", "hinge"]
    capabilities = ["kinematic", "latches", "generic", "link", "timeline", "library"]
    assert [n for n in robots if re.search(rf"\b{n}\b", source, re.IGNORECASE)] == []
    assert [n for n in capabilities if re.search(rf"[\"']{n}[\"']", source)] == []
    assert "hook_name ==" not in source and ".function(" not in source


def test_the_core_import_graph_has_no_cycle():
    # a package importing its own submodules (__init__ re-exports) is not a cycle
    graph = GRAPH.copy()
    graph.remove_edges_from([(a, b) for a, b in GRAPH.edges if b.startswith(a + ".")])
    cycles = list(nx.simple_cycles(graph, length_bound=6))
    assert not cycles, f"import cycles: {cycles[:5]}"


def test_no_plugin_imports_another():
    plugins = CORE.parent / "plugins"
    for path in plugins.rglob("*.py"):
        own = path.relative_to(plugins).parts[0]
        tree = ast.parse(path.read_text(), str(path))
        for node in ast.walk(tree):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            for name in names:
                parts = name.split(".")
                if parts[:2] == ["msrr", "plugins"] and len(parts) > 2:
                    assert parts[2] == own, f"{path} imports {name}"


WITNESS = "msrr.core.witness"
CONTROL_PATH = ("msrr.core.executor", "msrr.core.closed_loop", "msrr.core.control",
                "msrr.core.capabilities", "msrr.core.estimation", "msrr.core.events",
                "msrr.core.driver", "msrr.core.generic.controller", "msrr.core.generic.drive",
                "msrr.core.generic.recognizer", "msrr.core.generic.planner",
                "msrr.core.freeform.recognition", "msrr.core.freeform.miso",
                "msrr.core.matching", "msrr.core.kinematics", "msrr.core.plan")
"""What decides a run's commands: none of it may reach the witness channel."""


@pytest.mark.parametrize("module", CONTROL_PATH)
def test_the_control_path_cannot_import_the_witness_channel(module):
    assert module in GRAPH, f"no module {module}"
    assert WITNESS not in nx.descendants(GRAPH, module) | {module}, (
        f"{module} reaches {WITNESS}: decisions read what the robot senses "
        "(Observation, msrr.core.estimation), never the simulator's state")


def test_only_the_judge_the_recording_and_the_drivers_import_the_witness_channel():
    allowed = ("msrr.core.judge", "msrr.core.faults", "msrr.core.app.", "msrr.core.timeline.",
               "msrr.core.link.emulator", "msrr.core.freeform.mujoco", "msrr.core.generic.driver",
               "msrr.core.generic.physics")
    importers = sorted(GRAPH.predecessors(WITNESS))
    assert "msrr.core.judge" in importers
    assert [m for m in importers if not m.startswith(allowed)] == []
