"""Training NaviGAN-R's evasion networks (`navigan.evasion`) on the shield's test, DAgger-style.

The generator stays as it is. The first walk takes it alone through playback episodes cut from the
split's training recordings (never its test scene); each later round walks it with the networks
trained so far, so they learn in the states their own choices lead to. At every visited state the
shield's test (`navigan.shield`) labels the planned step and each move of the ring: held for the
shield's horizon, does it come within the margin of someone's constant-velocity forecast?

- The shortfall network is trained once, on the first walk's states: each person's own shortfall
  (m) for every choice, computed from the features, so every person in every state teaches it
  (squared error of PENALTY times the shortfall).
- A fresh head is trained after each walk on all the walks' states (binary cross-entropy of every
  choice's label: the planned step's, plus the mean of the ring's).

Batches are turned by a random multiple of the ring's heading step and mirrored at random, which
maps the ring onto itself. The checkpoint is saved after every walk; an interrupted training walks
its finished rounds again with the networks that walked them, and continues.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from navigan import checkpoint as ckpt
from navigan.config import EvasionConfig
from navigan.errors import NaviganError
from navigan.evasion import Evasion, EvasionHead, ShortfallNet, candidates, features, person_shortfalls, turned
from navigan.playback.episodes import Episodes
from navigan.playback.rollout import Policy, Visit, roll_out
from navigan.shield import HEADINGS, HORIZON, PENALTY, clearance, forecast


@dataclass(frozen=True)
class Labelled:
    """Visited states: what the networks see, and whether each choice falls short there.

    Attributes:
        x: (S, F) `navigan.evasion.features`.
        short: (S, CHOICES) the shield's test of the planned step and of each move of the ring.
    """

    x: np.ndarray
    short: np.ndarray

    def __len__(self) -> int:
        return len(self.x)


def join(parts: list[Labelled]) -> Labelled:
    """One set of states from several walks'."""
    return Labelled(np.concatenate([p.x for p in parts]), np.concatenate([p.short for p in parts]))


@torch.no_grad()
def walk(policy: Policy, episodes: Episodes, margin: float) -> Labelled:
    """The states `policy` visits walking `episodes`, labelled by the shield's test."""
    xs: list[np.ndarray] = []
    shorts: list[np.ndarray] = []

    def record(seen: Visit) -> None:
        position = seen.histories[:, -1]
        step = seen.planned - position
        xs.append(features(seen.histories, seen.around, step))
        shorts.append(clearance(position, candidates(step), forecast(seen.around, HORIZON)) < margin)

    roll_out(policy, episodes, visit=record)
    return Labelled(np.concatenate(xs), np.concatenate(shorts).astype(np.float32))


