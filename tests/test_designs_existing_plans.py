"""Plans that already exist (`trials design --evaluate`, `--compare`, `--augment`) and the spec's criterion and
disallowed combinations, end to end."""

from __future__ import annotations

import csv
import itertools
import json
from pathlib import Path

import numpy as np
import pytest

from designs.plan import balanced_arms
from tests.support.blinding import NAMES
from trials.cli import main

SPEC = """[study]
name = "restricted"
runs = 12
model = "main + interactions"
criterion = "I"
disallowed = ["Layout == 'doorway' and Speed > 1.0"]

[[factors]]
name = "Speed"
type = "continuous"
low = 0.4
high = 1.2

[[factors]]
name = "Layout"
type = "categorical"
levels = ["corridor", "hall", "doorway"]
"""


def _plan_rows(folder: Path) -> list[dict[str, str]]:
    with (folder / "plan.csv").open(newline="") as handle:
        return list(csv.DictReader(handle))


def test_evaluate_reproduces_the_diagnostics_of_a_generated_plan(tmp_path, capsys):
    study = tmp_path / "s"
    assert main(["design", "--study", str(study), "--seed", "3"]) == 0
    record = json.loads((study / "design.json").read_text())["diagnostics"]
    capsys.readouterr()
    before = sorted(p.name for p in study.iterdir())
    assert main(["design", "--study", str(study), "--evaluate", str(study / "plan.csv")]) == 0
    out = capsys.readouterr().out
    assert sorted(p.name for p in study.iterdir()) == before, "evaluate writes nothing"
    assert f"D-efficiency                 {record['d_efficiency']:9.4f}   det(X'X) = {record['det_xtx']:.10g}" in out
    assert f"A-efficiency                 {record['a_efficiency']:9.4f}" in out
    assert f"G-efficiency                 {record['g_efficiency']:9.4f}" in out
    assert f"Average prediction variance  {record['average_prediction_variance']:9.4f}" in out
    for term in record["power"]["terms"]:
        assert f"{term['parameters']} df  power {term['power']:.3f}" in out


def test_compare_sets_the_optimum_beside_the_full_factorial(tmp_path, capsys):
    study = tmp_path / "s"
    assert main(["design", "--study", str(study), "--seed", "1"]) == 0
    factorial = tmp_path / "factorial.csv"
    rows = itertools.product([2, 4, 6], ["Parallel", "ParallelCrossing", "Crossing"], [1, 2, 3])
    factorial.write_text("Pedestrians,Direction,CrossingDistance\n" + "".join(f"{a},{b},{c}\n" for a, b, c in rows))
    capsys.readouterr()
    assert main(["design", "--study", str(study), "--compare", str(study / "plan.csv"), str(factorial)]) == 0
    line = next(line for line in capsys.readouterr().out.splitlines() if line.startswith("D-efficiency"))
    assert line.split()[1:] == ["79.9157", "68.2558"]  # the proven optimum; the 3x3x3 closed form


def _factorial(path: Path) -> Path:
    """The 3 x 3 x 3 full factorial of the paper's factors, as a plan file."""
    rows = itertools.product([2, 4, 6], ["Parallel", "ParallelCrossing", "Crossing"], [1, 2, 3])
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("Pedestrians,Direction,CrossingDistance\n" + "".join(f"{a},{b},{c}\n" for a, b, c in rows))
    return path


def _png_width(path: Path) -> int:
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", path.name
    return int.from_bytes(data[16:20], "big")  # IHDR's width


FIGURES = ("correlation_map.png", "correlation_map.svg", "design_evaluation.png", "design_evaluation.svg")


