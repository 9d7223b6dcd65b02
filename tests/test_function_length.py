"""No function of the platform is longer than 80 lines (issue 23, item 8).

A long function is split into named steps (the algorithm's own steps where it
implements one). Read from the source with :mod:`ast` (nothing is imported); a
function's length counts from its ``def`` line to its last line, decorators left out
and its docstring included. Nested functions and methods are measured on their own
as well as inside the function that holds them.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = ("core", "plugins", "benchmarks", "examples")
LIMIT = 80
"""Most lines a function may have."""


def _sources() -> list[Path]:
    return sorted(path for folder in FOLDERS for path in (ROOT / folder).rglob("*.py")
                  if "__pycache__" not in path.parts)


def _long_functions(path: Path) -> list[str]:
    """``path::qualified.name lines`` of every function in ``path`` over :data:`LIMIT`."""
    found = []

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
                name = f"{prefix}{child.name}"
                if not isinstance(child, ast.ClassDef):
                    lines = child.end_lineno - child.lineno + 1
                    if lines > LIMIT:
                        found.append(f"{path.relative_to(ROOT)}::{name} {lines}")
                visit(child, f"{name}.")
            else:
                visit(child, prefix)

    visit(ast.parse(path.read_text(encoding="utf-8"), filename=str(path)), "")
    return found


def test_the_tree_has_sources() -> None:
    assert len(_sources()) > 50


def test_no_function_over_80_lines() -> None:
    long = [entry for path in _sources() for entry in _long_functions(path)]
    assert not long, (f"{len(long)} functions over {LIMIT} lines (split them into named "
                      "steps):\n" + "\n".join(long))
