"""Where ``pvgraph.components`` and ``pvgraph.circuits`` live.

Installed, setuptools places the component library and the applications inside the package
(``pyproject.toml`` maps the folders ``components/`` and ``circuits/`` to ``pvgraph.components``
and ``pvgraph.circuits``). In a source checkout they stay beside ``pvgraph/``; this finder gives
them the same names there, so tests and examples run from the checkout import what a user
imports. The framework itself imports neither.
"""

from __future__ import annotations

import importlib.abc
import importlib.util
import sys
from pathlib import Path

SUBPACKAGES = ("components", "circuits")


class _SourceTreeFinder(importlib.abc.MetaPathFinder):
    """Find ``pvgraph.<name>`` in the checkout's top-level folder ``<name>/``."""

    def __init__(self, folders: dict[str, Path]):
        self.folders = folders

    def find_spec(self, fullname, path=None, target=None):
        folder = self.folders.get(fullname)
        if folder is None:
            return None
        return importlib.util.spec_from_file_location(
            fullname, folder / "__init__.py", submodule_search_locations=[str(folder)])


def install(package_dir: Path) -> None:
    """Register the finder when ``package_dir`` is a source checkout's ``pvgraph/``."""
    root = package_dir.parent
    folders = {f"pvgraph.{name}": root / name for name in SUBPACKAGES
               if not (package_dir / name).exists() and (root / name / "__init__.py").is_file()}
    if folders and not any(isinstance(f, _SourceTreeFinder) for f in sys.meta_path):
        # first: an installed pvgraph (an editable install of another checkout) must not
        # lend this checkout its components and circuits
        sys.meta_path.insert(0, _SourceTreeFinder(folders))