@pytest.mark.slow  # over 1.5 s: left out of the quick loop
def test_evaluate_draws_the_plans_figures_beside_the_studys_own(tmp_path, capsys):
    study = tmp_path / "s"
    assert main(["design", "--study", str(study), "--seed", "1", "--figures", "--dpi", "50"]) == 0
    own = {p.name: p.read_bytes() for p in study.iterdir()}
    factorial = _factorial(tmp_path / "factorial.csv")
    assert main(["design", "--study", str(study), "--compare", str(study / "plan.csv"), str(factorial),
                 "--figures", "--dpi", "100"]) == 0
    assert "Wrote plan.correlation_map.png" in capsys.readouterr().out
    assert sorted(p.name for p in study.iterdir()) == sorted([*own, *(f"plan.{n}" for n in FIGURES),
                                                             *(f"factorial.{n}" for n in FIGURES)])
    assert {name: (study / name).read_bytes() for name in own} == own, "the study's own files stay as they were"
    for stem in ("correlation_map", "design_evaluation"):
        # The evaluated plan is the study's own plan, drawn at twice the resolution; its SVG is the same drawing.
        assert _png_width(study / f"plan.{stem}.png") == pytest.approx(2 * _png_width(study / f"{stem}.png"), rel=0.05)
        svg = (study / f"factorial.{stem}.svg").read_text(encoding="utf-8")
        assert svg.startswith("<?xml") and "<svg" in svg and "factorial.csv" in svg
        assert svg != (study / f"plan.{stem}.svg").read_text(encoding="utf-8")


@pytest.mark.slow  # over 1.5 s: left out of the quick loop
def test_evaluated_figures_are_replaced_only_with_force(tmp_path, capsys):
    factorial = _factorial(tmp_path / "factorial.csv")
    study = tmp_path / "s"
    args = ["design", "--study", str(study), "--evaluate", str(factorial), "--figures", "--dpi", "50"]
    assert main(args) == 0
    assert sorted(p.name for p in study.iterdir()) == sorted(f"factorial.{n}" for n in FIGURES)
    (study / "factorial.design_evaluation.svg").write_text("mine")
    capsys.readouterr()
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "factorial.correlation_map.png already exists; pass --force" in err
    assert (study / "factorial.design_evaluation.svg").read_text() == "mine"
    assert main([*args, "--force"]) == 0
    assert (study / "factorial.design_evaluation.svg").read_text(encoding="utf-8").startswith("<?xml")


