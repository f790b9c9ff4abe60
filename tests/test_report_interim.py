"""An interim look at a blinded study: before every run has finished its report compares no arms, unless
`--interim REASON` is given, and then the look is recorded in unblinding.json as an opening of the key is."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.support.registration import recorded_digest
from tests.support.synthetic_study import design, judged_ab_study, run_all
from trials.cli import main

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def study(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The blinded A/B plan with 4 of its 18 runs finished and judged by simulated participants."""
    return judged_ab_study(tmp_path_factory.mktemp("interim") / "study", limit=4)


def _report(root: Path, capsys: pytest.CaptureFixture[str], *extra: str) -> tuple[str, dict, str]:
    capsys.readouterr()
    assert main(["report", "--study", str(root), *extra]) == 0
    out = capsys.readouterr().out
    return out, json.loads((root / "report" / "report.json").read_text()), (root / "report" / "report.md").read_text()


def test_a_blinded_report_compares_arms_before_the_end_only_as_a_recorded_interim_look(study: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out, record, markdown = _report(study, capsys)
    assert record["blinding"]["compares_arms"] is False and record["blinding"]["interim_look"] is None
    assert record["primary"] is None and record["fits"] == [] and record["scores_by_arm"] == {}
    assert {arm for row in record["table_ii"] for arm in row["arms"]} == {"all arms"}
    assert all(row["fisher_p"] is None for row in record["table_ii"])
    assert {s["arm"] for s in record["scores"].values()} == {"all arms"}
    for text in (out, markdown):
        assert "4 of 18 runs have finished in this blinded study, so this report compares no arms" in text
        assert "Primary result" not in text and "Fisher" not in text
    assert "A: runs" not in markdown and "| A |" not in markdown
    assert not (study / "unblinding.json").exists()

    reason = "safety review after a near miss"
    out, record, markdown = _report(study, capsys, "--interim", reason)
    assert record["blinding"]["compares_arms"] is True and record["blinding"]["controllers_named"] is False
    assert record["blinding"]["interim_look"] == {"completeness": "4 of 18 runs finished", "reason": reason}
    assert record["primary"] is not None and {arm for row in record["table_ii"] for arm in row["arms"]} == {"A", "B"}
    assert f"**Interim look** at the blinded arms with 4 of 18 runs finished, for this reason: {reason}" in markdown
    looks = json.loads((study / "unblinding.json").read_text())
    (look,) = looks["interim_looks"]
    assert (look["completeness"], look["interim"], look["command"]) == ("4 of 18 runs finished", reason, "trials report --interim")
    assert looks["unblinded_utc"] == [] and looks["openings"] == []
    assert look["analysis_plan_sha256"] == json.loads((study / "design.json").read_text())["analysis_plan"]["sha256"]

    capsys.readouterr()
    assert main(["status", "--study", str(study)]) == 0
    assert "unblinded: no (the sealed key is closed)" in capsys.readouterr().out

    out, record, markdown = _report(study, capsys)  # pooled again, and the earlier look is told
    assert record["blinding"]["compares_arms"] is False and len(record["blinding"]["interim_looks"]) == 1
    assert f"Interim looks at the blinded arms before this report (1): {look['utc']}, 4 of 18 runs finished, for this reason: {reason}." in markdown

    digest = recorded_digest(study)
    _report(study, capsys, "--unblind", "--commitment", digest, "--interim", "the second look, unblinded")
    kept = json.loads((study / "unblinding.json").read_text())
    assert kept["interim_looks"] == [look] and len(kept["openings"]) == 1 and len(kept["unblinded_utc"]) == 1


def test_an_interim_look_needs_runs_to_go_and_a_blinded_study(study: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    open_study = tmp_path / "open"
    run_all(design(open_study, ab=False), limit=2, blind=False)
    capsys.readouterr()
    assert main(["report", "--study", str(open_study), "--interim", "why"]) == 2
    assert "the study is not blinded, so its report compares the arms at any time" in capsys.readouterr().err
    assert not (open_study / "report").exists()
