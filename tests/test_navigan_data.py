"""ETH/UCY reading, windows and whole-scene batches."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from navigan.data import FAR_STEPS, SEQ_LEN, Sampling, Scenes, load_split, read_recording, recording_windows
from navigan.errors import NaviganError
from robot_logs.physical import T_OBS


def write(tmp_path: Path, text: str, name: str = "scene.txt") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def walkers(frames: range, peds: dict[int, range]) -> str:
    """Tab-separated rows: pedestrian p walks along x one metre per frame over its frames."""
    return "".join(
        f"{f}\t{p}\t{float(f) / 10:.1f}\t{float(p)}\n" for f in frames for p, span in peds.items() if f in span
    )


def test_malformed_line_names_file_and_line(tmp_path):
    path = write(tmp_path, "10\t1\t1.0\t2.0\n20\t1\t1.5\n")
    with pytest.raises(NaviganError, match=r'malformed line 2 of scene.txt: expected 4 numbers "frame ped x y"'):
        read_recording(path)


def test_non_number_is_an_error_with_its_line(tmp_path):
    path = write(tmp_path, "10 1 1.0 2.0\n\n20 1 abc 2.0\n")
    with pytest.raises(NaviganError, match="malformed line 3 of scene.txt"):
        read_recording(path)


def test_duplicate_pedestrian_in_frame_is_an_error(tmp_path):
    path = write(tmp_path, "10 1 1.0 2.0\n10 1 1.1 2.0\n")
    with pytest.raises(NaviganError, match="line 2 of scene.txt: pedestrian 1 appears twice in frame 10"):
        read_recording(path)


def test_nan_and_missing_rows_are_skipped_and_counted(tmp_path):
    path = write(tmp_path, "10\t1\t1.0\t2.0\n20\t1\tnan\t2.0\n30\t1\t\t2.0\n40 1 NaN 3\n50\t1\t2.0\t2.0\n")
    recording = read_recording(path)
    assert recording.skipped == 3
    assert recording.frames.tolist() == [10, 50]
    np.testing.assert_allclose(recording.xy, [[1.0, 2.0], [2.0, 2.0]])


def test_windows_hold_targets_then_the_agents_present_at_the_last_observed_frame(tmp_path):
    # ped 1 spans frames 0..240 (25 frames), ped 2 frames 0..190 (20), ped 3 only 10 frames (50..140).
    text = walkers(range(0, 250, 10), {1: range(0, 250), 2: range(0, 200), 3: range(50, 150)})
    windows = recording_windows(read_recording(write(tmp_path, text)))
    assert len(windows) == 6  # starts at frames 0..50 for ped 1
    assert [w.targets for w in windows] == [2, 1, 1, 1, 1, 1]
    assert [len(w.positions) for w in windows] == [3, 3, 3, 3, 3, 3]  # ped 3 (and 2) seen at frame start + 7
    assert windows[0].positions.shape == (3, T_OBS + FAR_STEPS, 2)
    np.testing.assert_allclose(windows[1].positions[0, :SEQ_LEN, 0], np.arange(1, 21))
    # ped 1's track goes on past the window until the recording ends (frame 240), then NaN
    np.testing.assert_allclose(windows[5].positions[0, :20, 0], np.arange(5, 25))
    assert np.isnan(windows[5].positions[0, 20:]).all()
    # the context agent ped 3 of the first window: seen from frame 50 to 140, NaN elsewhere
    seen = ~np.isnan(windows[0].positions[2, :, 0])
    assert np.flatnonzero(seen).tolist() == list(range(5, 15))


def test_no_window_spans_a_gap_in_frames(tmp_path):
    text = walkers(range(0, 150, 10), {1: range(0, 1000)}) + walkers(range(200, 350, 10), {1: range(0, 1000)})
    assert recording_windows(read_recording(write(tmp_path, text))) == []


def test_real_eth_scene_windows(eth_ucy_dir):
    windows = recording_windows(read_recording(eth_ucy_dir / "all_data" / "biwi_eth.txt"))
    assert len(windows) == 253
    assert sum(w.targets for w in windows) == 364
    steps = np.linalg.norm(np.diff(windows[0].positions[: windows[0].targets, :SEQ_LEN], axis=1), axis=-1)
    assert steps.max() < 2.0  # metres per 0.4 s: no window jumps across a gap


def test_splits_and_all_scenes(eth_ucy_dir):
    eth = load_split(eth_ucy_dir, "eth")
    assert [p.name for p in eth.test] == ["biwi_eth.txt"]
    assert "biwi_eth_train.txt" not in {p.name for p in eth.train}
    everything = load_split(eth_ucy_dir, "all")
    assert len(everything.train) == 8 and len(everything.val) == 8 and everything.test == ()
    assert everything.describe()["train"][0] == "train/biwi_eth_train.txt"
    with pytest.raises(NaviganError, match="unknown split 'mars'"):
        load_split(eth_ucy_dir, "mars")


def test_batches_cover_every_window_once_within_the_target_limit(eth_ucy_dir):
    scenes = Scenes.from_files([eth_ucy_dir / "val" / "crowds_zara02_val.txt"])
    batches = scenes.batches(32, seed=(0, 1))
    flat = np.concatenate(batches)
    assert sorted(flat.tolist()) == list(range(len(scenes.counts)))
    for b in batches:
        assert scenes.counts[b].sum() <= 32 or len(b) == 1
    again = scenes.batches(32, seed=(0, 1))
    assert all(np.array_equal(a, b) for a, b in zip(batches, again))
    assert not all(np.array_equal(a, b) for a, b in zip(batches, scenes.batches(32, seed=(0, 2))))


def test_scene_batch_padding_and_goals(eth_ucy_dir):
    scenes = Scenes.from_files([eth_ucy_dir / "val" / "crowds_zara02_val.txt"])
    windows = np.array([0, int(np.argmax(scenes.agents))])
    batch = scenes.batch(windows)
    assert batch.obs.shape == (2, scenes.agents[windows].max(), T_OBS, 2)
    assert batch.targets.sum().item() == scenes.counts[windows].sum()
    assert batch.mask.sum().item() == scenes.agents[windows].sum()
    assert batch.goals.shape == (int(scenes.counts[windows].sum()), 2)
    np.testing.assert_allclose(batch.goals[0].numpy(), scenes.positions[0, 0, SEQ_LEN - 1])
    assert not torch.isnan(batch.obs).any() and not torch.isnan(batch.future).any()
    others, present = batch.neighbours()
    assert present.shape == others.shape[:3] and present.any()


def test_goals_drawn_from_a_range_of_horizons(eth_ucy_dir):
    scenes = Scenes.from_files([eth_ucy_dir / "val" / "crowds_zara02_val.txt"])
    windows = np.arange(len(scenes.counts))
    batch = scenes.batch(windows, Sampling((8, 36)), np.random.default_rng(0))
    far = torch.from_numpy(scenes.positions[:, :, T_OBS:])[batch.targets]  # (K, FAR_STEPS, 2)
    hit = (far - batch.goals[:, None]).norm(dim=-1) < 1e-6
    steps = hit.float().argmax(dim=1) + 1
    assert hit.any(dim=1).all()
    assert steps.min() == 8 and steps.max() == 36 and 15 < steps.float().median() < 30
    assert not torch.equal(batch.goals, scenes.batch(windows, Sampling((8, 36)), np.random.default_rng(1)).goals)
    with pytest.raises(NaviganError, match="goal steps 0-36"):
        Sampling((0, 36))


def test_turned_scenes_keep_their_shape(eth_ucy_dir):
    scenes = Scenes.from_files([eth_ucy_dir / "val" / "crowds_zara02_val.txt"])
    windows = np.arange(6)
    plain = scenes.batch(windows)
    turned = scenes.batch(windows, Sampling(augment=True), np.random.default_rng(0))
    assert not torch.allclose(plain.obs, turned.obs)
    for a, b in ((plain.obs, turned.obs), (plain.future, turned.future)):
        gaps = lambda x: (x[:, :, None] - x[:, None]).norm(dim=-1)  # noqa: E731
        torch.testing.assert_close(gaps(a) * plain.mask[:, :, None, None], gaps(b) * plain.mask[:, :, None, None])
    torch.testing.assert_close(plain.goals.norm(dim=-1), turned.goals.norm(dim=-1))
