"""The shipped weights: complete, reproducible from their records, small, and better than constant velocity."""

from __future__ import annotations

from dataclasses import asdict

import pytest

from navigan import checkpoint as ckpt
from navigan.config import EvasionConfig
from navigan.data import SPLITS, Scenes, load_split
from navigan.evaluation import evaluate, evaluate_constant_velocity

MODELS = ("goal-social-lstm", "navil2", "navigan", "navigan-r")


pytestmark = pytest.mark.usefixtures("one_torch_thread")


def test_every_model_and_split_is_shipped_with_its_record():
    expected = {f"{m}-{s}.pt" for m in MODELS for s in SPLITS} | {"navigan-r-all.pt"}
    assert {p.name for p in ckpt.WEIGHTS_DIR.glob("*.pt")} == expected
    total = 0
    for name in sorted(expected):
        path = ckpt.WEIGHTS_DIR / name
        total += path.stat().st_size
        record = ckpt.load(path)
        model, split = record.model.model, record.split["name"]
        assert name == f"{model}-{split}.pt"
        assert record.finished in ("early stopping", "epoch limit") and record.state is None
        assert record.command.startswith(f"trials train --model {model} --split {split} ")
        assert f"--seed {record.train.seed}" in record.command
        assert record.split["train"] and record.split["val"]
        assert record.best["epoch"] <= record.epoch == len(record.history)
    assert total < 8 * 2**20


@pytest.mark.parametrize("split", SPLITS)
def test_each_split_navigan_r_holds_evasion_networks_and_how_they_were_trained(split):
    record = ckpt.load(ckpt.shipped("navigan-r", split))
    epochs = " --epochs 60" if split == "univ" else ""
    assert record.evasion["command"] == (f"trials train --recipe playback --split {split}{epochs} --evasion "
                                         f"--evasion-seed 0 --out navigan-r-{split}.pt")
    assert record.evasion["settings"] == asdict(EvasionConfig()) and record.evasion["resume"] is None
    assert [r["round"] for r in record.evasion["rounds"]] == [0, 1, 2]
    assert record.build_evasion() is not None
    assert ckpt.load(ckpt.shipped("navigan-r", "all")).evasion is None  # the trial controller's has none


@pytest.mark.parametrize("split", SPLITS)
@pytest.mark.slow
def test_shipped_navigan_r_beats_constant_velocity(split, eth_ucy_dir):
    test = Scenes.from_files(load_split(eth_ucy_dir, split).test)
    model = evaluate(ckpt.load(ckpt.shipped("navigan-r", split)).build_generator(), test, seed=0)
    baseline = evaluate_constant_velocity(test)
    assert model["ade"] < baseline["ade"]
    assert model["fde"] < baseline["fde"]
