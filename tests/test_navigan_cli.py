"""`trials train` and `trials evaluate` on a small copy of real ETH/UCY recordings."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from navigan import config
from navigan.checkpoint import load
from trials.cli import main
from trials.commands import train as train_command

pytestmark = pytest.mark.usefixtures("one_torch_thread")


@pytest.fixture
def data(eth_ucy_dir, tmp_path) -> Path:
    """A data folder with one split, `zara2`, over the first lines of three real recordings."""
    root = tmp_path / "data"
    parts = {"train": "train/crowds_zara01_train.txt", "val": "val/crowds_zara01_val.txt",
             "test": "all_data/crowds_zara02.txt"}
    for name in parts.values():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        lines = (eth_ucy_dir / name).read_text().splitlines(keepends=True)
        (root / name).write_text("".join(lines[:600]))
    (root / "splits.json").write_text(json.dumps({"zara2": {k: [v] for k, v in parts.items()}}))
    return root


@pytest.mark.slow
def test_train_then_resume_then_evaluate(data, tmp_path, capsys):
    out = tmp_path / "m.pt"
    args = ["train", "--model", "navil2", "--split", "zara2", "--epochs", "2", "--batch", "64", "--data", str(data),
            "--out", str(out), "--quiet"]
    assert main(args) == 0
    assert "epoch limit after 2 epochs" in capsys.readouterr().out
    before = out.read_bytes()
    assert main(args) == 0  # finished: nothing more to do, nothing rewritten
    assert out.read_bytes() == before
    assert main(["evaluate", "--checkpoint", str(out), "--data", str(data), "--json", str(tmp_path / "e.json")]) == 0
    printed = capsys.readouterr().out
    assert "NaviL2 " in printed and "NaviL2†" in printed
    record = json.loads((tmp_path / "e.json").read_text())
    assert record["split"] == "zara2" and record["test_files"] == ["all_data/crowds_zara02.txt"]
    assert record["model"] == "navil2" and record["epochs"] == 2 and record["targets"] > 0
    assert 0 < record["full"]["ade"] < 5 and 0 < record["dagger"]["fde"] < 5


def test_recorded_command_reproduces_the_settings(data, tmp_path):
    out = tmp_path / "m.pt"
    assert main(["train", "--model", "goal-social-lstm", "--split", "zara2", "--epochs", "1", "--patience", "3",
                 "--hidden", "16", "--batch", "48", "--seed", "4", "--data", str(data), "--out", str(out),
                 "--quiet"]) == 0
    record = load(out)
    assert record.command == (
        "trials train --model goal-social-lstm --split zara2 --epochs 1 --patience 3 --hidden 16 --batch 48 "
        "--lr 0.001 --seed 4 --out m.pt"
    )
    assert record.model.hidden == 16 and record.train.batch == 48 and record.train.patience == 3


def test_recorded_command_keeps_the_social_training_options(data, tmp_path):
    out = tmp_path / "r.pt"
    assert main(["train", "--model", "navigan-r", "--split", "zara2", "--epochs", "1", "--batch", "64",
                 "--goal-steps", "8-36", "--augment", "--w-resistance", "5", "--d-safe", "0.9", "--resist-forces-only",
                 "--resist-beyond-truth", "--resist-steps", "4", "--encounters", "0.5", "--encounter-crowd", "0.25",
                 "--pair-pool", "--data", str(data), "--out", str(out), "--quiet"]) == 0
    record = load(out)
    assert record.command == (
        "trials train --model navigan-r --split zara2 --epochs 1 --pair-pool --batch 64 --lr 0.001 --seed 0 "
        "--goal-steps 8-36 --augment --w-resistance 5 --d-safe 0.9 --resist-forces-only --resist-beyond-truth "
        "--resist-steps 4 --encounters 0.5 --encounter-crowd 0.25 --out r.pt"
    )
    train = record.train
    settings = (train.goal_first, train.goal_last, train.augment, train.w_resistance, train.d_safe, train.resist_steps)
    assert settings == (8, 36, True, 5.0, 0.9, 4)
    assert not train.resist_intention and train.resist_beyond_truth and train.encounters == 0.5
    assert train.encounter_crowd == 0.25 and record.model.pair_pool
    assert {"encounter_l2", "encounter_resistance"} <= set(record.history[0]["train"])


@pytest.mark.parametrize(("option", "value", "message"), [
    ("--goal-steps", "far", "--goal-steps: expected FIRST or FIRST-LAST whole numbers of steps, got 'far'"),
    ("--goal-steps", "20-10", "goal steps 20-10: expected 1 <= first <= last <= 36"),
    ("--encounters", "-1", "--encounters: expected a number >= 0, got -1.0"),
    ("--d-safe", "0", "--d-safe: expected a positive distance in metres, got 0.0"),
    ("--encounter-crowd", "1.5", "--encounter-crowd: expected a fraction in [0, 1], got 1.5"),
    ("--resist-steps", "0", "--resist-steps: expected a positive whole number, got 0"),
    ("--resist-steps", "13", "resistance steps 13: expected 1 to 12, the plan's way-points"),
    ("--force-size", "-1", "--force-size: expected a number >= 0, got -1.0"),
])
def test_bad_social_training_options(data, tmp_path, capsys, option, value, message):
    assert main(["train", "--model", "navigan-r", "--split", "zara2", option, value, "--data", str(data),
                 "--out", str(tmp_path / "r.pt"), "--quiet"]) == 2
    assert capsys.readouterr().err == f"error: {message}\n"
    assert not (tmp_path / "r.pt").exists()


def test_constant_velocity_baseline(data, tmp_path, capsys):
    out = tmp_path / "cv.json"
    assert main(["evaluate", "--baseline", "constant-velocity", "--split", "zara2", "--data", str(data),
                 "--json", str(out)]) == 0
    record = json.loads(out.read_text())
    assert record["baseline"] == "constant-velocity" and "dagger" not in record
    assert 0.1 < record["full"]["ade"] < record["full"]["fde"]


def test_malformed_data_is_one_error_line(data, tmp_path, capsys):
    with (data / "train" / "crowds_zara01_train.txt").open("a") as f:
        f.write("9990\t1.0\t2.0\n")
    code = main(["train", "--model", "navil2", "--split", "zara2", "--epochs", "1", "--data", str(data),
                 "--out", str(tmp_path / "m.pt"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2
    assert err == ('error: malformed line 601 of crowds_zara01_train.txt: expected 4 numbers "frame ped x y", '
                   "got 3 fields\n")
    assert not (tmp_path / "m.pt").exists()


def test_missing_data_and_bad_values(monkeypatch, tmp_path, capsys):
    assert main(["train", "--model", "navil2", "--split", "eth", "--data", str(tmp_path),
                 "--out", str(tmp_path / "m.pt")]) == 2
    assert f"{tmp_path} is not an ETH/UCY data folder: it has no splits.json" in capsys.readouterr().err
    assert main(["train", "--model", "navil2", "--split", "eth", "--epochs", "0"]) == 2
    assert "--epochs: expected a positive whole number, got 0" in capsys.readouterr().err
    assert main(["evaluate", "--baseline", "constant-velocity"]) == 2
    assert "--baseline needs --split" in capsys.readouterr().err


def test_command_lists_every_model():
    assert train_command.MODELS == tuple(config.MODELS)
