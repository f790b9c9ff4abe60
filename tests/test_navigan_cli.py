"""`trials train` and `trials evaluate` on a small copy of real ETH/UCY recordings."""

from __future__ import annotations

import json
from dataclasses import fields
from pathlib import Path

import pytest
import torch

from navigan.checkpoint import load
from navigan.config import ClosedLoopConfig, TrainConfig
from trials.cli import main

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


def recipe_file(folder: Path, text: str) -> Path:
    """A user's recipe file holding `text`."""
    path = folder / "mine.toml"
    path.write_text(text)
    return path


@pytest.mark.slow
def test_train_then_resume_then_evaluate(data, tmp_path, capsys):
    out = tmp_path / "m.pt"
    mine = recipe_file(tmp_path, 'model = "navil2"\n[train]\nbatch = 64\n')
    args = ["train", "--recipe", str(mine), "--split", "zara2", "--epochs", "2", "--data", str(data),
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


@pytest.mark.slow  # over 1.5 s: left out of the quick loop
def test_checkpoint_records_the_recipe_and_the_command_that_reproduce_it(data, tmp_path):
    out = tmp_path / "m.pt"
    mine = recipe_file(tmp_path, 'model = "goal-social-lstm"\n[network]\nhidden = 16\n[train]\nbatch = 48\n')
    assert main(["train", "--recipe", str(mine), "--split", "zara2", "--epochs", "1", "--patience", "3",
                 "--seed", "4", "--data", str(data), "--out", str(out), "--quiet"]) == 0
    record = load(out)
    assert record.command == f"trials train --recipe {mine} --split zara2 --epochs 1 --patience 3 --seed 4 --out m.pt"
    assert record.recipe == {"name": str(mine), "file": str(mine), "text": mine.read_text()}
    assert record.model.hidden == 16 and record.train.batch == 48 and record.train.patience == 3
    assert record.train.seed == 4 and record.train.epochs == 1


def test_train_without_out_writes_into_the_study_folder_with_a_line_per_epoch(data, tmp_path, capsys):
    study = tmp_path / "study"
    study.mkdir()
    mine = recipe_file(tmp_path, 'model = "goal-social-lstm"\n[network]\nhidden = 16\n[train]\nbatch = 48\n')
    assert main(["train", "--recipe", str(mine), "--split", "zara2", "--epochs", "1", "--data", str(data),
                 "--study", str(study)]) == 0
    first, last = capsys.readouterr().out.splitlines()  # piped: one numbered line per epoch, no bar
    assert first.startswith("[1/1] epoch 1: validation loss ") and "best epoch 1" in first
    assert last.startswith(f"{study / 'goal-social-lstm-zara2.pt'}: ")
    assert load(study / "goal-social-lstm-zara2.pt").train.epochs == 1


def test_recipe_sets_the_social_training_settings(data, tmp_path):
    out = tmp_path / "r.pt"
    mine = recipe_file(tmp_path, '''model = "navigan-r"
[network]
pair_pool = true
[train]
batch = 64
augment = true
w_resistance = 5
d_safe = 0.9
resist_intention = false
resist_beyond_truth = true
resist_steps = 4
encounters = 0.5
encounter_crowd = 0.25
''')
    assert main(["train", "--recipe", str(mine), "--split", "zara2", "--epochs", "1", "--data", str(data),
                 "--out", str(out), "--quiet"]) == 0
    record = load(out)
    train = record.train
    assert (train.augment, train.w_resistance, train.d_safe, train.resist_steps) == (True, 5.0, 0.9, 4)
    assert not train.resist_intention and train.resist_beyond_truth and train.encounters == 0.5
    assert train.encounter_crowd == 0.25 and record.model.pair_pool
    assert {"encounter_l2", "encounter_resistance"} <= set(record.history[0]["train"])


def test_rerun_refuses_a_recipe_with_other_settings(data, tmp_path, capsys):
    out = tmp_path / "m.pt"
    mine = recipe_file(tmp_path, 'model = "navil2"\n[train]\nepochs = 1\nbatch = 64\n')
    args = ["train", "--recipe", str(mine), "--split", "zara2", "--data", str(data), "--out", str(out), "--quiet"]
    assert main(args) == 0
    before = out.read_bytes()
    mine.write_text('model = "navil2"\n[train]\nepochs = 1\nbatch = 64\nlr = 0.01\n')
    assert main(args) == 2
    assert "m.pt holds another training" in capsys.readouterr().err
    mine.write_text('model = "navil2"\n[train]\nepochs = 3\nbatch = 64\n')  # only a limit: the same training
    assert main(args) == 0
    assert out.read_bytes() == before


SETTINGS = ", ".join(f.name for f in fields(TrainConfig) if f.name != "split")
TUNING = ", ".join(f.name for f in fields(ClosedLoopConfig))


@pytest.mark.parametrize(("text", "message"), [
    ('model = "navigan-r"\n[train]\nbatchsize = 64', f"unknown key train.batchsize: expected one of {SETTINGS}"),
    ('model = "navigan-r"\nsplit = "eth"', "unknown key split: expected one of model, network, train, closed_loop, evasion"),
    ('model = "navigan-r"\n[closed_loop]\nrounds = 0', "closed_loop.rounds: expected a positive whole number, got 0"),
    ('model = "navigan-r"\n[closed_loop]\nmargin = -0.5', "closed_loop.margin: expected a positive distance in metres, got -0.5"),
    ('model = "navigan-r"\n[closed_loop]\nshield = 0.5', f"unknown key closed_loop.shield: expected one of {TUNING}"),
    ('model = "navigan-r"\n[evasion]\nwidth = 0', "evasion.width: expected a positive whole number, got 0"),
    ('model = "navigan-r"\n[evasion]\nshortfall_batches = 2.5', "evasion.shortfall_batches: expected a positive whole number, got 2.5"),
    ('[train]\nepochs = 3', "model: expected one of goal-social-lstm, navil2, navigan, navigan-r, got nothing"),
    ('model = "navigan-x"', 'model: expected one of goal-social-lstm, navil2, navigan, navigan-r, got "navigan-x"'),
    ('model = "navigan-r"\ntrain = 3', "train: expected a table of TrainConfig settings, got 3"),
    ('model = "navigan-r"\n[train]\nbatch = "256"', 'train.batch: expected a positive whole number, got "256"'),
    ('model = "navigan-r"\n[train]\naugment = 1', "train.augment: expected true or false, got 1"),
    ('model = "navigan-r"\n[train]\nencounters = -1', "train.encounters: expected a number >= 0, got -1"),
    ('model = "navigan-r"\n[train]\nd_safe = 0', "train.d_safe: expected a positive distance in metres, got 0"),
    ('model = "navigan-r"\n[train]\nencounter_crowd = 1.5', "train.encounter_crowd: expected a fraction in [0, 1], got 1.5"),
    ('model = "navigan-r"\n[train]\nresist_steps = 13',
     "train.resist_steps: expected a whole number of way-points from 1 to 12, got 13"),
    ('model = "navigan-r"\n[train]\nforce_size = -1.0', "train.force_size: expected a number >= 0, got -1.0"),
    ('model = "navigan-r"\n[network]\nhidden = 0', "network.hidden: expected a positive whole number, got 0"),
    ('model = "navigan-r"\nepochs 3', "not valid TOML: Expected '=' after a key in a key/value pair (at line 2, column 8)"),
])
def test_bad_recipe_is_one_error_line(data, tmp_path, capsys, text, message):
    mine = recipe_file(tmp_path, text)
    assert main(["train", "--recipe", str(mine), "--split", "zara2", "--data", str(data),
                 "--out", str(tmp_path / "r.pt"), "--quiet"]) == 2
    assert capsys.readouterr().err == f"error: {mine}: {message}\n"
    assert not (tmp_path / "r.pt").exists()


@pytest.mark.parametrize(("extra", "message"), [
    (["--closed-loop-seed", "1"], "--closed-loop-seed: only with --closed-loop"),
    (["--closed-loop", "--split", "all"], "--closed-loop: needs a split with a held-out test scene, not all"),
    (["--closed-loop", "--recipe", "navigan"], "--closed-loop: tunes NaviGAN-R only; recipe navigan trains navigan"),
    (["--closed-loop", "--device", "cuda"],
     "--closed-loop: tunes on the CPU only; train with --device cuda first, then add --closed-loop without it"),
    (["--evasion-seed", "1"], "--evasion-seed: only with --evasion"),
    (["--retrain-evasion"], "--retrain-evasion: only with --evasion"),
    (["--evasion", "--recipe", "navigan"],
     "--evasion: trains NaviGAN-R's evasion networks only; recipe navigan trains navigan"),
    (["--evasion", "--device", "cuda"],
     "--evasion: trains on the CPU only; train with --device cuda first, then add --evasion without it"),
])
def test_closed_loop_refusals_are_one_error_line(tmp_path, capsys, extra, message):
    args = ["train", "--recipe", "playback", "--split", "zara1", *extra, "--out", str(tmp_path / "r.pt"), "--quiet"]
    assert main(args) == 2
    assert capsys.readouterr().err == f"error: {message}\n"
    assert not (tmp_path / "r.pt").exists()


@pytest.mark.slow
def test_train_then_tune_in_closed_loop_interrupted_then_resumed(data, tmp_path, capsys, monkeypatch):
    from navigan import closed_loop

    mine = recipe_file(tmp_path, 'model = "navigan-r"\n[network]\npair_pool = true\n[train]\nbatch = 64\n'
                                 '[closed_loop]\nrounds = 2\nepochs = 1\nbatch = 64\n')

    def tuning(out: Path) -> list[str]:
        return ["train", "--recipe", str(mine), "--split", "zara2", "--epochs", "1", "--data", str(data),
                "--out", str(out), "--closed-loop", "--closed-loop-seed", "3"]

    whole = tmp_path / "whole.pt"
    assert main(tuning(whole)) == 0
    printed = capsys.readouterr().out
    first, second = load(whole).closed_loop["rounds"]
    assert f"closed-loop round 1/2: walked {first['states']} states, trained on {first['states']}, " in printed
    assert (f"closed-loop round 2/2: walked {second['states']} states, "
            f"trained on {first['states'] + second['states']}, ") in printed
    assert "tuned in closed loop over 2 rounds" in printed and first["states"] > 100
    before = whole.read_bytes()
    assert main(tuning(whole)) == 0  # tuned: nothing more to do, nothing rewritten
    assert whole.read_bytes() == before

    # Ctrl-C during round 2's training: round 1 is kept, and the same command finishes the tuning
    rounds = closed_loop.train_round
    trained: list[int] = []

    def stopped_in_round_two(generator, parts, config, rng):
        trained.append(len(parts))
        if len(trained) == 2:
            raise KeyboardInterrupt
        return rounds(generator, parts, config, rng)

    monkeypatch.setattr(closed_loop, "train_round", stopped_in_round_two)
    out = tmp_path / "r.pt"
    assert main(tuning(out)) == 130
    kept = load(out).closed_loop
    assert [r["round"] for r in kept["rounds"]] == [1] and kept["resume"] is not None
    monkeypatch.setattr(closed_loop, "train_round", rounds)
    assert main(tuning(out)) == 0
    resumed, uninterrupted = load(out), load(whole)
    assert resumed.closed_loop["resume"] is None and [r["states"] for r in resumed.closed_loop["rounds"]] == [
        first["states"], second["states"]]
    assert resumed.command.endswith("--closed-loop --closed-loop-seed 3 --out r.pt")
    assert all(torch.equal(resumed.generator[k], uninterrupted.generator[k]) for k in uninterrupted.generator)


@pytest.mark.slow
def test_train_then_add_evasion_networks_interrupted_then_resumed(data, tmp_path, capsys, monkeypatch):
    from navigan import evasion_training

    mine = recipe_file(tmp_path, 'model = "navigan-r"\n[network]\npair_pool = true\n[train]\nbatch = 64\n'
                                 '[evasion]\nrounds = 1\nepochs = 1\nbatch = 64\nwidth = 16\nshortfall_batches = 3\n')

    def training(out: Path) -> list[str]:
        return ["train", "--recipe", str(mine), "--split", "zara2", "--epochs", "1", "--data", str(data),
                "--out", str(out), "--evasion", "--evasion-seed", "4"]

    whole = tmp_path / "whole.pt"
    assert main(training(whole)) == 0
    printed = capsys.readouterr().out
    first, second = load(whole).evasion["rounds"]
    assert (f"evasion walk 0/1: walked {first['states']} states ({first['planned_short']:.3f} of the planned steps "
            f"short), head trained on {first['states']}") in printed
    assert f"head trained on {first['states'] + second['states']}" in printed
    assert "evasion networks trained over 2 walks" in printed and first["states"] > 100
    before, before_weights = whole.read_bytes(), load(whole).evasion["weights"]
    assert main(training(whole)) == 0  # trained: nothing more to do, nothing rewritten
    assert whole.read_bytes() == before
    other_seed = [*training(whole)[:-1], "5"]
    assert main(other_seed) == 2 and "evasion networks trained with other settings" in capsys.readouterr().err
    assert whole.read_bytes() == before
    assert main([*other_seed, "--retrain-evasion"]) == 0  # the networks replaced by seed 5's
    retrained = load(whole)
    assert retrained.evasion["settings"]["seed"] == 5 and retrained.evasion["command"].endswith(
        "--evasion --evasion-seed 5 --retrain-evasion --out whole.pt")
    assert retrained.command.endswith("--evasion --evasion-seed 4 --out whole.pt")  # the generator's: it trained it
    capsys.readouterr()

    # Ctrl-C during the second head's training: the first walk is kept, and the same command finishes
    fit = evasion_training.fit_head
    fitted: list[int] = []

    def stopped_in_the_second_fit(states, config, rng, seed):
        fitted.append(len(states))
        if len(fitted) == 2:
            raise KeyboardInterrupt
        return fit(states, config, rng, seed)

    monkeypatch.setattr(evasion_training, "fit_head", stopped_in_the_second_fit)
    out = tmp_path / "r.pt"
    assert main(training(out)) == 130
    kept = load(out).evasion
    assert [r["round"] for r in kept["rounds"]] == [0] and kept["weights"] is None
    monkeypatch.setattr(evasion_training, "fit_head", fit)
    assert main(training(out)) == 0
    resumed = load(out)
    assert resumed.evasion["command"].endswith("--evasion --evasion-seed 4 --out r.pt")
    assert all(torch.equal(resumed.evasion["weights"][k], v) for k, v in before_weights.items())  # seed 4's, whole


def test_unknown_recipe_lists_the_shipped_ones(capsys):
    assert main(["train", "--recipe", "fast", "--split", "eth"]) == 2
    assert capsys.readouterr().err == (
        "error: unknown recipe 'fast': shipped recipes are goal-social-lstm, navigan, navil2, paper, playback, robot "
        "(or give a .toml file)\n"
    )
    assert main(["train", "--recipe", "missing.toml", "--split", "eth"]) == 2
    assert capsys.readouterr().err == "error: no recipe file missing.toml\n"


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
    code = main(["train", "--recipe", "navil2", "--split", "zara2", "--epochs", "1", "--data", str(data),
                 "--out", str(tmp_path / "m.pt"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2
    assert err == ('error: malformed line 601 of crowds_zara01_train.txt: expected 4 numbers "frame ped x y", '
                   "got 3 fields\n")
    assert not (tmp_path / "m.pt").exists()


def test_missing_data_and_bad_values(monkeypatch, tmp_path, capsys):
    assert main(["train", "--recipe", "navil2", "--split", "eth", "--data", str(tmp_path),
                 "--out", str(tmp_path / "m.pt")]) == 2
    assert f"{tmp_path} is not an ETH/UCY data folder: it has no splits.json" in capsys.readouterr().err
    assert main(["train", "--recipe", "navil2", "--split", "eth", "--epochs", "0"]) == 2
    assert "--epochs: expected a positive whole number, got 0" in capsys.readouterr().err
    assert main(["evaluate", "--baseline", "constant-velocity"]) == 2
    assert "--baseline needs --split" in capsys.readouterr().err
