"""The lattice planner is a library of its own: trials/lattice imports nothing else of the toolkit."""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import trials.lattice
from trials.errors import StudyError
from trials.lattice.errors import LatticeError

LIBRARY = Path(trials.lattice.__file__).parent
PACKAGE = "trials.lattice"
#: The toolkit's other top-level packages, none of which the library needs.
TOOLKIT = ("trials", "designs", "navigan", "analysis", "robot_logs")


def imports(path: Path) -> Iterator[str]:
    """The absolute name of every module `path` imports (relative imports resolved within the package)."""
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = PACKAGE.rsplit(".", node.level - 1)[0] if node.level else ""
            yield ".".join(part for part in (base, node.module) if part)


def outside(name: str) -> bool:
    inside = name == PACKAGE or name.startswith(f"{PACKAGE}.")
    return not inside and name.split(".")[0] in TOOLKIT


def test_the_library_imports_nothing_of_the_toolkit_outside_it():
    modules = sorted(LIBRARY.glob("*.py"))
    assert len(modules) > 10
    found = [f"{path.name}: {name}" for path in modules for name in imports(path) if outside(name)]
    assert found == []


def test_its_errors_are_its_own():
    assert not issubclass(LatticeError, StudyError) and issubclass(LatticeError, ValueError)
