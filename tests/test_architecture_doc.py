"""docs/architecture.md names modules and the functions that own each study file and paper equation:
every one of them must exist, so the page cannot drift from the code unnoticed."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "architecture.md"
#: A module path on the page, and a name in backticks that a module should define (`name`, `Class.member`).
MODULE = re.compile(r"`((?:designs|navigan|trials|robot_logs|analysis)/[\w/]*\.py)`")
NAME = re.compile(r"`([A-Za-z_]\w*(?:\.[A-Za-z_]\w*)?)`")
FILE_SUFFIXES = (".py", ".csv", ".json", ".toml", ".mcap", ".png", ".md", ".html")


def defined_names(path: Path) -> set[str]:
    """Top-level functions, classes and assignments of a module, and `Class.member` for class bodies."""
    names: set[str] = set()
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
            if isinstance(node, ast.ClassDef):
                names.update(f"{node.name}.{item.name}" for item in node.body
                             if isinstance(item, (ast.FunctionDef, ast.AsyncFunctionDef)))
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names.update(t.id for t in targets if isinstance(t, ast.Name))
    return names


def mentions() -> list[tuple[str, list[str]]]:
    """Every module path in a table cell of the page, with the names that follow it in that cell."""
    found = []
    for line in PAGE.read_text().splitlines():
        if not line.startswith("|"):
            continue
        for cell in line.split("|"):
            modules = list(MODULE.finditer(cell))
            for match, after in zip(modules, modules[1:] + [None]):
                text = cell[match.end(): after.start() if after else len(cell)]
                names = [n for n in NAME.findall(text) if not n.endswith(FILE_SUFFIXES)]
                found.append((match.group(1), names))
    return found


def test_the_page_names_modules():
    paths = {path for path, _ in mentions()}
    assert len(paths) >= 25
    assert {"trials/outcomes.py", "robot_logs/run_log.py", "trials/study.py", "navigan/losses.py"} <= paths


@pytest.mark.parametrize(("path", "names"), mentions(), ids=lambda value: str(value))
def test_every_named_module_and_definition_exists(path, names):
    module = ROOT / path
    assert module.is_file(), f"docs/architecture.md names {path}, which does not exist"
    missing = set(names) - defined_names(module)
    assert not missing, f"docs/architecture.md says {path} defines {sorted(missing)}"


def test_a_wrong_name_is_caught(tmp_path):
    """The check itself: a module that lacks a named definition is reported."""
    module = tmp_path / "m.py"
    module.write_text("class A:\n    def b(self):\n        pass\n\nX = 1\n\ndef f():\n    pass\n")
    assert defined_names(module) == {"A", "A.b", "X", "f"}
    assert "g" not in defined_names(module)
