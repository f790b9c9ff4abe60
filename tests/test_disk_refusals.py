"""A read-only study folder and a full disk: every command that writes ends in one line naming the file, exit 2,
and leaves the study exactly as it was (no traceback, nothing half-written, nothing moved aside)."""

from __future__ import annotations

import errno
import hashlib
import re
import shutil
from pathlib import Path

import pytest

from tests.support.refusing_disk import refuse_changes
from tests.support.synthetic_study import judged_ab_study
from trials.cli import main

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def template(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The blinded A/B plan with its first 4 runs finished and judged."""
    return judged_ab_study(tmp_path_factory.mktemp("disk") / "study", limit=4, seed=3)


def _snapshot(root: Path) -> dict[str, str]:
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "folder" for p in sorted(root.rglob("*"))}


FIRST, FIFTH = "NGAC3", "9C669"  # the plan's first run (finished) and fifth (pending)
COMMANDS = {
    "log show": ["log", "show", FIRST],
    "run --rerun": ["run", "--rerun", FIRST, "--no-responses"],
    "run": ["run", "--only", FIFTH, "--no-responses"],
    "design --augment": ["design", "--augment", "2", "--seed", "4"],
    "design --force": ["design", "--force", "--ab", "--seed", "2", "--power", "0"],
    "report": ["report"],
    "respond": ["respond", FIRST, "P9", "yes"],
    "score": ["score", FIRST, "3", "--by", "second"],
}


@pytest.mark.parametrize("code", [errno.EROFS, errno.ENOSPC], ids=["read-only", "full"])
@pytest.mark.parametrize("command", list(COMMANDS))
def test_a_refused_write_is_one_line_naming_the_file_and_changes_nothing(command: str, code: int, template: Path, tmp_path: Path,
                                                                         monkeypatch: pytest.MonkeyPatch,
                                                                         capsys: pytest.CaptureFixture[str]) -> None:
    study = Path(shutil.copytree(template, tmp_path / "study", symlinks=True))
    before = _snapshot(study)
    refused = refuse_changes(monkeypatch, study, code)
    capsys.readouterr()
    assert main([*COMMANDS[command], "--study", str(study)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1, err
    assert refused, "nothing was refused: the command wrote nothing"
    named = Path(refused[-1]).relative_to(study)  # the refusal the command could not go on from, by its target's name
    named = named.with_name(re.sub(r"^\.(.+)\.[0-9a-f]{8}\.tmp$", r"\1", named.name))
    assert str(named) in err, (named, err)
    assert ("no space left on the device to write" if code == errno.ENOSPC else "Read-only file system") in err
    monkeypatch.undo()
    assert _snapshot(study) == before

