"""Package discovery for the ``msrr`` namespace.

``core/`` and ``plugins/`` are mapped onto ``msrr.core`` and ``msrr.plugins`` by
``package-dir`` in pyproject.toml; setuptools' ``find`` cannot add that prefix, so
the sub-packages are listed here once, from the folders themselves.
"""

from setuptools import find_packages, setup


def _mapped(prefix: str, folder: str) -> list[str]:
    return [prefix] + [f"{prefix}.{name}" for name in find_packages(folder)]


setup(packages=_mapped("msrr.core", "core") + _mapped("msrr.plugins", "plugins"))
