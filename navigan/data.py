"""ETH/UCY trajectories: read the text files, cut them into windows, batch whole scenes.

A window is T_OBS + T_PRED consecutive frames (0.4 s apart) of one recording; its targets are
the pedestrians present in every frame of it (the Social LSTM / Social GAN practice), and its
context agents are the others present at the last observed frame, as a planner sees them at run
time. A target's goal is its recorded position some steps after the last observed one: the last
future position (the paper's), or drawn from a range of horizons (see `Sampling`). A batch is a
set of whole windows, padded to the same number of agents, with masks saying which rows are real
and which are targets.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np
import torch

from navigan.errors import NaviganError
from robot_logs.physical import T_OBS, T_PRED

#: Observed and predicted steps of a window.
SEQ_LEN = T_OBS + T_PRED
#: How far past the last observed step a window keeps its agents' tracks: as far as playback's goals.
FAR_STEPS = 3 * T_PRED

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


@dataclass(frozen=True)
class Window:
    """T_OBS + FAR_STEPS consecutive frames of one recording, from one window's first frame.

    Attributes:
        positions: (agents, T_OBS + FAR_STEPS, 2) positions, NaN where an agent is absent: first
            the targets (present in all of the first SEQ_LEN frames), then the context agents
            (present at the last observed frame but not throughout).
        targets: how many of the rows are targets.
    """

    positions: np.ndarray
    targets: int


def recording_windows(recording: Recording) -> list[Window]:
    """Every window of SEQ_LEN consecutive frames with at least one target, in frame order.

    Frames are consecutive when they differ by the recording's frame step (the smallest gap);
    a window spanning a gap in the frame numbers has no agent present throughout, so none is cut.
    Each window also keeps every agent's track up to FAR_STEPS steps after the last observed
    frame (the goals of far horizons), NaN beyond the recording's end.
    """
    frames = np.unique(recording.frames)
    if len(frames) < SEQ_LEN:
        return []
    step = int(np.diff(frames).min())
    grid_index = (recording.frames - frames[0]) // step
    if np.any((recording.frames - frames[0]) % step):
        bad = int(np.argmax((recording.frames - frames[0]) % step != 0))
        raise NaviganError(
            f"{recording.path.name}: frame {recording.frames[bad]} is off the frame step {step}"
        )
    ids, ped_index = np.unique(recording.pedestrians, return_inverse=True)
    length = int(grid_index.max()) + 1
    grid = np.full((length + FAR_STEPS - T_PRED, len(ids), 2), np.nan, dtype=np.float32)
    grid[grid_index, ped_index] = recording.xy
    present = ~np.isnan(grid[..., 0])
    if length < SEQ_LEN:
        return []
    throughout = np.lib.stride_tricks.sliding_window_view(present[:length], SEQ_LEN, axis=0).all(axis=-1)
    windows = []
    for start, targets in enumerate(throughout):
        if not targets.any():
            continue
        context = present[start + T_OBS - 1] & ~targets
        agents = np.concatenate([np.flatnonzero(targets), np.flatnonzero(context)])
        track = grid[start : start + T_OBS + FAR_STEPS, agents].transpose(1, 0, 2)
        windows.append(Window(np.ascontiguousarray(track), int(targets.sum())))
    return windows


def fill_tracks(tracks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(..., N, T, 2) histories with NaN -> filled histories and (..., N) which agents are present.

    An agent is present when its newest position is known; its unknown earlier positions take
    the nearest known one after them (it is taken to have stood there until first seen);
    absent agents are zero.
    """
    known = ~np.isnan(tracks).any(axis=-1)
    present = known[..., -1]
    filled = tracks.copy()
    for t in range(tracks.shape[-2] - 2, -1, -1):
        missing = ~known[..., t]
        filled[..., t, :][missing] = filled[..., t + 1, :][missing]
    filled[~present] = 0.0
    return filled, present


@dataclass(frozen=True)
class SceneBatch:
    """Whole windows padded to one agent count: targets to plan for among the agents present.

    Attributes:
        obs: (B, A, T_OBS, 2) observed positions in each scene's world frame (an agent seen late
            stands at its first seen position before; zero for padding).
        future: (B, A, T_PRED, 2) future positions, zero where unknown.
        seen: (B, A, T_PRED) which future positions are known.
        mask: (B, A) the agents present at the last observed step (targets and context).
        targets: (B, A) the targets, present in every step of the window.
        goals: (K, 2) each target's goal, in `targets.nonzero()` order.
    """

    obs: torch.Tensor
    future: torch.Tensor
    seen: torch.Tensor
    mask: torch.Tensor
    targets: torch.Tensor
    goals: torch.Tensor

    @property
    def truth(self) -> torch.Tensor:
        """(K, T_PRED, 2) the future of each target, in target order."""
        return self.future[self.targets]

    def neighbours(self) -> tuple[torch.Tensor, torch.Tensor]:
        """(K, A, T_PRED, 2) the future positions of each target's scene and (K, A, T_PRED) where
        they are known positions of agents other than the target."""
        b, a = self.targets.nonzero(as_tuple=True)
        others = self.mask[b] & (torch.arange(self.mask.shape[1], device=self.mask.device) != a.unsqueeze(1))
        return self.future[b], self.seen[b] & others.unsqueeze(-1)

    def to(self, device: str | torch.device) -> SceneBatch:
        return SceneBatch(*(getattr(self, f.name).to(device) for f in fields(self)))


