"""`trials power` end to end: bad input, the files it writes, seeds, resuming from power.csv, local
processes giving the same campaigns with 1 and 2 workers, and a blinded study's key left closed."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import pytest

from tests.support.run_studies import design_small_study
from trials.cli import main


def campaigns(out: Path) -> list[dict[str, str]]:
    with (out / "power.csv").open(newline="", encoding="utf-8") as handle:
        return sorted(csv.DictReader(handle), key=lambda r: (int(r["runs"]), int(r["campaign"])))


@pytest.fixture(scope="module")
def small(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("power") / "small"
    design_small_study(folder, blind=True)
    return folder


@pytest.mark.parametrize(("args", "message"), [
    (["--campaigns", "0"], "argument --campaigns: expected a whole number from 1"),
    (["--shares", "0.7"], "argument --shares: expected two shares"),
    (["--terms", "Speed"], "--terms: 'Speed' is not a term of the study's model"),
    (["--runs", "3"], "runs = 3 is too few"),
    (["--ray", "127.0.0.1:9", "--campaigns", "1"], "--ray 127.0.0.1:9: no Ray cluster answers there"),
    (["--ray", "nowhere", "--campaigns", "1"], "--ray: expected HOST:PORT"),
    (["--ray", "local"], "--ray runs closed-loop campaigns: give --campaigns K too"),
    (["--campaigns", "1", "--controllers", "NaviGAN-R"], "the study has 2 arms (A, B), got 1 controllers"),
])
def test_bad_input_is_one_line_and_exit_2_writing_nothing(small, tmp_path, capsys, args, message):
    out = tmp_path / "out"
    assert main(["power", "--study", str(small), "--out", str(out), "--simulations", "2", *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err
    assert not (out / "power.csv").exists() and not (out / "power.md").exists()


def test_no_plan_is_one_line(tmp_path, capsys):
    assert main(["power", "--study", str(tmp_path)]) == 2
    assert "no plan in" in capsys.readouterr().err


@pytest.mark.slow  # two model-based power runs of 12 simulations, about 10 s
def test_model_based_only_writes_json_md_and_figure_with_the_seed(small, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["power", "--study", str(small), "--out", str(out), "--simulations", "12", "--seed", str(2**53 - 1)]) == 0
    record = json.loads((out / "power.json").read_text())
    assert record["power_seed"] == 2**53 - 1 and record["model_based"]["simulations"] == 12
    (plan,) = record["plans"]
    assert plan["runs"] == 6 and set(plan["judgments"]) == {"Pedestrians", "Direction", "Controller"}
    assert all(e["total"] == 12 and e["low"] <= e["power"] <= e["high"] for e in plan["judgments"].values())
    assert (out / "power.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and not (out / "power.csv").exists()
    assert "Controller model-based" in capsys.readouterr().out
    # The same seed gives the same numbers.
    again = tmp_path / "again"
    assert main(["power", "--study", str(small), "--out", str(again), "--simulations", "12", "--seed", str(2**53 - 1)]) == 0
    assert json.loads((again / "power.json").read_text())["plans"] == record["plans"]


@pytest.mark.slow
def test_campaigns_resume_reproduce_and_never_open_the_sealed_key(small, tmp_path):
    study = tmp_path / "study"
    shutil.copytree(small, study)
    # Anything reading the sealed key would fail on this, and the key's bytes must stay as they are.
    key = study / "sealed" / "allocation.json"
    key.write_text("not a key")
    base = ["power", "--study", str(study), "--simulations", "5", "--seed", "12", "--campaigns", "4"]
    assert main([*base, "--workers", "2", "--out", str(tmp_path / "two")]) == 0
    two = campaigns(tmp_path / "two")
    assert [int(r["campaign"]) for r in two] == [0, 1, 2, 3]
    assert all(int(r["seed"]) < 2**53 and int(r["goal"]) + int(r["collision"]) + int(r["timeout"]) == 6 for r in two)
    assert {r["allocation"] for r in two} <= {"A=NaviGAN-R;B=Lattice", "A=Lattice;B=NaviGAN-R"}
    assert len({r["seed"] for r in two}) == 4
    assert key.read_text() == "not a key"
    # One worker, and a run interrupted after two campaigns and resumed, give the very same campaigns.
    one = tmp_path / "one"
    assert main([*base, "--workers", "1", "--out", str(one)]) == 0
    assert campaigns(one) == two
    lines = (one / "power.csv").read_text().splitlines()
    (one / "power.csv").write_text("\n".join(lines[:3]) + "\n")
    assert main([*base, "--out", str(one)]) == 0
    assert campaigns(one) == two
    record = json.loads((one / "power.json").read_text())
    assert record["closed_loop"]["campaigns"] == 4 and record["plans"][0]["campaigns"] == 4
    shares = record["plans"][0]["shares"]
    assert set(shares["2"]) == {"NaviGAN-R", "Lattice"}
    # A different seed is other settings: refused rather than mixed in, and nothing written is replaced.
    before = {p.name: p.read_bytes() for p in one.iterdir()}
    assert main([*base[:-4], "--seed", "13", "--campaigns", "4", "--out", str(one)]) == 2
    assert {p.name: p.read_bytes() for p in one.iterdir()} == before
