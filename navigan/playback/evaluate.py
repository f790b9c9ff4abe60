"""The playback evaluation: every requested model on every requested split, resumable, into one folder.

    OUT/episodes/<split>/<model>.json  each episode's scores and walked path, with the settings,
                                       the checkpoint's digest and the episode names that made them
    OUT/table1.md, OUT/table1.csv      Table I pooled over the splits and averaged over them, each
                                       beside the paper's with 95 % intervals, then per split
    OUT/episodes.csv                   every episode's scores, one row per split, model and episode
    OUT/figures/                       fig4_<split>, forces_<split>, min_distance: each as .png (at `dpi`) and .svg

A (split, model) whose file exists is not walked again; an interrupted run picks up where it was.
A file made with other settings, weights or data is an error, never silently reused or replaced.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from tqdm.auto import tqdm

from navigan import checkpoint as ckpt
from navigan.data import SPLITS, load_split
from navigan.errors import NaviganError
from navigan.playback import figures
from navigan.playback.episodes import CUTOFF_STEPS, Episodes, load_episodes
from navigan.playback.metrics import Scoring, score_episode
from navigan.playback.paper import PAPER_FILE, PaperTable, load_paper
from navigan.playback.protocols import DEFAULT_PROTOCOL, PROTOCOLS, target_rule
from navigan.playback.rollout import RECORDED, Policy, Rollout, recorded_rollout, roll_out
from navigan.playback.table import (
    COLUMNS,
    POOLED,
    SPLIT_MEAN,
    SceneCount,
    Table,
    aggregate,
    csv_text,
    document,
    episodes_csv,
    summarize,
)
from robot_logs.figure_files import DEFAULT_DPI, Rendered

MODELS: tuple[str, ...] = tuple(COLUMNS)
HUMAN = "human"
#: The shielded columns' margin by default (m): the paper's d_safe between people.
SHIELD_MARGIN = 0.5
#: Column suffixes: the intention-only path, the shield's check, the checkpoint's evasion networks.
DAGGER, SHIELDED, EVADING = "-dagger", "-shield", "-evasion"
#: Which model's full and dagger paths Fig. 4 shows: the first of these that a requested column walks with.
FIGURE_MODELS = ("navigan-r", "navigan", "navil2")
#: `Settings.of`'s sub-goal pace meaning "the protocol's own".
PROTOCOL_GOAL = "protocol"


@dataclass(frozen=True)
class Settings:
    """What, besides the weights and the data, decides the scores.

    Attributes:
        scoring: the reward's settings.
        seed: seeds the fluctuation noise (with each episode's name).
        limit: evaluate only the first `limit` episodes of each split (a quick look).
        subgoal_speed: the pace of the sub-goals the networks are handed, T_PRED steps ahead
            toward the goal: RECORDED (each target's own) or m/s; None hands them the goal itself
            (see `rollout.roll_out`).
        shield: the margin (m) of the shielded columns' check (`navigan.shield`).
        protocol: the protocol's name (`protocols.PROTOCOLS`): which pedestrians become targets and
            where their goals lie; `scoring.distances` and `subgoal_speed` carry its other two choices.
    """

    scoring: Scoring = field(default_factory=Scoring)
    seed: int = 0
    limit: int | None = None
    subgoal_speed: float | str | None = RECORDED
    shield: float = SHIELD_MARGIN
    protocol: str = DEFAULT_PROTOCOL

    def record(self) -> dict[str, Any]:
        return asdict(self.scoring) | {"seed": self.seed, "limit": self.limit, "subgoal_speed": self.subgoal_speed,
                                       "shield": self.shield, "protocol": self.protocol,
                                       "targets": target_rule(self.protocol)}

    @classmethod
    def of(cls, protocol: str, gamma: float = 0.9, v_pref: float = 1.0, collision: float = 0.1, seed: int = 0,
           limit: int | None = None, subgoal_speed: float | str | None = PROTOCOL_GOAL,
           shield: float = SHIELD_MARGIN) -> Settings:
        """The settings of a named protocol: its targets, distances and (unless `subgoal_speed` says
        otherwise) its goal handed to the networks."""
        chosen = PROTOCOLS[protocol]
        speed = chosen.subgoal_speed if subgoal_speed == PROTOCOL_GOAL else subgoal_speed
        return cls(Scoring(gamma, v_pref, collision, chosen.distances), seed, limit, speed, shield, protocol)

    def policy(self, model: str, record: ckpt.Checkpoint, path: Path) -> Policy:
        """The policy a learned column walks with: its checkpoint's, its dagger, shield or evasion
        networks, our seed.

        Raises:
            NaviganError: an evasion column's checkpoint has no evasion networks.
        """
        shield = self.shield if model.endswith(SHIELDED) else None
        return Policy.of(record, path, dagger=model.endswith(DAGGER), seed=self.seed, shield=shield,
                         evasion=model.endswith(EVADING))


def base_model(model: str) -> str:
    """The trained model a column walks with: `navigan-dagger`, `navigan-r-shield` and
    `navigan-r-evasion` -> `navigan`, `navigan-r` and `navigan-r`."""
    return model.removesuffix(DAGGER).removesuffix(SHIELDED).removesuffix(EVADING)


def checkpoint_file(model: str, split: str, folder: Path) -> Path | None:
    """The checkpoint a column uses on a split: `<model>-<split>.pt` in `folder`; None for the human row."""
    return None if model == HUMAN else folder / f"{base_model(model)}-{split}.pt"


def check_request(splits: Sequence[str], models: Sequence[str], folder: Path) -> None:
    """Refuse unknown splits or models, missing checkpoints, and checkpoints without the evasion
    networks an evasion column walks, before any work.

    Raises:
        NaviganError: naming every unknown name or missing file.
    """
    unknown = [s for s in splits if s not in SPLITS]
    if unknown:
        raise NaviganError(f"unknown split {', '.join(unknown)}: choose from {', '.join(SPLITS)} or all")
    unknown = [m for m in models if m not in MODELS]
    if unknown:
        raise NaviganError(f"unknown model {', '.join(unknown)}: choose from {', '.join(MODELS)}")
    missing = sorted({str(p) for s in splits for m in models
                      if (p := checkpoint_file(m, s, folder)) is not None and not p.is_file()})
    if missing:
        raise NaviganError(f"missing checkpoint{'s' if len(missing) > 1 else ''}: {', '.join(missing)}")
    without = sorted({str(p) for s in splits for m in models if m.endswith(EVADING)
                      if (p := checkpoint_file(m, s, folder)) is not None and ckpt.load(p).build_evasion() is None})
    if without:
        raise NaviganError(f"no evasion networks in {', '.join(without)}: add them with trials train --evasion, "
                           f"or leave the {EVADING} column out")


def write_atomic(path: Path, data: bytes) -> None:
    """Write through a temporary file in the same folder and a rename, so no file is ever half-written."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _finite(value: float | None) -> float | None:
    """JSON has no inf or NaN: store them as null."""
    return None if value is None or not math.isfinite(value) else round(float(value), 6)


def score_rollout(episodes: Episodes, rollout: Rollout, scoring: Scoring) -> list[dict[str, Any]]:
    """One record per episode: its name, every score, and the walked path."""
    history = episodes.history()
    records = []
    for e, name in enumerate(episodes.ids):
        path = rollout.path(e)
        score = score_episode(path, episodes.others(e)[: len(path)], episodes.goal[e], episodes.recorded(e),
                              history[e, -1] - history[e, -2], scoring)
        record: dict[str, Any] = {"episode": name}
        for key, value in asdict(score).items():
            record[key] = _finite(value) if isinstance(value, float) else value
        record["path"] = np.round(path.astype(np.float64), 4).tolist()
        records.append(record)
    return records


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@dataclass
class Playback:
    """An evaluation writing into `out`, with checkpoints from `checkpoints`, data under `data`, the
    paper's values from the transcription `paper`, and PNG figures at `dpi` (the scores do not depend on it)."""

    data: Path
    out: Path
    checkpoints: Path = ckpt.WEIGHTS_DIR
    settings: Settings = field(default_factory=Settings)
    paper: Path = PAPER_FILE
    dpi: int = DEFAULT_DPI

    def result_file(self, split: str, model: str) -> Path:
        return self.out / "episodes" / split / f"{model}.json"

    def episodes(self, split: str) -> tuple[Episodes, list[str]]:
        """A split's episodes (the first `limit` of them) and its test files."""
        files = load_split(self.data, split).test
        episodes = load_episodes(files, self.settings.protocol)
        if self.settings.limit is not None:
            episodes = episodes.subset(range(min(self.settings.limit, len(episodes))))
        return episodes, [f.name for f in files]

    def identity(self, split: str, model: str, episodes: Episodes) -> dict[str, Any]:
        """What a stored result must match to be reused."""
        path = checkpoint_file(model, split, self.checkpoints)
        return {"settings": self.settings.record(), "weights": path and _digest(path), "episodes": episodes.ids}

    def stored(self, split: str, model: str, identity: dict[str, Any]) -> dict[str, Any] | None:
        """The stored result of a (split, model), None if there is none.

        Raises:
            NaviganError: it was made with other settings, weights or episodes.
        """
        file = self.result_file(split, model)
        if not file.is_file():
            return None
        try:
            record = json.loads(file.read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError) as exc:
            raise NaviganError(f"cannot read {file}: {exc}; delete it to redo that evaluation") from exc
        differ = [k for k, v in identity.items() if record.get("identity", {}).get(k) != v]
        if differ:
            raise NaviganError(f"{file} was made with other {' and '.join(differ)}; pass another --out, "
                               "or delete that file to redo it")
        return record

    def walk(self, split: str, model: str, episodes: Episodes, progress: Callable[[int], object] | None
             ) -> tuple[Rollout, dict[str, Any] | None]:
        """Roll out one column on a split's episodes; also a description of the checkpoint used."""
        path = checkpoint_file(model, split, self.checkpoints)
        if path is None:
            return recorded_rollout(episodes), None
        record = ckpt.load(path)
        policy = self.settings.policy(model, record, path)
        about = {"file": path.name, "trained_on": record.split.get("name"), "epochs": record.epoch,
                 "kept_epoch": (record.best or {}).get("epoch"), "finished": record.finished}
        return roll_out(policy, episodes, progress=progress, subgoal_speed=self.settings.subgoal_speed), about

    def evaluate(self, splits: Sequence[str], models: Sequence[str], progress: bool = True,
                 on_walked: Callable[[int, int, str, str], object] | None = None) -> list[Table]:
        """Evaluate what is not stored yet, then write the tables, the episode CSV and the figures.

        `progress` shows a tqdm bar; `on_walked(n, total, split, column)` is called as each of the
        `total` columns still to walk has been walked and stored.

        Raises:
            NaviganError: unknown split or model, missing checkpoint or data, a bad transcription
                of the paper's table, or a stored result made differently.
        """
        check_request(splits, models, self.checkpoints)
        paper = load_paper(self.paper)
        models = [m for m in MODELS if m in models]
        loaded = {s: self.episodes(s) for s in splits}
        results: dict[tuple[str, str], dict[str, Any]] = {}
        pending = []
        for split in splits:
            for model in models:
                identity = self.identity(split, model, loaded[split][0])
                record = self.stored(split, model, identity)
                if record is None:
                    pending.append((split, model, identity))
                else:
                    results[split, model] = record
        learned = sum(1 for _, m, _ in pending if m != HUMAN)
        with tqdm(total=learned * CUTOFF_STEPS, disable=not progress, unit="step", desc="playback") as bar:
            for done, (split, model, identity) in enumerate(pending, start=1):
                bar.set_description(f"playback {split} {COLUMNS[model]}")
                episodes = loaded[split][0]
                rollout, about = self.walk(split, model, episodes, bar.update)
                if model != HUMAN:
                    bar.update(CUTOFF_STEPS - int(rollout.steps.max(initial=0)))
                record = {"split": split, "model": model, "column": COLUMNS[model], "checkpoint": about,
                          "identity": identity, "results": score_rollout(episodes, rollout, self.settings.scoring)}
                write_atomic(self.result_file(split, model), (json.dumps(record) + "\n").encode())
                results[split, model] = record
                if on_walked is not None:
                    on_walked(done, len(pending), split, COLUMNS[model])
        tables = self.write_tables(splits, models, loaded, results, paper)
        self.write_figures(splits, models, loaded, results)
        return tables

    def write_tables(self, splits: Sequence[str], models: Sequence[str],
                     loaded: dict[str, tuple[Episodes, list[str]]],
                     results: dict[tuple[str, str], dict[str, Any]], paper: PaperTable) -> list[Table]:
        """table1.md, table1.csv and episodes.csv from the results, the paper's values beside them."""
        columns = tuple(models)
        per_split = {m: [results[s, m]["results"] for s in splits] for m in models}
        tables = [aggregate(scope, columns, per_split, self.settings.seed) for scope in (POOLED, SPLIT_MEAN)]
        tables += [Table(s, columns, {m: summarize(results[s, m]["results"]) for m in models}) for s in splits]
        scenes = [SceneCount(s, loaded[s][1], len(loaded[s][0]), loaded[s][0].standing) for s in splits]
        weights = {(s, m): results[s, m]["checkpoint"] for s in splits for m in models}
        write_atomic(self.out / "table1.md", document(tables, scenes, weights, self.settings.record(), paper).encode())
        write_atomic(self.out / "table1.csv", csv_text(tables, paper, self.settings.protocol).encode())
        write_atomic(self.out / "episodes.csv",
                     episodes_csv({(s, m): results[s, m]["results"] for s in splits for m in models},
                                  self.settings.protocol).encode())
        return tables

    def scored(self, split: str, model: str, episodes: Episodes, results: dict[tuple[str, str], dict[str, Any]]
               ) -> list[dict[str, Any]]:
        """A column's episode records on a split: the evaluated ones, else walked now for the figure
        (not stored: the tables show only the columns asked for)."""
        if (split, model) in results:
            return results[split, model]["results"]
        return score_rollout(episodes, self.walk(split, model, episodes, None)[0], self.settings.scoring)

    def write_figures(self, splits: Sequence[str], models: Sequence[str],
                      loaded: dict[str, tuple[Episodes, list[str]]],
                      results: dict[tuple[str, str], dict[str, Any]]) -> None:
        """Fig. 4 and the force plot per split, for the first of FIGURE_MODELS any column walks with
        (itself, its dagger or its shielded variant), and the distribution of closest approaches."""
        folder = self.out / "figures"
        closest = {COLUMNS[m]: [np.inf if r["min_distance"] is None else r["min_distance"]
                                for s in splits for r in results[s, m]["results"]] for m in models}
        self.save_figure(folder / "min_distance",
                         figures.plot_min_distances(closest, f"Closest approach per episode ({', '.join(splits)}; "
                                                                   f"protocol {self.settings.protocol})"))
        model = next((m for m in FIGURE_MODELS if any(base_model(c) == m for c in models)), None)
        if model is None:
            return
        for split in splits:
            episodes = loaded[split][0]
            full, dagger = (self.scored(split, variant, episodes, results) for variant in (model, f"{model}-dagger"))
            e = choose_episode(full, dagger)
            one = episodes.subset([e])
            path = checkpoint_file(model, split, self.checkpoints)
            speed = self.settings.subgoal_speed
            walked = roll_out(Policy.load(path, seed=self.settings.seed), one, record=True, subgoal_speed=speed)
            intention = roll_out(Policy.load(path, dagger=True, seed=self.settings.seed), one, subgoal_speed=speed)
            n = int(walked.steps[0])
            label = f"{COLUMNS[model]} ({path.name}) on {split}, episode {one.ids[0]}, protocol {self.settings.protocol}"
            self.save_figure(folder / f"fig4_{split}",
                             figures.plot_paths(one, 0, walked.path(0), intention.path(0), walked.plans[0, :n, 2, 0],
                                                label))
            self.save_figure(folder / f"forces_{split}",
                             figures.plot_forces(one, 0, walked.path(0), walked.plans[0, :n], label))

    def save_figure(self, stem: Path, figure: Rendered) -> None:
        """stem.png at the evaluation's dpi and stem.svg, each written whole."""
        for path, data in figure.files(stem, self.dpi).items():
            write_atomic(path, data)


def choose_episode(full: list[dict[str, Any]], dagger: list[dict[str, Any]]) -> int:
    """The episode whose full and dagger paths part most (mean distance over their common steps),
    among those the full model completes, else among all: where the social force shows."""
    def parting(a: dict[str, Any], b: dict[str, Any]) -> float:
        pa, pb = np.asarray(a["path"]), np.asarray(b["path"])
        n = min(len(pa), len(pb))
        return float(np.linalg.norm(pa[:n] - pb[:n], axis=-1).mean())

    order = [i for i, r in enumerate(full) if r["arrived"]] or list(range(len(full)))
    return max(order, key=lambda i: parting(full[i], dagger[i]))