@dataclass(frozen=True)
class Sampling:
    """How a batch's goals and orientation are drawn.

    Attributes:
        goal_steps: (first, last) steps after the last observed one where a target's goal may lie;
            each target's goal is its recorded position a uniformly drawn number of steps ahead,
            no farther than it stays in view ((T_PRED, T_PRED): the paper's last future position).
        augment: turn each window by a uniform random angle, and mirror half of them.
    """

    goal_steps: tuple[int, int] = (T_PRED, T_PRED)
    augment: bool = False

    def __post_init__(self) -> None:
        first, last = self.goal_steps
        if not 1 <= first <= last <= FAR_STEPS:
            raise NaviganError(f"goal steps {first}-{last}: expected 1 <= first <= last <= {FAR_STEPS}")


def _turn(positions: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """(W, A, T, 2) windows, each turned by a random angle about the origin and mirrored at random."""
    angle = rng.uniform(0.0, 2 * np.pi, len(positions))
    mirror = np.where(rng.random(len(positions)) < 0.5, -1.0, 1.0)
    c, s = np.cos(angle), np.sin(angle)
    rotation = np.stack([np.stack([c, -s * mirror], -1), np.stack([s, c * mirror], -1)], -2)
    return np.einsum("wij,watj->wati", rotation.astype(np.float32), positions)


def _goals(far: np.ndarray, sampling: Sampling, rng: np.random.Generator | None) -> np.ndarray:
    """(K, 2) goals from (K, FAR_STEPS, 2) tracks after the last observed step (see Sampling)."""
    first, last = sampling.goal_steps
    in_view = np.cumprod(~np.isnan(far[..., 0]), axis=1).sum(axis=1)
    top = np.maximum(np.minimum(last, in_view), first)
    steps = top if rng is None else rng.integers(np.minimum(first, top), top + 1)
    steps = np.minimum(steps, in_view)
    return far[np.arange(len(far)), steps - 1]


@dataclass(frozen=True)
class Scenes:
    """The windows of some recordings as one NaN-padded array.

    Attributes:
        positions: (W, A_max, T_OBS + FAR_STEPS, 2) each window's agents (targets first), NaN
            where absent and beyond each window's agents.
        counts: (W,) targets in each window.
        agents: (W,) agents (targets and context) in each window.
        files: the recordings read.
        skipped: NaN/missing rows skipped, per file name.
    """

    positions: np.ndarray
    counts: np.ndarray
    agents: np.ndarray
    files: tuple[Path, ...]
    skipped: dict[str, int]

    @classmethod
    def from_files(cls, files: Sequence[str | Path]) -> Scenes:
        """Read recordings and cut all their windows."""
        recordings = [read_recording(f) for f in files]
        windows = [w for r in recordings for w in recording_windows(r)]
        if not windows:
            raise NaviganError(f"no {SEQ_LEN}-frame windows in {', '.join(map(str, files))}")
        agents = np.array([len(w.positions) for w in windows], dtype=np.int64)
        positions = np.full((len(windows), agents.max(), T_OBS + FAR_STEPS, 2), np.nan, dtype=np.float32)
        for i, w in enumerate(windows):
            positions[i, : len(w.positions)] = w.positions
        return cls(
            positions=positions,
            counts=np.array([w.targets for w in windows], dtype=np.int64),
            agents=agents,
            files=tuple(r.path for r in recordings),
            skipped={r.path.name: r.skipped for r in recordings},
        )

    @property
    def n_targets(self) -> int:
        return int(self.counts.sum())

    def subset(self, windows: Iterable[int]) -> Scenes:
        """The same data restricted to some windows (tests and quick runs)."""
        index = np.asarray(list(windows), dtype=np.int64)
        width = int(self.agents[index].max())
        return Scenes(self.positions[index, :width], self.counts[index], self.agents[index], self.files, self.skipped)

    def batch(
        self, windows: np.ndarray, sampling: Sampling = Sampling(), rng: np.random.Generator | None = None
    ) -> SceneBatch:
        """Padded tensors of the given windows.

        Without `rng` nothing is random: no turning, and each goal lies `sampling.goal_steps[1]`
        steps ahead (or as far as the target stays in view).
        """
        width = int(self.agents[windows].max())
        positions = self.positions[windows, :width]
        if sampling.augment and rng is not None:
            positions = _turn(positions, rng)
        obs, present = fill_tracks(positions[:, :, :T_OBS])
        future = positions[:, :, T_OBS:SEQ_LEN]
        seen = ~np.isnan(future[..., 0])
        targets = np.arange(width)[None, :] < self.counts[windows][:, None]
        goals = _goals(positions[:, :, T_OBS:][targets], sampling, rng)
        return SceneBatch(
            obs=torch.from_numpy(obs),
            future=torch.from_numpy(np.where(seen[..., None], future, 0.0).astype(np.float32)),
            seen=torch.from_numpy(seen),
            mask=torch.from_numpy(present),
            targets=torch.from_numpy(targets),
            goals=torch.from_numpy(np.ascontiguousarray(goals)),
        )

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


SHIPPED_DATA = Path(__file__).resolve().parent / "datasets" / "eth_ucy"


def data_dir(path: str | Path | None) -> Path:
    """The ETH/UCY folder: `path` if given, else $TRIALS_DATA, else the copy shipped with the package.

    Raises:
        NaviganError: the folder has no splits.json.
    """
    chosen = path if path is not None else os.environ.get("TRIALS_DATA") or SHIPPED_DATA
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
