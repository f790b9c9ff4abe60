"""Short training runs on real ETH/UCY data: learning, early stopping, checkpoints and resuming."""

from __future__ import annotations

from dataclasses import replace

import pytest
import torch

from navigan import checkpoint as ckpt
from navigan.config import ModelConfig, TrainConfig
from navigan.data import Scenes, load_split
from navigan.errors import NaviganError
from navigan.evaluation import evaluate
from navigan.training import Networks, train

pytestmark = pytest.mark.usefixtures("one_torch_thread")


@pytest.fixture(scope="module")
def small(eth_ucy_dir):
    """About 300 training and 150 validation targets of the zara2 split, with their split record."""
    split = load_split(eth_ucy_dir, "zara2")
    train_scenes = Scenes.from_files([eth_ucy_dir / "train" / "crowds_zara01_train.txt"]).subset(range(0, 400, 4))
    val_scenes = Scenes.from_files([eth_ucy_dir / "val" / "crowds_zara01_val.txt"]).subset(range(0, 110, 2))
    return train_scenes, val_scenes, split.describe()


@pytest.mark.slow
def test_short_training_lowers_the_validation_loss(small, tmp_path):
    train_scenes, val_scenes, split = small
    model, config = ModelConfig("navigan-r"), TrainConfig("zara2", epochs=3, batch=32, seed=0)
    before = evaluate(Networks.build(model, config, torch.device("cpu")).generator, val_scenes, seed=0, train=config)
    record = train(model, config, train_scenes, val_scenes, split, tmp_path / "m.pt", progress=False)
    after = record.best["val"]
    assert after["loss"] < 0.5 * before["loss"]
    assert after["ade"] < before["ade"]
    assert record.finished == "epoch limit" and record.epoch == 3
    assert {"l2", "fde", "resistance", "adversarial", "d"} <= set(record.history[0]["train"])


class Interrupt(Exception):
    """Stands for Ctrl-C arriving after an epoch's checkpoint was saved."""


def interrupt_after(epochs: int):
    def on_epoch(record: ckpt.Checkpoint) -> None:
        if record.epoch == epochs:
            raise Interrupt

    return on_epoch


@pytest.mark.slow
def test_interrupted_training_resumes_to_the_same_weights(small, tmp_path):
    train_scenes, val_scenes, split = small
    model, config = ModelConfig("navigan"), TrainConfig("zara2", epochs=2, batch=64, seed=3)
    straight = train(model, config, train_scenes, val_scenes, split, tmp_path / "a.pt", progress=False)
    with pytest.raises(Interrupt):
        train(model, replace(config, epochs=5), train_scenes, val_scenes, split, tmp_path / "b.pt", progress=False,
              on_epoch=interrupt_after(1), command="five epochs", recipe={"name": "five"})
    partial = ckpt.load(tmp_path / "b.pt")
    assert partial.epoch == 1 and partial.finished is None and partial.state is not None
    resumed = train(model, config, train_scenes, val_scenes, split, tmp_path / "b.pt", progress=False,
                    command="two epochs", recipe={"name": "two"})  # a new limit: what finished it is recorded
    assert resumed.epoch == 2 and [h["epoch"] for h in resumed.history] == [1, 2]
    assert resumed.command == "two epochs" and ckpt.load(tmp_path / "b.pt").command == "two epochs"
    assert ckpt.load(tmp_path / "b.pt").recipe == {"name": "two"}
    assert resumed.finished == "epoch limit" and resumed.state is None
    for name, value in straight.generator.items():
        torch.testing.assert_close(resumed.generator[name], value)
    assert resumed.history[1]["val"] == straight.history[1]["val"]


@pytest.mark.slow
def test_early_stopping_keeps_the_best_epoch(small, tmp_path):
    train_scenes, val_scenes, split = small
    config = TrainConfig("zara2", epochs=10, patience=2, batch=64, lr=0.0)  # nothing changes: no improvement
    record = train(ModelConfig("navil2"), config, train_scenes, val_scenes, split, tmp_path / "m.pt", progress=False)
    assert record.finished == "early stopping"
    assert record.epoch == 3 and record.best["epoch"] == 1


def test_checkpoint_loads_and_reproduces_its_metrics(small, tmp_path):
    train_scenes, val_scenes, split = small
    config = TrainConfig("zara2", epochs=1, batch=64, seed=5)
    record = train(ModelConfig("goal-social-lstm"), config, train_scenes, val_scenes, split, tmp_path / "m.pt",
                   command="trials train --model goal-social-lstm", progress=False)
    loaded = ckpt.load(tmp_path / "m.pt")
    assert loaded.command == "trials train --model goal-social-lstm"
    assert loaded.train.seed == 5 and loaded.split["name"] == "zara2" and loaded.state is None
    assert loaded.data["train"]["targets"] == train_scenes.n_targets
    metrics = evaluate(loaded.build_generator(), val_scenes, seed=5, train=config)
    assert metrics == pytest.approx(record.best["val"])


def test_other_training_is_not_overwritten(small, tmp_path):
    train_scenes, val_scenes, split = small
    out = tmp_path / "m.pt"
    train(ModelConfig("navil2"), TrainConfig("zara2", epochs=1, batch=64), train_scenes, val_scenes, split, out,
          progress=False)
    before = out.read_bytes()
    with pytest.raises(NaviganError, match="holds another training"):
        train(ModelConfig("navil2"), TrainConfig("zara2", epochs=1, batch=64, seed=9), train_scenes, val_scenes,
              split, out, progress=False)
    assert out.read_bytes() == before


def test_unreadable_checkpoint_is_a_clear_error(tmp_path):
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"not a checkpoint")
    with pytest.raises(NaviganError, match="bad.pt is not a readable checkpoint"):
        ckpt.load(bad)
    with pytest.raises(NaviganError, match="no checkpoint at"):
        ckpt.load(tmp_path / "missing.pt")


def test_retired_settings_load_only_at_the_value_training_keeps(tmp_path):
    record = torch.load(ckpt.shipped("navil2", "zara2"), weights_only=True)
    assert ckpt.load(ckpt.shipped("navil2", "zara2")).train.batch == 256  # records goal_first = goal_last = 12
    record["train"]["goal_last"] = 36
    torch.save(record, tmp_path / "old.pt")
    with pytest.raises(NaviganError, match="old.pt was trained with goal_last = 36, a setting training no longer has"):
        ckpt.load(tmp_path / "old.pt")
