"""ETH/UCY trajectories: read the text files, cut them into windows, batch whole scenes.

A window is T_OBS + T_PRED consecutive frames (0.4 s apart) of one recording; its agents are
the pedestrians present in every frame of it (the Social LSTM / Social GAN practice), and each
of them is a target whose goal is its last future position. A batch is a set of whole windows,
padded to the same number of agents, with a mask saying which rows are real.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from navigan.errors import NaviganError

#: Observed and predicted steps of a window, and the time between steps (s).
T_OBS = 8
T_PRED = 12
SEQ_LEN = T_OBS + T_PRED
STEP_S = 0.4

#: The leave-one-scene-out splits of splits.json, and the extra split over all scenes.
SPLITS = ("eth", "hotel", "univ", "zara1", "zara2")
ALL_SCENES = "all"

_MISSING = {"", "nan", "na", "n/a", "null", "none", "?", "-"}


@dataclass(frozen=True)
class Recording:
    """The rows of one ETH/UCY text file, in file order.

    Attributes:
        path: the file read.
        frames: (n,) frame numbers.
        pedestrians: (n,) pedestrian ids.
        xy: (n, 2) positions (m).
        skipped: rows left out because a value was NaN or missing.
    """

    path: Path
    frames: np.ndarray
    pedestrians: np.ndarray
    xy: np.ndarray
    skipped: int


def read_recording(path: str | Path) -> Recording:
    """Read a `frame ped x y` file (tab or space separated); NaN/missing rows are skipped.

    Raises:
        NaviganError: the file cannot be read, a line does not hold 4 fields, a field is not a
            number, or a pedestrian appears twice in one frame; the message names file and line.
    """
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise NaviganError(f"cannot read trajectory file {path}: {exc}") from exc
    rows: list[tuple[float, float, float, float]] = []
    skipped = 0
    seen: dict[tuple[float, float], int] = {}
    for number, line in enumerate(lines, start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        fields = [f.strip() for f in line.split("\t")] if "\t" in line else line.split()
        if len(fields) != 4:
            raise NaviganError(
                f'malformed line {number} of {path.name}: expected 4 numbers "frame ped x y", '
                f"got {len(fields)} fields"
            )
        if any(f.lower() in _MISSING for f in fields):
            skipped += 1
            continue
        try:
            values = tuple(float(f) for f in fields)
        except ValueError:
            raise NaviganError(
                f'malformed line {number} of {path.name}: expected 4 numbers "frame ped x y", '
                f"got {line.strip()!r}"
            ) from None
        if not all(math.isfinite(v) for v in values):
            skipped += 1
            continue
        key = (values[0], values[1])
        if key in seen:
            raise NaviganError(
                f"line {number} of {path.name}: pedestrian {values[1]:g} appears twice in frame "
                f"{values[0]:g} (first on line {seen[key]})"
            )
        seen[key] = number
        rows.append(values)  # type: ignore[arg-type]
    if not rows:
        raise NaviganError(f"no trajectory rows in {path}")
    table = np.asarray(rows, dtype=np.float64)
    return Recording(
        path=path,
        frames=table[:, 0].astype(np.int64),
        pedestrians=table[:, 1].astype(np.int64),
        xy=table[:, 2:].astype(np.float32),
        skipped=skipped,
    )


def recording_windows(recording: Recording, seq_len: int = SEQ_LEN) -> list[np.ndarray]:
    """Every window of `seq_len` consecutive frames, as (agents, seq_len, 2) arrays.

    Frames are consecutive when they differ by the recording's frame step (the smallest gap);
    a window spanning a gap in the frame numbers has no agent present throughout, so none is cut.
    """
    frames = np.unique(recording.frames)
    if len(frames) < seq_len:
        return []
    step = int(np.diff(frames).min())
    grid_index = (recording.frames - frames[0]) // step
    if np.any((recording.frames - frames[0]) % step):
        bad = int(np.argmax((recording.frames - frames[0]) % step != 0))
        raise NaviganError(
            f"{recording.path.name}: frame {recording.frames[bad]} is off the frame step {step}"
        )
    ids, ped_index = np.unique(recording.pedestrians, return_inverse=True)
    grid = np.full((int(grid_index.max()) + 1, len(ids), 2), np.nan, dtype=np.float32)
    grid[grid_index, ped_index] = recording.xy
    present = ~np.isnan(grid[..., 0])
    if present.shape[0] < seq_len:
        return []
    throughout = np.lib.stride_tricks.sliding_window_view(present, seq_len, axis=0).all(axis=-1)
    return [
        np.ascontiguousarray(grid[start : start + seq_len, agents].transpose(1, 0, 2))
        for start, agents in enumerate(throughout)
        if agents.any()
    ]


@dataclass(frozen=True)
class SceneBatch:
    """Whole windows padded to one agent count; every real agent is a target.

    Attributes:
        obs: (B, A, T_OBS, 2) observed positions in each scene's world frame.
        future: (B, A, T_PRED, 2) future positions.
        mask: (B, A) which rows are real agents.
    """

    obs: torch.Tensor
    future: torch.Tensor
    mask: torch.Tensor

    @property
    def goals(self) -> torch.Tensor:
        """(K, 2) the goal of each target: its last future position (targets in mask order)."""
        return self.future[self.mask][:, -1]

    @property
    def truth(self) -> torch.Tensor:
        """(K, T_PRED, 2) the future of each target, in mask order."""
        return self.future[self.mask]

    def neighbours(self) -> tuple[torch.Tensor, torch.Tensor]:
        """(K, A, T_PRED, 2) the future positions of each target's scene and (K, A) which of them
        are real agents other than the target."""
        b, a = self.mask.nonzero(as_tuple=True)
        others = self.mask[b] & (torch.arange(self.mask.shape[1], device=self.mask.device) != a.unsqueeze(1))
        return self.future[b], others

    def to(self, device: str | torch.device) -> SceneBatch:
        return SceneBatch(self.obs.to(device), self.future.to(device), self.mask.to(device))


@dataclass(frozen=True)
class Scenes:
    """The windows of some recordings as one zero-padded array.

    Attributes:
        positions: (W, A_max, SEQ_LEN, 2) agents' positions, zero beyond each window's count.
        counts: (W,) agents (= targets) in each window.
        files: the recordings read.
        skipped: NaN/missing rows skipped, per file name.
    """

    positions: np.ndarray
    counts: np.ndarray
    files: tuple[Path, ...]
    skipped: dict[str, int]

    @classmethod
    def from_files(cls, files: Sequence[str | Path]) -> Scenes:
        """Read recordings and cut all their windows."""
        recordings = [read_recording(f) for f in files]
        windows = [w for r in recordings for w in recording_windows(r)]
        if not windows:
            raise NaviganError(f"no {SEQ_LEN}-frame windows in {', '.join(map(str, files))}")
        counts = np.array([len(w) for w in windows], dtype=np.int64)
        positions = np.zeros((len(windows), counts.max(), SEQ_LEN, 2), dtype=np.float32)
        for i, w in enumerate(windows):
            positions[i, : len(w)] = w
        return cls(
            positions=positions,
            counts=counts,
            files=tuple(r.path for r in recordings),
            skipped={r.path.name: r.skipped for r in recordings},
        )

    @property
    def n_targets(self) -> int:
        return int(self.counts.sum())

    def subset(self, windows: Iterable[int]) -> Scenes:
        """The same data restricted to some windows (tests and quick runs)."""
        index = np.asarray(list(windows), dtype=np.int64)
        width = int(self.counts[index].max())
        return Scenes(self.positions[index, :width], self.counts[index], self.files, self.skipped)

    def batch(self, windows: np.ndarray) -> SceneBatch:
        """Padded tensors of the given windows."""
        counts = self.counts[windows]
        width = int(counts.max())
        positions = torch.from_numpy(self.positions[windows, :width])
        mask = torch.arange(width)[None, :] < torch.from_numpy(counts)[:, None]
        return SceneBatch(positions[:, :, :T_OBS], positions[:, :, T_OBS:], mask)

    def batches(self, targets: int, seed: int | Sequence[int] | None = None) -> list[np.ndarray]:
        """Group whole windows into batches of at most `targets` agents (a bigger window alone).

        With a seed (numpy's: an int or a sequence of them) the windows are shuffled, sorted by
        size inside chunks of about 50 batches so each batch pads little, and the batches are
        shuffled; without, they keep file order.
        """
        rng = np.random.default_rng(seed) if seed is not None else None
        order = np.arange(len(self.counts)) if rng is None else rng.permutation(len(self.counts))
        if rng is not None:
            chunk = max(1, 50 * targets // max(1, int(self.counts.mean())))
            order = np.concatenate(
                [c[np.argsort(self.counts[c], kind="stable")] for c in np.split(order, range(chunk, len(order), chunk))]
            )
        groups: list[np.ndarray] = []
        current: list[int] = []
        size = 0
        for w in order:
            if current and size + self.counts[w] > targets:
                groups.append(np.array(current))
                current, size = [], 0
            current.append(int(w))
            size += int(self.counts[w])
        groups.append(np.array(current))
        if rng is not None:
            rng.shuffle(groups)  # type: ignore[arg-type]
        return groups


@dataclass(frozen=True)
class Split:
    """The recordings of one leave-one-scene-out split (paths resolved under the data folder)."""

    name: str
    root: Path
    train: tuple[Path, ...]
    val: tuple[Path, ...]
    test: tuple[Path, ...]

    def describe(self) -> dict[str, object]:
        """A JSON-able record of the split: its name and files relative to the data folder."""
        record: dict[str, object] = {"name": self.name}
        for part in ("train", "val", "test"):
            record[part] = [p.relative_to(self.root).as_posix() for p in getattr(self, part)]
        return record


def data_dir(path: str | Path | None) -> Path:
    """The ETH/UCY folder: `path` if given, else $TRIALS_DATA.

    Raises:
        NaviganError: neither is set, or the folder has no splits.json.
    """
    chosen = path if path is not None else os.environ.get("TRIALS_DATA")
    if not chosen:
        raise NaviganError("no ETH/UCY data folder: pass --data DIR or set TRIALS_DATA")
    root = Path(chosen)
    if not (root / "splits.json").is_file():
        raise NaviganError(f"{root} is not an ETH/UCY data folder: it has no splits.json")
    return root


def load_split(root: str | Path, name: str) -> Split:
    """The files of split `name` from `root/splits.json`; `all` trains and validates on every scene.

    Raises:
        NaviganError: unknown split, malformed splits.json, or a listed file is missing.
    """
    root = Path(root)
    index_path = root / "splits.json"
    try:
        index = json.loads(index_path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as exc:
        raise NaviganError(f"cannot read {index_path}: {exc}") from exc
    known = sorted(index) + [ALL_SCENES]
    if name not in known:
        raise NaviganError(f"unknown split {name!r}: {index_path.name} has {', '.join(known)}")
    try:
        if name == ALL_SCENES:
            parts = {
                part: sorted({f for split in index.values() for f in split[part]})
                for part in ("train", "val")
            } | {"test": []}
        else:
            parts = {part: list(index[name][part]) for part in ("train", "val", "test")}
    except (KeyError, TypeError) as exc:
        raise NaviganError(f"{index_path}: split {name!r} lacks train/val/test lists ({exc})") from exc
    for files in parts.values():
        for f in files:
            if not (root / f).is_file():
                raise NaviganError(f"{index_path.name} lists {f}, which is not in {root}")
    return Split(
        name=name,
        root=root,
        train=tuple(root / f for f in parts["train"]),
        val=tuple(root / f for f in parts["val"]),
        test=tuple(root / f for f in parts["test"]),
    )
