"""`trials design` end to end: the study folder it writes, bad input, reproducibility, --force."""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from trials.cli import main

GENERIC_SPEC = """
[study]
name = "speed-trial"
runs = 12
model = "Speed + Density + Layout + Speed*Layout + Speed^2"
seed = 31
starts = 20

[[factors]]
name = "Speed"
type = "continuous"
low = 0.4
high = 1.2
units = "m/s"

[[factors]]
name = "Density"
type = "discrete"
levels = [0.1, 0.3]

[[factors]]
name = "Layout"
type = "categorical"
levels = ["corridor", "hall", "doorway"]

[[factors]]
name = "Robot"
type = "fixed"
value = "husky"
"""


def design(tmp_path: Path, *args: str) -> int:
    return main(["design", "--study", str(tmp_path), *args])


def read_plan(folder: Path) -> list[dict[str, str]]:
    with (folder / "plan.csv").open(newline="") as handle:
        return list(csv.DictReader(handle))


def test_qualitative_default_writes_the_study_folder(tmp_path, capsys):
    assert design(tmp_path, "--runs", "27", "--seed", "4") == 0
    out = capsys.readouterr().out
    assert "79.9157" in out and "80.2742" in out and "99.55 %" in out
    assert sorted(p.name for p in tmp_path.iterdir()) == ["design.json", "plan.csv", "preregistration.md", "study.toml"]
    rows = read_plan(tmp_path)
    assert len(rows) == 27
    assert list(rows[0]) == ["order", "run_code", "Pedestrians", "Direction", "CrossingDistance"]
    assert [r["order"] for r in rows] == [str(i) for i in range(1, 28)]
    assert {r["Pedestrians"] for r in rows} == {"2", "6"}
    assert {r["CrossingDistance"] for r in rows} == {"1", "3"}
    assert len({r["run_code"] for r in rows}) == 27
    record = json.loads((tmp_path / "design.json").read_text())
    d = record["diagnostics"]
    assert d["p"] == 5 and d["det_xtx"] == pytest.approx(4_677_120)
    assert d["d_efficiency"] == pytest.approx(79.9157, abs=1e-4)
    assert d["d_efficiency_vs_bound"] == pytest.approx(100 * 79.9157 / 80.2742, abs=1e-3)
    for key in ("a_efficiency", "g_efficiency", "average_prediction_variance", "standard_errors", "correlation_map", "power"):
        assert key in d
    assert len(d["correlation_map"]["matrix"]) == 4
    assert [t["term"] for t in d["power"]["terms"]] == ["Intercept", "Pedestrians", "Direction", "CrossingDistance"]
    assert record["seed"] == 4 and record["blinding"] is None


def _png_width(path: Path) -> int:
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", path.name
    return int.from_bytes(data[16:20], "big")  # IHDR's width


@pytest.mark.slow  # over 1.5 s: left out of the quick loop
def test_figures_are_drawn_on_request_as_png_at_dpi_and_svg(tmp_path):
    low, high = tmp_path / "low", tmp_path / "high"
    assert design(low, "--runs", "27", "--seed", "4", "--figures", "--dpi", "50") == 0
    assert design(high, "--runs", "27", "--seed", "4", "--figures", "--dpi", "100") == 0
    assert sorted(p.name for p in low.iterdir()) == ["correlation_map.png", "correlation_map.svg", "design.json",
                                                     "design_evaluation.png", "design_evaluation.svg", "plan.csv", "preregistration.md", "study.toml"]
    for stem in ("correlation_map", "design_evaluation"):
        assert _png_width(high / f"{stem}.png") == pytest.approx(2 * _png_width(low / f"{stem}.png"), rel=0.05)
        svg = (low / f"{stem}.svg").read_text(encoding="utf-8")
        assert svg.startswith("<?xml") and "<svg" in svg
        assert svg == (high / f"{stem}.svg").read_text(encoding="utf-8")  # SVG has no resolution


