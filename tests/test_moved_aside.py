"""Nothing moved aside is ever overwritten: each move gets a superseded/ folder of its own, even two in the same
UTC second, and `trials design --force` takes a blinded study's sealed run records with its runs."""

from __future__ import annotations

from pathlib import Path

import pytest

import trials.study
from tests.support.run_studies import design_small_study
from tests.test_study_files import _outcome
from trials.cli import main
from trials.outcomes import Outcomes, read_outcomes
from trials.runner import supersede_runs
from trials.study import OUTCOMES, SEALED, SUPERSEDED, StudyFolder

SECOND = "2026-03-01T09:30:00+00:00"


@pytest.fixture
def one_second(monkeypatch):
    """Every move aside happens in the same UTC second."""
    monkeypatch.setattr(trials.study, "utc_now", lambda: SECOND)


def _tree(root: Path) -> dict[str, bytes]:
    """Every file under root by its path relative to root."""
    return {str(path.relative_to(root)): path.read_bytes() for path in sorted(root.rglob("*")) if path.is_file()}


def test_moves_in_one_second_get_folders_of_their_own(tmp_path, one_second):
    folder = StudyFolder(tmp_path)
    moved = []
    for content in ("first", "second", "third"):
        folder.path("plan.csv").write_text(content)
        folder.path("sealed").mkdir(exist_ok=True)
        folder.path("sealed/allocation.json").write_text(content)
        moved.append(folder.supersede(("plan.csv",), ("sealed/allocation.json",)))
    copied = folder.copy_aside(("notes.txt", "plan.csv"))
    names = ["2026-03-01T093000+0000", "2026-03-01T093000+0000-2", "2026-03-01T093000+0000-3"]
    assert moved == [folder.path(SUPERSEDED) / name for name in names]
    assert copied == folder.path(SUPERSEDED) / "2026-03-01T093000+0000-4"
    for name, content in zip(names, ("first", "second", "third")):
        assert (folder.path(SUPERSEDED) / name / "plan.csv").read_text() == content
        assert (folder.path(SEALED) / SUPERSEDED / name / "allocation.json").read_text() == content


def test_a_sealed_folder_of_the_same_name_is_never_shared(tmp_path, one_second):
    folder = StudyFolder(tmp_path)
    taken = folder.path(SEALED) / SUPERSEDED / "2026-03-01T093000+0000"
    taken.mkdir(parents=True)
    folder.path("plan.csv").write_text("new")
    assert folder.supersede(("plan.csv",)) == folder.path(SUPERSEDED) / "2026-03-01T093000+0000-2"
    assert sorted(p.name for p in folder.path(SUPERSEDED).iterdir()) == ["2026-03-01T093000+0000-2"]


def test_two_reruns_in_one_second_keep_both_earlier_runs(tmp_path, one_second):
    folder = StudyFolder(tmp_path)
    aside = []
    for attempt in ("first", "second"):
        outcomes = Outcomes(folder, blind=True)
        outcomes.append(_outcome("AAAAA", "goal", None))
        folder.run_log("AAAAA").parent.mkdir(exist_ok=True)
        folder.run_log("AAAAA").write_text(attempt)
        folder.sealed_run("AAAAA").parent.mkdir(parents=True, exist_ok=True)
        folder.sealed_run("AAAAA").write_text(attempt)
        aside.append(supersede_runs(folder, outcomes, ["AAAAA"], folder.aside_stamp()))
    assert aside[0] != aside[1]
    for target, attempt in zip(aside, ("first", "second")):
        assert (target / "runs" / "AAAAA.mcap").read_text() == attempt
        assert (folder.path(SEALED) / SUPERSEDED / target.name / "runs" / "AAAAA.json.gz").read_text() == attempt
        assert [row.run_code for row in read_outcomes(target / OUTCOMES, blind=True)] == ["AAAAA"]


@pytest.mark.slow  # three designs
def test_two_forces_in_one_second_keep_both_blinded_designs_and_their_sealed_runs(tmp_path, one_second):
    study = tmp_path / "study"
    design_small_study(study, blind=True)
    before = []
    for force in range(2):
        sealed_runs = study / "sealed" / "runs"
        sealed_runs.mkdir(exist_ok=True)
        (sealed_runs / f"RUN{force}.json.gz").write_bytes(f"sealed record {force}".encode())
        public = {name: (study / name).read_bytes() for name in ("study.toml", "plan.csv", "design.json")}
        sealed = {name: content for name, content in _tree(study / SEALED).items() if not name.startswith(SUPERSEDED)}
        before.append((public, sealed))
        assert main(["design", "--force", "--quiet", "--study", str(study)]) == 0
        assert not sealed_runs.exists()  # the next run starts on an empty sealed/runs/
    folders = sorted((study / SUPERSEDED).iterdir())
    assert [f.name for f in folders] == ["2026-03-01T093000+0000", "2026-03-01T093000+0000-2"]
    for folder, (public, sealed) in zip(folders, before):
        assert {name: (folder / name).read_bytes() for name in public} == public
        assert _tree(study / SEALED / SUPERSEDED / folder.name) == sealed
