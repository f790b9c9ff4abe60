"""The release is one number, the same everywhere: pyproject.toml, the installed distribution `trials --version`
prints, and the newest section of CHANGELOG.md, which lists its changes in short entries under Added, Changed, Fixed."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

from trials.cli import main

ROOT = Path(__file__).resolve().parents[1]
#: Semantic versioning's MAJOR.MINOR.PATCH, no leading zeros.
SEMVER = re.compile(r"(0|[1-9]\d*)\.(0|[1-9]\d*)\.(0|[1-9]\d*)")
SECTION = re.compile(r"^## (\S+) \((\d{4}-\d\d-\d\d)\)$", re.MULTILINE)


def test_the_version_is_semantic_and_trials_prints_it(capsys):
    version = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    assert SEMVER.fullmatch(version) and version == "0.2.0"
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"trials (navtrials) {version}"


def test_the_changelog_opens_with_this_release_in_short_grouped_entries():
    text = (ROOT / "CHANGELOG.md").read_text()
    version = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    sections = SECTION.findall(text)
    assert [v for v, _ in sections][:2] == [version, "0.1.0"] and all(SEMVER.fullmatch(v) for v, _ in sections)
    assert [d for _, d in sections] == sorted((d for _, d in sections), reverse=True)  # newest first
    newest = text[text.index(f"## {version} "):text.index("## 0.1.0")]
    assert re.findall(r"^### (.+)$", newest, re.MULTILINE) == ["Added", "Changed", "Fixed"]
    entries = re.split(r"^- ", newest, flags=re.MULTILINE)[1:]
    assert len(entries) > 20
    for entry in entries:  # one or two lines of the page each
        assert len(entry.strip().splitlines()) <= 3 and len(entry) <= 400, entry