@pytest.mark.slow
def test_same_seed_same_plan_other_seed_other_order(tmp_path):
    """The seed alone fixes the plan, whatever the threads its starts searched on."""
    a, b, c = tmp_path / "a", tmp_path / "b", tmp_path / "c"
    for folder, seed, threads in [(a, "9", "1"), (b, "9", "3"), (c, "10", "1")]:
        assert design(folder, "--seed", seed, "--threads", threads) == 0
    assert (a / "plan.csv").read_text() == (b / "plan.csv").read_text()
    assert (a / "study.toml").read_text() == (b / "study.toml").read_text()
    design_a, design_b = (json.loads((f / "design.json").read_text()) for f in (a, b))
    for record in (design_a, design_b):
        del record["created"], record["digest"]  # the time it was made, and the digest that covers it
    assert design_a == design_b
    assert read_plan(a) != read_plan(c)


@pytest.mark.slow
def test_seed_is_drawn_and_recorded_when_not_given(tmp_path, capsys):
    assert design(tmp_path) == 0
    seed = json.loads((tmp_path / "design.json").read_text())["seed"]
    assert f"seed = {seed}" in (tmp_path / "study.toml").read_text()
    assert f"Seed {seed}" in capsys.readouterr().out
    rebuilt = tmp_path / "again"
    assert design(rebuilt, "--seed", str(seed)) == 0
    assert (rebuilt / "plan.csv").read_text() == (tmp_path / "plan.csv").read_text()


@pytest.mark.slow
def test_generic_study_from_a_spec_file(tmp_path):
    spec = tmp_path / "spec.toml"
    spec.write_text(GENERIC_SPEC)
    folder = tmp_path / "study"
    assert design(folder, "--spec", str(spec)) == 0
    rows = read_plan(folder)
    assert len(rows) == 12
    assert list(rows[0]) == ["order", "run_code", "Speed", "Density", "Layout", "Robot"]
    assert {r["Robot"] for r in rows} == {"husky"}
    assert all(0.4 - 1e-9 <= float(r["Speed"]) <= 1.2 + 1e-9 for r in rows)
    assert {r["Density"] for r in rows} <= {"0.1", "0.3"}
    record = json.loads((folder / "design.json").read_text())
    assert record["model"]["terms"] == ["Intercept", "Speed", "Density", "Layout", "Speed*Layout", "Speed^2"]
    assert record["diagnostics"]["p"] == 8
    assert 0 < record["diagnostics"]["d_efficiency_vs_bound"] <= 100 + 1e-6
    # The written public spec rebuilds the same plan.
    again = tmp_path / "again"
    assert design(again, "--spec", str(folder / "study.toml")) == 0
    assert (again / "plan.csv").read_text() == (folder / "plan.csv").read_text()


def test_the_folders_own_study_toml_is_used_when_no_preset_is_asked(tmp_path):
    (tmp_path / "study.toml").write_text(GENERIC_SPEC)
    assert design(tmp_path) == 0
    assert len(read_plan(tmp_path)) == 12


@pytest.mark.slow
def test_existing_plan_is_never_overwritten_without_force(tmp_path, capsys):
    assert design(tmp_path, "--seed", "1") == 0
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    capsys.readouterr()
    assert design(tmp_path, "--seed", "2") == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "--force" in err and err.count("\n") == 1
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


@pytest.mark.slow
def test_force_moves_the_old_plan_and_results_aside(tmp_path):
    assert design(tmp_path, "--seed", "1") == 0
    old_plan = (tmp_path / "plan.csv").read_text()
    (tmp_path / "outcomes.csv").write_text("run_code,status\nX,done\n")
    assert design(tmp_path, "--seed", "2", "--force") == 0
    moved = list((tmp_path / "superseded").iterdir())
    assert len(moved) == 1
    assert (moved[0] / "plan.csv").read_text() == old_plan
    assert (moved[0] / "outcomes.csv").read_text() == "run_code,status\nX,done\n"
    assert not (tmp_path / "outcomes.csv").exists()
    assert (tmp_path / "plan.csv").read_text() != old_plan


BAD_SPECS = {
    "unknown type": ('[[factors]]\nname = "A"\ntype = "ordinal"\nlevels = [1, 2]\n', "unknown factor type 'ordinal'"),
    "duplicate levels": ('[[factors]]\nname = "A"\ntype = "categorical"\nlevels = ["x", "x"]\n', "duplicate level 'x'"),
    "empty level": ('[[factors]]\nname = "A"\ntype = "categorical"\nlevels = ["x", " "]\n', "empty level name"),
    "no levels": ('[[factors]]\nname = "A"\ntype = "categorical"\nlevels = []\n', "needs at least 2 levels"),
    "non-numeric level": ('[[factors]]\nname = "A"\ntype = "discrete"\nlevels = [1, "two"]\n', "level 'two' is not a number"),
    "low above high": ('[[factors]]\nname = "A"\ntype = "continuous"\nlow = 3\nhigh = 1\n', "low (3.0) must be below high"),
}


