"""Blinded A/B plans: no public output reveals the allocation; the commitment catches a changed key."""

from __future__ import annotations

import hashlib
import json
import shutil
import stat
from pathlib import Path

import pytest

from designs.blinding import FACTOR_AND_ARMS, WHOLE_KEY, SealedAllocation, seal, verify
from designs.errors import DesignError
from trials.cli import main
from trials.controllers.registry import AB_PRESET as CONTROLLERS
from trials.errors import StudyError
from trials.study import StudyFolder, design_digest

CONTROLLER_WORDS = ("navigan", "lattice", "sbpl")


def public_files(folder: Path) -> list[Path]:
    return [p for p in folder.rglob("*") if p.is_file() and "sealed" not in p.relative_to(folder).parts]


@pytest.mark.slow  # over 1.5 s: left out of the quick loop
def test_ab_plan_public_outputs_name_no_controller(tmp_path, capsys):
    assert main(["design", "--ab", "--study", str(tmp_path), "--seed", "12", "--figures"]) == 0
    captured = capsys.readouterr()
    console = (captured.out + captured.err).lower()
    assert all(word not in console for word in CONTROLLER_WORDS)
    files = public_files(tmp_path)
    assert sorted(p.name for p in files) == ["correlation_map.png", "correlation_map.svg", "design.json", "design_evaluation.png",
                                             "design_evaluation.svg", "plan.csv", "preregistration.md", "study.toml"]
    for path in files:
        content = path.read_bytes().lower()
        assert all(word.encode() not in content for word in CONTROLLER_WORDS), path.name
        assert all(word not in path.name.lower() for word in CONTROLLER_WORDS)
    sealed = json.loads((tmp_path / "sealed" / "allocation.json").read_text())
    assert sorted(sealed["arms"]) == ["A", "B"]
    assert sorted(sealed["arms"].values()) == sorted(CONTROLLERS)
    plan = (tmp_path / "plan.csv").read_text().splitlines()
    assert plan[0] == "order,run_code,Pedestrians,Direction,Controller,CrossingDistance"
    assert {line.split(",")[4] for line in plan[1:]} == {"A", "B"}
    assert len(plan) == 19


@pytest.mark.slow
def test_allocation_does_not_follow_from_the_public_seed(tmp_path):
    """The same public seed gives the same public plan; each key comes from a fresh secret seed."""
    keys = []
    for name in ("a", "b"):
        assert main(["design", "--ab", "--study", str(tmp_path / name), "--seed", "12"]) == 0
        keys.append(json.loads((tmp_path / name / "sealed" / "allocation.json").read_text()))
    assert (tmp_path / "a" / "plan.csv").read_text() == (tmp_path / "b" / "plan.csv").read_text()
    assert keys[0]["allocation_seed"] != keys[1]["allocation_seed"]
    assert 12 not in (keys[0]["allocation_seed"], keys[1]["allocation_seed"])
    mappings = {seal("Controller", CONTROLLERS).arms["A"] for _ in range(16)}
    assert mappings == set(CONTROLLERS)  # both allocations occur (fails with p = 2 / 2**16)


def test_allocation_seed_reproduces_the_key(tmp_path):
    keys = []
    for name in ("a", "b"):
        assert main(["design", "--ab", "--study", str(tmp_path / name), "--seed", "3", "--allocation-seed", "77"]) == 0
        keys.append(json.loads((tmp_path / name / "sealed" / "allocation.json").read_text()))
    assert keys[0]["arms"] == keys[1]["arms"] and keys[0]["allocation_seed"] == 77
    assert keys[0]["salt"] != keys[1]["salt"]  # the salt is always fresh, so the digest cannot be brute-forced


