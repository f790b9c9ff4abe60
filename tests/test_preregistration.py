"""The pre-registration binds the analysis plan, the design and the sealed key: `trials design` prints the one digest
to record outside the study, opening the key checks it, and every report says whether the study is what it registered."""

from __future__ import annotations

import hashlib
import json
import re
import shutil
import tomllib
from pathlib import Path

import pytest
import tomli_w

from analysis.plan import table_digest
from tests.support.registration import recorded_digest
from tests.support.synthetic_study import judged_ab_study
from trials.cli import main
from trials.study import design_digest

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def finished(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The blinded A/B plan, every run finished and judged by simulated participants."""
    return judged_ab_study(tmp_path_factory.mktemp("registered") / "study")


def _copy(study: Path, tmp_path: Path) -> Path:
    return Path(shutil.copytree(study, tmp_path / "copy"))


def _restrata(study: Path, strata: list[str], recompute: bool) -> None:
    """Change the [analysis] table's strata in study.toml; with `recompute`, make design.json commit to the new plan and
    recompute its own digest, as someone covering the change would."""
    spec = study / "study.toml"
    tables = tomllib.loads(spec.read_text())
    tables["analysis"]["strata"] = strata
    spec.write_text(tomli_w.dumps(tables))
    if recompute:
        record = json.loads((study / "design.json").read_text())
        record["analysis_plan"]["sha256"] = table_digest(tables["analysis"])
        record["digest"] = design_digest(record)
        (study / "design.json").write_text(json.dumps(record, indent=1))


def _report(study: Path, capsys: pytest.CaptureFixture[str], *extra: str) -> tuple[int, str, str]:
    capsys.readouterr()
    code = main(["report", "--study", str(study), *extra])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_design_writes_a_registration_whose_digest_it_prints(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    capsys.readouterr()
    assert main(["design", "--ab", "--seed", "3", "--power", "0", "--study", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    text = (tmp_path / "preregistration.md").read_text()
    digest = hashlib.sha256(text.encode()).hexdigest()
    assert f"Pre-registration preregistration.md, sha256\n  {digest}\nRecord this digest outside the study folder" in out
    for heading in ("Hypotheses", "Design", "Allocation", "Planned analysis", "Sample size and power", "Stopping rules",
                    "Exclusion rules", "Deviations", "Bindings"):
        assert f"\n## {heading}\n" in text, heading
    record = json.loads((tmp_path / "design.json").read_text())
    bound = dict(re.findall(r"^- (design|analysis plan|sealed key): `([0-9a-f]{64})`", text, re.MULTILINE))
    assert bound == {"design": record["digest"]["sha256"], "analysis plan": record["analysis_plan"]["sha256"],
                     "sealed key": record["blinding"]["commitment"]["digest"]}
    assert "NaviGAN" not in text and "lattice" not in text.lower()  # public: arm labels only


def test_the_registered_study_unblinds_against_its_digest(finished: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    study = _copy(finished, tmp_path)
    key = json.loads((study / "design.json").read_text())["blinding"]["commitment"]["digest"]
    code, _, err = _report(study, capsys, "--unblind", "--commitment", key)
    assert code == 2 and "that is the sealed key's commitment; this study has a pre-registration" in err
    code, out, _ = _report(study, capsys, "--unblind", "--commitment", recorded_digest(study))
    assert code == 0 and "matched the digest recorded outside the study" in out
    record = json.loads((study / "report" / "report.json").read_text())
    assert record["preregistration"] == {"sha256": recorded_digest(study), "differs": [], "matches_recorded": True,
                                         "analysis_registered": True}
    assert "The design and sealed key are those it registered. The analysis run is the registered one." in (study / "report" / "report.md").read_text()


def test_a_plan_swapped_by_hand_is_refused_and_reported(finished: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    study = _copy(finished, tmp_path)
    recorded = recorded_digest(study)
    _restrata(study, ["Direction"], recompute=True)
    assert main(["status", "--study", str(study)]) == 0  # design.json reads as sound: its own digest was recomputed
    code, _, err = _report(study, capsys, "--unblind", "--commitment", recorded)
    assert code == 2 and "the design of" in err and "differ from what preregistration.md registered" in err, err
    assert not (study / "unblinding.json").exists()
    code, _, _ = _report(study, capsys, "--commitment", recorded)
    markdown = (study / "report" / "report.md").read_text()
    assert code == 0 and "**Changed since it was written: the design**" in markdown
    assert "**The analysis run is not the registered one**" in markdown
    assert json.loads((study / "report" / "report.json").read_text())["preregistration"]["differs"] == ["design", "analysis plan"]

    # Rewriting the registration to match changes its digest: the one recorded outside no longer fits.
    text = (study / "preregistration.md").read_text()
    record = json.loads((study / "design.json").read_text())
    text = re.sub(r"^- design: `[0-9a-f]{64}`", f"- design: `{record['digest']['sha256']}`", text, flags=re.MULTILINE)
    text = re.sub(r"^- analysis plan: `[0-9a-f]{64}`", f"- analysis plan: `{record['analysis_plan']['sha256']}`", text, flags=re.MULTILINE)
    (study / "preregistration.md").write_text(text)
    code, _, _ = _report(study, capsys)  # without the recorded digest, the rewritten file looks sound
    assert code == 0 and "The design and sealed key are those it registered" in (study / "report" / "report.md").read_text()
    code, _, _ = _report(study, capsys, "--commitment", recorded)  # with it, a plain report says what happened
    assert code == 0 and "**It does not match the digest recorded outside the study**" in (study / "report" / "report.md").read_text()
    assert json.loads((study / "report" / "report.json").read_text())["preregistration"]["matches_recorded"] is False
    code, _, err = _report(study, capsys, "--unblind", "--commitment", recorded)
    assert code == 2 and "preregistration.md does not match the digest you recorded" in err, err
    # Removing it leaves the study looking older than pre-registrations: the digest recorded outside still fails.
    (study / "preregistration.md").unlink()
    code, _, err = _report(study, capsys, "--unblind", "--commitment", recorded)
    assert code == 2 and "preregistration.md was removed" in err, err
    assert not (study / "unblinding.json").exists()


def test_an_analysis_changed_in_study_toml_alone_is_run_and_said_not_registered(finished: Path, tmp_path: Path,
                                                                               capsys: pytest.CaptureFixture[str]) -> None:
    study = _copy(finished, tmp_path)
    _restrata(study, ["Direction"], recompute=False)
    code, _, _ = _report(study, capsys, "--unblind", "--commitment", recorded_digest(study))
    markdown = (study / "report" / "report.md").read_text()
    assert code == 0 and "The design and sealed key are those it registered. **The analysis run is not the registered one**" in markdown
    assert "re-randomized within Direction" in markdown