def _turned(x: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    return turned(x, int(rng.integers(len(HEADINGS))), bool(rng.integers(2)))


def fit_head(states: Labelled, config: EvasionConfig, rng: np.random.Generator, seed: int) -> EvasionHead:
    """A head (initial weights from `seed`) fitted to every choice's label."""
    torch.manual_seed(seed)
    head = EvasionHead(config.width)
    optimizer = torch.optim.Adam(head.parameters(), lr=config.lr)
    head.train()
    for _ in range(config.epochs):
        order = rng.permutation(len(states))
        for start in range(0, len(states), config.batch):
            rows = order[start:start + config.batch]
            x, perm = _turned(states.x[rows], rng)
            y = np.empty_like(states.short[rows])
            y[:, perm] = states.short[rows]
            each = nn.functional.binary_cross_entropy_with_logits(
                head(torch.from_numpy(x)), torch.from_numpy(y), reduction="none").mean(dim=0)
            loss = each[0] + each[1:].mean()
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            optimizer.step()
    return head.eval()


def person_targets(states: Labelled, margin: float, chunk: int = 4096) -> np.ndarray:
    """(S, NEAR, CHOICES) each person's shortfall (m) for every choice at every state, in chunks of
    `chunk` states (a turned batch's are these, its choices permuted as `turned` says)."""
    return np.concatenate([person_shortfalls(states.x[i:i + chunk], margin, HORIZON)[0]
                           for i in range(0, len(states), chunk)])


def fit_shortfall(states: Labelled, config: EvasionConfig, rng: np.random.Generator, seed: int) -> ShortfallNet:
    """A shortfall network (initial weights from `seed`) fitted to each person's shortfall."""
    targets = person_targets(states, config.margin)
    torch.manual_seed(seed)
    net = ShortfallNet(config.width)
    optimizer = torch.optim.Adam(net.parameters(), lr=config.lr)
    net.train()
    for _ in range(config.shortfall_batches):
        rows = rng.integers(len(states), size=config.batch)
        x, perm = _turned(states.x[rows], rng)
        truth = np.empty_like(targets[rows])
        truth[..., perm] = targets[rows]
        predicted, present = net.person(torch.from_numpy(x))
        weight = present.float()[..., None]
        error = (PENALTY * (predicted - torch.from_numpy(truth))).pow(2) * weight
        loss = error.sum() / weight.sum().clamp_min(1.0) / truth.shape[-1]
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
    return net.eval()


def walk_seed(config: EvasionConfig, round_: int) -> int:
    """The noise seed of a round's walk (round 0: the generator alone)."""
    return config.seed * 1000 + round_


def _networks(head: EvasionHead, shortfall: ShortfallNet, width: int) -> Evasion:
    networks = Evasion(width)
    networks.head.load_state_dict(head.state_dict())
    networks.shortfall.load_state_dict(shortfall.state_dict())
    return networks.eval()


def train_evasion(
    record: ckpt.Checkpoint,
    path: Path,
    episodes: Episodes,
    config: EvasionConfig,
    save: Callable[[ckpt.Checkpoint], None],
    on_round: Callable[[int, dict[str, Any]], object] | None = None,
    command: str = "",
) -> ckpt.Checkpoint:
    """Train the evasion networks of a finished NaviGAN-R checkpoint (read from `path`) on `episodes`,
    or resume their training.

    `record.evasion` holds the training: the command that trained them (`command`; the checkpoint's
    own is the generator's), its settings, one entry per finished walk (`states`: what it visited;
    `states_total`: what the head after it trained on; the share of planned steps that fall short;
    CPU seconds), until the last round what resuming needs, and then the networks' weights. The
    checkpoint is saved (`save`) after every walk; `on_round(round, entry)` is called as each
    finishes (round 0 is the generator's own walk). Seeds, from `config.seed` s: walk r's noise
    s * 1000 + r, the initial weights of the shortfall network s * 1000 and of the head fitted after
    walk r s * 1000 + 500 + r, the batches' order and turns one generator seeded with s.

    Raises:
        NaviganError: the checkpoint is unfinished, not a NaviGAN-R with noise, or holds evasion
            networks trained with other settings.
    """
    if not record.finished:
        raise NaviganError("evasion training starts from a finished training; finish it first")
    if not (record.model.variant.resistance and record.model.variant.fluctuation):
        raise NaviganError(f"evasion networks are trained for NaviGAN-R only, not {record.model.model}")
    training = record.evasion or {"command": command, "settings": asdict(config), "rounds": [], "resume": None,
                                  "weights": None}
    if training["settings"] != asdict(config):
        raise NaviganError(f"the checkpoint holds evasion networks trained with other settings ({training['settings']}); "
                           "choose another --out")
    if training["weights"] is not None:
        return record
    resume = training["resume"] or {"heads": [], "shortfall": None, "rng": None}
    generator = record.build_generator()
    rng = np.random.default_rng(config.seed)
    if resume["rng"] is not None:
        rng.bit_generator.state = resume["rng"]
    shortfall = ShortfallNet(config.width)
    if resume["shortfall"] is not None:
        shortfall.load_state_dict(resume["shortfall"])
    parts: list[Labelled] = []
    for round_ in range(config.rounds + 1):
        began = time.process_time()
        networks = None
        if round_:
            head = EvasionHead(config.width)
            head.load_state_dict(resume["heads"][round_ - 1])
            networks = _networks(head, shortfall.eval(), config.width)
        walker = Policy(generator, False, record.model.noise, walk_seed(config, round_), path, evasion=networks)
        parts.append(walk(walker, episodes, config.margin))
        if round_ < len(training["rounds"]):
            continue  # walked again only to gather its states
        if round_ == 0:
            shortfall = fit_shortfall(parts[0], config, rng, config.seed * 1000)
            resume["shortfall"] = ckpt.weights(shortfall)
        head = fit_head(join(parts), config, rng, walk_seed(config, round_) + 500)
        resume["heads"].append(ckpt.weights(head))
        resume["rng"] = rng.bit_generator.state
        entry = {"round": round_, "states": len(parts[-1]), "states_total": sum(len(p) for p in parts),
                 "planned_short": round(float(parts[-1].short[:, 0].mean()), 4),
                 "cpu_seconds": round(time.process_time() - began, 1)}
        training["command"] = command  # the one that finishes it
        training["rounds"].append(entry)
        last = round_ == config.rounds
        training["resume"] = None if last else resume
        if last:
            training["weights"] = ckpt.weights(_networks(head, shortfall, config.width))
        record.evasion = training
        save(record)
        if on_round is not None:
            on_round(round_, entry)
    return record