def test_commitment_check_detects_a_changed_key(tmp_path):
    assert main(["design", "--ab", "--study", str(tmp_path), "--seed", "5"]) == 0
    folder = StudyFolder(tmp_path)
    original = folder.read_sealed()
    assert sorted(original.arms.values()) == sorted(CONTROLLERS)
    path = tmp_path / "sealed" / "allocation.json"
    key = json.loads(path.read_text())
    key["arms"] = {"A": key["arms"]["B"], "B": key["arms"]["A"]}
    path.write_text(json.dumps(key))
    with pytest.raises(StudyError, match="does not match the commitment"):
        folder.read_sealed()
    path.write_text("{not json")
    with pytest.raises(StudyError, match="sealed key .* is damaged"):
        folder.read_sealed()


def test_seal_and_verify():
    sealed = seal("Controller", ("x", "y", "z"), seed=4)
    assert sorted(sealed.arms) == ["A", "B", "C"] and sorted(sealed.arms.values()) == ["x", "y", "z"]
    key = sealed.to_dict()
    assert "whole key" in verify(key, sealed, WHOLE_KEY, sealed.commitment())
    # Every field is covered: the arms, the salt, the allocation seed, and a field added to the file.
    for changed in ({"arms": {**sealed.arms, "A": "w"}}, {"salt": "0" * 32}, {"allocation_seed": sealed.seed + 1},
                    {"note": "added"}):
        tampered = {**key, **changed}
        with pytest.raises(DesignError, match="does not match the commitment in design.json"):
            verify(tampered, SealedAllocation.from_dict(tampered, "key"), WHOLE_KEY, sealed.commitment())


def test_blind_spec_written_by_the_researcher_moves_under_sealed(tmp_path, capsys):
    """A study.toml that names the blinded levels is kept under sealed/; the public one has arms."""
    spec = (
        '[study]\nruns = 8\nmodel = "main"\nseed = 2\n\n'
        '[[factors]]\nname = "Peds"\ntype = "discrete"\nlevels = [2, 6]\n\n'
        '[[factors]]\nname = "Planner"\ntype = "categorical"\nblind = true\nlevels = ["NaviGAN-R", "Lattice"]\n'
    )
    (tmp_path / "study.toml").write_text(spec)
    assert main(["design", "--study", str(tmp_path)]) == 0
    assert (tmp_path / "sealed" / "spec.toml").read_text() == spec
    public = (tmp_path / "study.toml").read_text()
    assert 'arms = [' in public and "navigan" not in public.lower()
    for path in public_files(tmp_path):
        assert b"lattice" not in path.read_bytes().lower()
    # Re-designing from the public spec recovers the levels through the verified key.
    capsys.readouterr()
    assert main(["design", "--study", str(tmp_path), "--force"]) == 0
    assert sorted(StudyFolder(tmp_path).read_sealed().arms.values()) == ["Lattice", "NaviGAN-R"]
    assert "lattice" not in capsys.readouterr().out.lower()


@pytest.fixture(scope="module")
def designed(tmp_path_factory) -> Path:
    """The blinded A/B plan (seed 5), designed once; tests change copies of it."""
    study = tmp_path_factory.mktemp("ab") / "study"
    assert main(["design", "--ab", "--study", str(study), "--seed", "5"]) == 0
    return study


@pytest.fixture
def study(designed, tmp_path) -> Path:
    return Path(shutil.copytree(designed, tmp_path / "study"))


