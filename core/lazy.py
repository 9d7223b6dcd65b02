"""Lazy package exports (PEP 562): a package names what it exports and where from, and a
name's module is imported when the name is first used.

The command line loads every plugin on ``--help``, and a built-in plugin module lives in
its package (``msrr.core.generic.plugin``): importing it imports the package, which must
therefore not import numpy, networkx or a simulator (``tests/core/test_cli_startup.py``).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["lazy_exports"]


def lazy_exports(package: str, exports: Mapping[str, str]
                 ) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """``(__getattr__, __dir__)`` for package ``package`` whose export ``name`` lives in
    its submodule ``exports[name]`` (``"planner"``; a module further up with its dots,
    ``"..mapping"``)."""

    def __getattr__(name: str) -> Any:
        module = exports.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        relative = module if module.startswith(".") else f".{module}"
        value = getattr(importlib.import_module(relative, package), name)
        vars(importlib.import_module(package))[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted({*vars(importlib.import_module(package)), *exports})

    return __getattr__, __dir__
