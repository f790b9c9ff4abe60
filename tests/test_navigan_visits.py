"""Visited states: rows from the model's own walks through real scenes, and training on them."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from navigan import checkpoint as ckpt
from navigan.config import ModelConfig, TrainConfig
from navigan.data import T_OBS, T_PRED, Scenes, load_split
from navigan.errors import NaviganError
from navigan.playback.episodes import SceneGrid, episodes_of, load_episodes
from navigan.playback.rollout import neighbours
from navigan.training import train
from navigan.visits import pick, risky, visit_episodes, visited_rows, walked_tracks

WEIGHTS = ckpt.WEIGHTS_DIR / "navigan-r-zara1.pt"

pytestmark = pytest.mark.usefixtures("one_torch_thread")


@pytest.fixture(scope="module")
def zara1(eth_ucy_dir):
    return load_episodes(load_split(eth_ucy_dir, "zara1").test)


def test_a_walk_is_risky_only_within_d_safe_of_a_known_position():
    track = np.array([[[0.0, 0.0], [0.4, 0.0], [0.8, 0.0]]])
    around = np.full((1, 2, 3, 2), np.nan)
    around[0, 0, 2] = (0.8, 0.3)  # 0.3 m from the last step
    around[0, 1, :2] = (5.0, 5.0)  # far, then gone
    assert risky(track, around, 0.5, 3).tolist() == [True]
    assert risky(track, around, 0.3, 3).tolist() == [False]
    assert risky(track, np.full((1, 2, 3, 2), np.nan), 10.0, 3).tolist() == [False]


def test_a_pedestrian_starts_an_episode_every_so_many_frames():
    frames = 80
    positions = np.full((frames, 1, 2), np.nan, dtype=np.float32)
    positions[:, 0] = np.stack([np.arange(frames) * 0.4, np.zeros(frames)], axis=1)
    grid = SceneGrid("toy.txt", np.array([1]), positions)
    assert episodes_of([grid]).start.tolist() == [7]
    # windows of 44 frames start at 0..36; every 12 frames: 0, 12, 24, 36
    assert episodes_of([grid], every=12).start.tolist() == [7, 19, 31, 43]
    assert episodes_of([grid], every=12).steps.tolist() == [60, 60, 48, 36]


def test_neighbours_ahead_are_the_recorded_future_and_nan_past_the_end(zara1):
    active = np.arange(len(zara1))
    step = 5
    plain, ahead = neighbours(zara1, active, step), neighbours(zara1, active, step, ahead=T_PRED)
    np.testing.assert_array_equal(ahead[:, :, :T_OBS], plain)
    for e in active:
        positions = zara1.scenes[zara1.scene[e]].positions
        frame = zara1.start[e] + step
        for row in ahead[e]:
            if np.isnan(row[T_OBS - 1, 0]):
                continue
            column = int(np.flatnonzero(np.all(positions[frame] == row[T_OBS - 1], axis=1))[0])
            for k in range(1, T_PRED + 1):
                expected = positions[frame + k, column] if frame + k < len(positions) else np.full(2, np.nan)
                np.testing.assert_array_equal(row[T_OBS - 1 + k], expected)
    frames = len(zara1.scenes[0].positions)
    late = neighbours(zara1, active[:1], frames - 2 - zara1.start[0], ahead=3)  # last observed: the next-to-last frame
    assert late.shape[1] > 0 and not np.isnan(late[0, :, T_OBS]).all()
    assert np.isnan(late[0, :, T_OBS + 1 :]).all()


def test_visited_rows_are_the_walks_states(zara1):
    generator = ckpt.load(WEIGHTS).build_generator()
    d_safe, steps = 0.5, 4
    tracks = walked_tracks(generator, zara1, seed=0)
    rows = visited_rows(generator, zara1, 0, d_safe, steps, np.random.default_rng(1))
    assert rows is not None and rows.targets[:, 0].all() and rows.targets.sum() == len(rows.goals)
    count = len(rows.goals)
    windows = np.lib.stride_tricks.sliding_window_view(tracks, T_OBS, axis=1).transpose(0, 1, 3, 2)
    future, known = (x.numpy() for x in rows.neighbours())
    found_risky = 0
    for r in range(count):  # every row's walker history is a window of some walk, its goal that walk's goal
        gap = np.abs(windows - rows.obs[r, 0].numpy()).max(axis=(2, 3))
        hits = np.argwhere(gap < 1e-6)
        assert len(hits), f"row {r} is no state of any walk"
        e, s = hits[0]
        np.testing.assert_allclose(rows.goals[r].numpy(), zara1.goal[e])
        ahead = tracks[e, s + T_OBS : s + T_OBS + steps]
        distance = np.linalg.norm(future[r, :, : len(ahead)] - ahead[None], axis=-1)
        usable = known[r, :, : len(ahead)] & ~np.isnan(distance)
        found_risky += bool(np.where(usable, distance, np.inf).min() < d_safe)
    assert found_risky * 2 == count  # the risky states and as many calm ones
    some = pick(rows, np.array([0, count - 1]))
    assert some.obs.shape[1] == int(rows.mask[[0, count - 1]].sum(dim=1).max())
    np.testing.assert_array_equal(some.goals.numpy(), rows.goals[[0, count - 1]].numpy())


def test_training_on_visited_states(eth_ucy_dir, tmp_path):
    files = [eth_ucy_dir / "train" / "crowds_zara01_train.txt"]
    visits = visit_episodes(files)
    assert len(visits) > len(episodes_of(visits.scenes))  # more than one start per pedestrian
    train_scenes = Scenes.from_files(files).subset(range(0, 400, 8))
    val_scenes = Scenes.from_files([eth_ucy_dir / "val" / "crowds_zara01_val.txt"]).subset(range(0, 110, 4))
    split = load_split(eth_ucy_dir, "zara2").describe()
    model = ModelConfig("navigan-r", pair_pool=True)
    config = TrainConfig("zara2", epochs=1, batch=64, augment=True, on_policy=0.5, resist_steps=4)
    with pytest.raises(NaviganError, match="needs the training scenes' episodes"):
        train(model, config, train_scenes, val_scenes, split, tmp_path / "a.pt", progress=False)
    assert not (tmp_path / "a.pt").exists()
    record = train(model, config, train_scenes, val_scenes, split, tmp_path / "a.pt", progress=False,
                   visits=visits.subset(range(0, len(visits), 4)))
    losses = record.history[0]["train"]
    assert losses["visited_l2"] > 0 and losses["visited_resistance"] > 0
    again = train(model, config, train_scenes, val_scenes, split, tmp_path / "b.pt", progress=False,
                  visits=visits.subset(range(0, len(visits), 4)))
    for name, value in record.generator.items():
        torch.testing.assert_close(again.generator[name], value)