@pytest.mark.parametrize("case", sorted(BAD_SPECS))
def test_bad_factor_specs_are_one_line_errors_and_write_nothing(tmp_path, capsys, case):
    factor, message = BAD_SPECS[case]
    spec = tmp_path / "bad.toml"
    spec.write_text('[study]\nruns = 6\n\n' + factor)
    folder = tmp_path / "study"
    assert design(folder, "--spec", str(spec)) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: bad.toml: factors[0] (A): ")
    assert message in err and err.count("\n") == 1
    assert not folder.exists()


def test_malformed_toml_names_the_line(tmp_path, capsys):
    spec = tmp_path / "bad.toml"
    spec.write_text('[study]\nruns = 6\n[[factors]]\nname = "A"\ntype = categorical\n')
    assert design(tmp_path / "s", "--spec", str(spec)) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: malformed bad.toml") and "line 5" in err


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--runs", "4"], "runs = 4 is too few: the model has p = 5 parameters, so it needs at least 5 runs"),
        (["--runs", "10", "--ab"], "needs at least 11 runs"),
        (["--model", "Pedestrians + Speed"], "unknown term 'Speed'"),
        (["--model", "Direction^2"], "needs a numeric factor with at least 3 levels"),
        (["--ab", "--model", "main + CrossingDistance"], "CrossingDistance, a fixed factor"),
        (["--model", "Pedestrians + + Direction"], "empty term"),
    ],
)
def test_bad_requests_are_one_line_errors_and_write_nothing(tmp_path, capsys, args, message):
    assert design(tmp_path, *args) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and message in err and err.count("\n") == 1
    assert list(tmp_path.iterdir()) == []


def test_console_command_help_and_usage_errors():
    help_text = subprocess.run([sys.executable, "-m", "trials.cli", "--help"], capture_output=True, text=True, check=True).stdout
    assert "design" in help_text
    bad = subprocess.run([sys.executable, "-m", "trials.cli", "design", "--runs", "many"], capture_output=True, text=True)
    assert bad.returncode == 2
    assert bad.stderr.startswith("error: argument --runs: expected a whole number from 1 to 1000, got 'many'") and bad.stderr.count("\n") == 1
    assert "Traceback" not in bad.stderr


def test_anticipated_coefficients_from_the_spec_reach_design_json(tmp_path):
    spec = tmp_path / "spec.toml"
    spec.write_text(GENERIC_SPEC + '\n[anticipated]\nLayout = 2.0\n"Speed*Layout" = 0.5\n')
    folder = tmp_path / "study"
    assert design(folder, "--spec", str(spec)) == 0
    power = json.loads((folder / "design.json").read_text())["diagnostics"]["power"]
    assert power["convention"].startswith("JMP's convention")
    assert power["anticipated"]["Layout[corridor]"] == 2.0 and power["anticipated"]["Layout[hall]"] == -2.0
    assert power["anticipated"]["Speed*Layout[hall]"] == -0.5 and power["anticipated"]["Speed"] == 1.0
    assert "[anticipated]" in (folder / "study.toml").read_text()


def test_anticipated_coefficient_of_an_unknown_term_is_an_error(tmp_path, capsys):
    spec = tmp_path / "spec.toml"
    spec.write_text(GENERIC_SPEC + "\n[anticipated]\nDensity2 = 2.0\n")
    assert design(tmp_path / "study", "--spec", str(spec)) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: [anticipated] in the spec: 'Density2' is not a term of the model") and err.count("\n") == 1
    assert not (tmp_path / "study").exists()


@pytest.mark.parametrize(("given", "expected"), [(None, "1"), ("4", "4")])
def test_numpy_blas_runs_one_thread_unless_the_user_sets_it(monkeypatch, capsys, given, expected):
    """Small matrices gain nothing from OpenBLAS threads (they cost the 27-run plan about 0.15 s of CPU); a user's setting wins."""
    if given is None:
        monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    else:
        monkeypatch.setenv("OPENBLAS_NUM_THREADS", given)
    assert main(["--help"]) == 0
    assert os.environ["OPENBLAS_NUM_THREADS"] == expected