def _digest(key: dict) -> str:
    return hashlib.sha256(json.dumps(key, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def test_design_prints_the_whole_commitment_and_seals_privately(tmp_path, capsys):
    assert main(["design", "--ab", "--study", str(tmp_path), "--seed", "5"]) == 0
    out = capsys.readouterr().out
    key = json.loads((tmp_path / "sealed" / "allocation.json").read_text())
    digest = json.loads((tmp_path / "design.json").read_text())["blinding"]["commitment"]["digest"]
    assert set(key) == {"factor", "arms", "salt", "allocation_seed"} and digest == _digest(key)
    assert f"  {digest}\n" in out and "Record this digest outside the study folder" in out
    assert "readable by you only (folder 0700, files 0600)" in out
    assert stat.S_IMODE((tmp_path / "sealed").stat().st_mode) == 0o700
    assert stat.S_IMODE((tmp_path / "sealed" / "allocation.json").stat().st_mode) == 0o600


def _swap_arms(path: Path, design: Path) -> None:
    """Swap the key's arms and make design.json commit to the swapped key, its own digest recomputed."""
    key = json.loads(path.read_text())
    key["arms"] = {"A": key["arms"]["B"], "B": key["arms"]["A"]}
    path.write_text(json.dumps(key))
    record = json.loads(design.read_text())
    record["blinding"]["commitment"]["digest"] = _digest(key)
    record["digest"] = design_digest(record)
    design.write_text(json.dumps(record))


def test_a_swapped_key_with_a_recomputed_digest_fails_the_registration(study):
    folder = StudyFolder(study)
    recorded = hashlib.sha256((study / "preregistration.md").read_bytes()).hexdigest()
    assert "matched the digest recorded outside the study" in folder.open_sealed(recorded)[1]
    _swap_arms(study / "sealed" / "allocation.json", study / "design.json")
    with pytest.raises(StudyError, match="the design and the sealed key of .* differ from what preregistration.md registered"):
        folder.open_sealed(recorded)


def test_a_swapped_key_with_a_recomputed_digest_fails_the_recorded_commitment(study):
    """A study designed before pre-registrations: the key's commitment is what was recorded outside it."""
    (study / "preregistration.md").unlink()
    folder, path, design = StudyFolder(study), study / "sealed" / "allocation.json", study / "design.json"
    recorded = json.loads(design.read_text())["blinding"]["commitment"]["digest"]
    assert "recorded outside the study" in folder.open_sealed(recorded)[1]
    _swap_arms(path, design)
    # design.json alone is fooled, and says it could be; the recorded value is not.
    assert "a key and design.json changed together would pass" in folder.open_sealed()[1]
    with pytest.raises(StudyError, match="does not match the commitment you recorded"):
        folder.open_sealed(recorded)
    with pytest.raises(StudyError, match="expected the 64 hex digits"):
        folder.open_sealed(recorded[:16])


def test_the_allocation_seed_is_committed_to(study):
    path = study / "sealed" / "allocation.json"
    key = json.loads(path.read_text())
    path.write_text(json.dumps({**key, "allocation_seed": key["allocation_seed"] + 1}))
    with pytest.raises(StudyError, match="does not match the commitment in design.json"):
        StudyFolder(study).read_sealed()


def test_an_older_study_keeps_its_commitment_checked_as_before(study):
    """A study made by an earlier release: its key has `created`, design.json the salted factor-and-arms digest."""
    path, design = study / "sealed" / "allocation.json", study / "design.json"
    key = {**json.loads(path.read_text()), "created": "2026-01-01T00:00:00+00:00"}
    path.write_text(json.dumps(key))
    arms = json.dumps({"factor": key["factor"], "arms": key["arms"]}, sort_keys=True, separators=(",", ":"))
    record = json.loads(design.read_text())
    record["blinding"]["commitment"] = {"algorithm": FACTOR_AND_ARMS,
                                        "digest": hashlib.sha256(f"{key['salt']}\n{arms}".encode()).hexdigest()}
    del record["digest"]  # earlier releases' design.json had no digest of its own
    design.write_text(json.dumps(record))
    folder = StudyFolder(study)
    assert "the older format: the allocation seed is not covered" in folder.open_sealed()[1]
    path.write_text(json.dumps({**key, "allocation_seed": 1}))
    assert folder.read_sealed().seed == 1  # not covered by that format, as before
    path.write_text(json.dumps({**key, "arms": {"A": key["arms"]["B"], "B": key["arms"]["A"]}}))
    with pytest.raises(StudyError, match="does not match the commitment in design.json"):
        folder.read_sealed()