def test_compared_plans_of_one_name_cannot_both_be_drawn(tmp_path, capsys):
    a, b = _factorial(tmp_path / "a" / "plan.csv"), _factorial(tmp_path / "b" / "plan.csv")
    study = tmp_path / "s"
    assert main(["design", "--study", str(study), "--compare", str(a), str(b), "--figures"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "both plans' files are named plan.csv" in err
    assert not study.exists()


@pytest.mark.parametrize(("cells", "message"), [
    ("5,Parallel,2", "factorial.csv line 2, column Pedestrians: 5 is no level of Pedestrians (levels: 2, 4, 6)"),
    ("2,Sideways,2", "factorial.csv line 2, column Direction: 'Sideways' is no level of Direction"),
    ("2,Parallel,9", "factorial.csv line 2, column CrossingDistance: 9 lies outside CrossingDistance's range [1, 3]"),
])
def test_a_bad_plan_to_evaluate_is_one_line(tmp_path, capsys, cells, message):
    bad = tmp_path / "factorial.csv"
    bad.write_text("Pedestrians,Direction,CrossingDistance\n" + f"{cells}\n" * 6)
    assert main(["design", "--study", str(tmp_path / "s"), "--evaluate", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.strip() == f"error: {message}" or message in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "s").exists() or not any((tmp_path / "s").iterdir())


def test_spec_criterion_and_disallowed_reach_the_plan(tmp_path, capsys):
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC)
    study = tmp_path / "s"
    assert main(["design", "--spec", str(spec), "--study", str(study), "--seed", "2"]) == 0
    assert "criterion I (smallest average prediction variance)" in capsys.readouterr().out
    rows = _plan_rows(study)
    assert len(rows) == 12
    assert not any(r["Layout"] == "doorway" and float(r["Speed"]) > 1.0 + 1e-9 for r in rows)
    record = json.loads((study / "design.json").read_text())
    assert record["criterion"] == "I" and record["search"]["criterion"] == "I"
    assert record["search"]["criterion_value"] == pytest.approx(record["diagnostics"]["average_prediction_variance"], rel=1e-9)
    search = record["search"]
    assert (search["patience"], search["restart_kicks"], search["agreed"]) == (20, 2, 3)
    assert "kicks of 3 runs" in search["algorithm"] and "after 20 kicks without gain" in search["algorithm"]
    assert search["kick_budget_per_start"] == 0 and search["hits"] == 100  # every start agrees: no kick
    assert record["disallowed"] == ["Layout == 'doorway' and Speed > 1.0"]
    assert 'criterion = "I"' in (study / "study.toml").read_text()


@pytest.mark.parametrize(("line", "message"), [
    ('criterion = "E"', "spec.toml: [study]: criterion must be one of D, I, A, got 'E'"),
    ('disallowed = ["Layout == \'attic\'"]', "'attic' is no level of Layout"),
    ('disallowed = ["open(\'x\')"]', "expected a comparison"),
    ('constraints = "Speed < 1"', "constraints must be a list of strings"),
    ('disallowed = ["Layout == \'hall\' or Layout != \'hall\'"]', "leave no candidate point"),
])
def test_bad_criterion_or_restriction_is_one_line_exit_2(tmp_path, capsys, line, message):
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC.replace('criterion = "I"\ndisallowed = ["Layout == \'doorway\' and Speed > 1.0"]', line))
    assert main(["design", "--spec", str(spec), "--study", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "s").exists() or not any((tmp_path / "s").iterdir())


@pytest.mark.slow  # over 1.5 s: left out of the quick loop
def test_augment_keeps_the_planned_runs_results_and_key(tmp_path, capsys):
    study = tmp_path / "s"
    assert main(["design", "--ab", "--seed", "1", "--study", str(study), "--figures"]) == 0
    before = json.loads((study / "design.json").read_text())
    old_map = (study / "correlation_map.svg").read_bytes()
    old_plan = (study / "plan.csv").read_text().splitlines()
    (study / "outcomes.csv").write_text("kept results\n")
    key = (study / "sealed" / "allocation.json").read_bytes()
    capsys.readouterr()
    assert main(["design", "--augment", "6", "--seed", "4", "--study", str(study)]) == 0
    assert "Kept the 18 planned runs and their results; added 6" in capsys.readouterr().out
    new_plan = (study / "plan.csv").read_text().splitlines()
    assert new_plan[: len(old_plan)] == old_plan and len(new_plan) == len(old_plan) + 6
    assert (study / "outcomes.csv").read_text() == "kept results\n"
    assert (study / "sealed" / "allocation.json").read_bytes() == key
    after = json.loads((study / "design.json").read_text())
    assert after["design"][:18] == before["design"]
    assert [run["order"] for run in after["design"]] == list(range(1, 25))
    assert len({run["run_code"] for run in after["design"]}) == 24
    assert after["blinding"]["commitment"] == before["blinding"]["commitment"]
    assert after["diagnostics"]["det_xtx"] > before["diagnostics"]["det_xtx"]
    copies = list((study / "superseded").iterdir())
    assert len(copies) == 1 and json.loads((copies[0] / "design.json").read_text()) == before
    # Figures of the old plan are kept aside only: drawn without --figures, none would show the new plan.
    assert (copies[0] / "correlation_map.svg").read_bytes() == old_map
    assert not list(study.glob("correlation_map.*")) and not list(study.glob("design_evaluation.*"))


def _public_files(study: Path) -> dict[str, bytes]:
    return {str(p.relative_to(study)): p.read_bytes() for p in sorted(study.rglob("*"))
            if p.is_file() and "sealed" not in p.relative_to(study).parts and "superseded" not in p.relative_to(study).parts}


def test_augmented_runs_of_a_blinded_study_are_split_evenly_between_its_arms(tmp_path, capsys):
    """Left to the exchange, four runs added to this 18-run A/B plan went 1 to A and 3 to B (and all 4 to B in
    other studies); the allocation gives each arm two, and an odd fifth to a random arm. The public files are
    the same whichever controller the sealed key puts behind A, so they tell nothing of the new runs' controllers."""
    studies = {}
    for seed in (0, 3):  # two allocation seeds giving opposite keys
        study = tmp_path / f"s{seed}"
        assert main(["design", "--ab", "--seed", "7", "--allocation-seed", str(seed), "--study", str(study)]) == 0
        assert main(["design", "--augment", "4", "--seed", "1", "--study", str(study)]) == 0
        studies[seed] = study
    capsys.readouterr()
    keys = [json.loads((s / "sealed" / "allocation.json").read_text())["arms"] for s in studies.values()]
    assert keys[0]["A"] == keys[1]["B"] and keys[0]["A"] != keys[1]["A"]
    rows = _plan_rows(studies[0])
    assert [row["Controller"] for row in rows[:18]].count("A") == 9
    assert sorted(row["Controller"] for row in rows[18:]) == ["A", "A", "B", "B"]
    public = [_public_files(s) for s in studies.values()]
    assert public[0]["plan.csv"] == public[1]["plan.csv"]
    records = [json.loads(files.pop("design.json")) for files in public]
    for record in records:
        del record["blinding"], record["created"], record["digest"]
    assert records[0] == records[1]
    assert not any(NAMES.search(content) for files in public for content in files.values())

    assert main(["design", "--augment", "5", "--seed", "2", "--study", str(studies[0])]) == 0
    new = [row["Controller"] for row in _plan_rows(studies[0])[22:]]
    assert len(new) == 5 and sorted(new.count(arm) for arm in "AB") == [2, 3]


def test_balanced_arms_gives_the_remainder_to_the_arms_with_fewest_runs():
    kept = np.array([0.0] * 10 + [1.0] * 8 + [2.0] * 9)
    for seed in range(5):
        arms = balanced_arms(kept, 5, 3, np.random.default_rng(seed))
        assert np.bincount(arms.astype(int), minlength=3).tolist() == [1, 2, 2]
    drawn = {tuple(balanced_arms(np.zeros(0), 6, 2, np.random.default_rng(seed))) for seed in range(10)}
    assert all(sorted(arms) == [0, 0, 0, 1, 1, 1] for arms in drawn) and len(drawn) > 3  # in random order


def test_augment_needs_a_plan(tmp_path, capsys):
    assert main(["design", "--augment", "3", "--study", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and len(err.strip().splitlines()) == 1


BLOCKED = """[study]
name = "blocked"
runs = 12
model = "main"
blocks = 3

[[factors]]
name = "Speed"
type = "continuous"
low = 0.4
high = 1.2

[[factors]]
name = "Age"
type = "covariate"
file = "ages.csv"
"""


def test_blocks_and_a_covariate_file_reach_the_plan(tmp_path):
    (tmp_path / "ages.csv").write_text("participant,Age\n" + "".join(f"P{i},{20 + 3 * i}\n" for i in range(12)))
    spec = tmp_path / "spec.toml"
    spec.write_text(BLOCKED)
    study = tmp_path / "s"
    assert main(["design", "--spec", str(spec), "--study", str(study), "--seed", "5"]) == 0
    rows = _plan_rows(study)
    assert [r["Block"] for r in rows] == ["1"] * 4 + ["2"] * 4 + ["3"] * 4
    assert [int(r["Age"]) for r in rows] == [20 + 3 * i for i in range(12)]
    text, _, analysis = (study / "study.toml").read_text().partition("[analysis]")
    assert "blocks = 3" in text and "values = [" in text and "Block" not in text  # the spec keeps blocks as a count
    assert 'model = "main + Block"' in analysis  # no arms to compare: the GEE of the design's model and its blocks
    record = json.loads((study / "design.json").read_text())
    assert record["model"]["terms"] == ["Intercept", "Speed", "Age", "Block"]
    # the written spec reads back to the same plan checks
    assert main(["design", "--study", str(study), "--evaluate", str(study / "plan.csv")]) == 0


@pytest.mark.parametrize(("old", "new", "message"), [
    ("blocks = 3", "blocks = 5", "blocks = 5 must divide runs = 12"),
    ('file = "ages.csv"', 'file = "none.csv"', "cannot read the covariate file"),
    ('file = "ages.csv"', "values = [1, 2]", "covariate Age has 2 values for 12 runs"),
    ('file = "ages.csv"', 'values = [1, "x"]', "covariate value (values[1]: 'x')"),
])
def test_bad_blocks_or_covariates_are_one_line(tmp_path, capsys, old, new, message):
    (tmp_path / "ages.csv").write_text("Age\n" + "30\n" * 6 + "40\n" * 6)
    spec = tmp_path / "spec.toml"
    spec.write_text(BLOCKED.replace(old, new))
    assert main(["design", "--spec", str(spec), "--study", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
