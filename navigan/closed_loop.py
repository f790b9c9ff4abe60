"""Closed-loop fine-tuning of NaviGAN-R: the shield's test taught to the network, DAgger-style.

Trained on recorded windows, the network meets in playback the states its own earlier steps led
to, which no recording holds, and there it comes closer to people than it learned to keep (a
distribution shift). Each round walks the network being tuned (the learner) through playback
episodes cut from the split's training recordings, never its test scene, records every state it
visits, and fine-tunes it on all the rounds' states so far. At each state the starting network
(the teacher, frozen) plans too, and the shield (`navigan.shield`) tests the teacher's first step:
held for the shield's horizon, does it keep `margin` from everyone's constant-velocity forecast?
The learner's social-force branch is trained (the intention branch, which does not see the
others, stays as it was) on three terms:

- `first`: its first way-point's squared distance from the teacher's, on the states where the
  shield keeps the teacher's step (it keeps what needs no change);
- `rest`: its other way-points' squared distance from the teacher's (it keeps the route and pace,
  so arrival holds);
- `hinge`: its own first step's squared shortfall under `margin` from each forecast position,
  summed over the others and the horizon: the shield's test, made differentiable.

Where the teacher's step fails the test, the first way-point answers to the hinge alone: copying
the shield's replacement (the cheapest move of a ring) would average its left and right detours
into an unsafe middle. Rounds are resumable: until the last round is done the checkpoint's kept
weights stay the teacher's, and it keeps the learner's weights after each round and the state of
the batch order's generator, so an interrupted tuning walks the finished rounds again with the
weights that walked them and continues.
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from navigan import checkpoint as ckpt
from navigan.config import ClosedLoopConfig
from navigan.data import fill_tracks
from navigan.errors import NaviganError
from navigan.generators import NaviganGenerator
from navigan.playback.episodes import Episodes
from navigan.playback.rollout import Policy, Visit, roll_out
from navigan.shield import HORIZON, forecast, shielded_steps

#: Generator parameters the tuning leaves alone: the intention branch, blind to the others.
FROZEN_PREFIX = "intention_"
#: A shielded step this close (m) to the planned one is the plan kept.
KEPT = 1e-4
#: Stand-in for an absent agent's forecast position (m): far enough to never fall short.
FAR = 1e6


@dataclass(frozen=True)
class States:
    """Visited states, each with the teacher's plan there (S states, N others at most).

    Attributes:
        histories: (S, T_OBS, 2) the walker's last positions.
        around: (S, N, T_OBS, 2) the others' last positions, NaN where absent or padding.
        goals: (S, 2) the sub-goals the walker was handed.
        noise: (S, noise) the fluctuation noise drawn there.
        teacher: (S, T_PRED, 2) the teacher's plan.
        kept: (S,) whether the shield keeps the teacher's first step there.
    """

    histories: np.ndarray
    around: np.ndarray
    goals: np.ndarray
    noise: np.ndarray
    teacher: np.ndarray
    kept: np.ndarray

    def __len__(self) -> int:
        return len(self.histories)

    def rows(self, index: slice) -> States:
        return States(*(getattr(self, name)[index] for name in self.__dataclass_fields__))


def join(parts: Sequence[States]) -> States:
    """One set of states from several, the others padded with NaN to the widest."""
    width = max(p.around.shape[1] for p in parts)
    columns = {name: np.concatenate([getattr(p, name) for p in parts]) for name in States.__dataclass_fields__
               if name != "around"}
    around = [np.concatenate([p.around, np.full((len(p), width - p.around.shape[1]) + p.around.shape[2:], np.nan,
                                                 dtype=np.float32)], axis=1) for p in parts]
    return States(around=np.concatenate(around), **columns)


@torch.no_grad()
def visited(learner: Policy, teacher: Policy, episodes: Episodes, margin: float) -> list[States]:
    """The states `learner` visits walking `episodes` (no shield), one part per step, each with the
    teacher's plan and whether the shield keeps its first step (it keeps a step that falls short
    where every move of its ring costs more)."""
    if not learner.noise_size:
        raise NaviganError("closed-loop tuning needs a model with fluctuation noise (navigan-r)")
    parts: list[States] = []

    def record(seen: Visit) -> None:
        assert seen.noise is not None
        plan = teacher.plan(seen.histories, seen.around, seen.goals, seen.noise)[0]
        checked = shielded_steps(seen.histories[:, -1], plan[:, 0].copy(), seen.around, margin)
        parts.append(States(seen.histories, seen.around, seen.goals.astype(np.float32), seen.noise, plan,
                            np.linalg.norm(checked - plan[:, 0], axis=-1) <= KEPT))

    roll_out(learner, episodes, visit=record)
    return parts


def batches(parts: Sequence[States], size: int, rng: np.random.Generator) -> Iterator[States]:
    """The states in batches of about `size`: each part cut into pieces of at most `size`, the
    pieces shuffled by `rng` and joined until a batch holds `size` or more."""
    pieces = [(p, slice(i, min(len(p), i + size))) for p in parts for i in range(0, len(p), size)]
    group: list[States] = []
    count = 0
    for k in rng.permutation(len(pieces)):
        part, rows = pieces[k]
        group.append(part.rows(rows))
        count += rows.stop - rows.start
        if count >= size:
            yield join(group)
            group, count = [], 0
    if group:
        yield join(group)


def losses(generator: NaviganGenerator, states: States, margin: float) -> dict[str, torch.Tensor]:
    """The tuning's terms on some states (see the module docstring)."""
    filled, present = fill_tracks(states.around)
    scene = torch.from_numpy(np.concatenate([states.histories[:, None], filled], axis=1).astype(np.float32))
    mask = torch.from_numpy(np.concatenate([np.ones((len(states), 1), dtype=bool), present], axis=1))
    targets = torch.zeros_like(mask)
    targets[:, 0] = True
    waypoints = generator(scene, mask, torch.from_numpy(states.goals), targets=targets,
                          noise=torch.from_numpy(states.noise)).waypoints
    error = (waypoints - torch.from_numpy(states.teacher)).pow(2).sum(dim=-1)
    kept = torch.from_numpy(states.kept.astype(np.float32))
    position = torch.from_numpy(states.histories[:, -1])
    held = position[:, None] + (waypoints[:, 0] - position)[:, None] * torch.arange(1, HORIZON + 1)[:, None]
    ahead = torch.from_numpy(np.nan_to_num(forecast(states.around, HORIZON), nan=FAR).astype(np.float32))
    gap = (held[:, None] - ahead).pow(2).sum(dim=-1).clamp_min(1e-12).sqrt()
    return {
        "first": (error[:, 0] * kept).sum() / kept.sum().clamp_min(1.0),
        "rest": error[:, 1:].mean(),
        "hinge": (margin - gap).clamp_min(0).pow(2).sum(dim=(1, 2)).mean(),
    }


def train_round(generator: NaviganGenerator, parts: Sequence[States], config: ClosedLoopConfig,
                rng: np.random.Generator) -> dict[str, float]:
    """`config.epochs` passes over the states with a fresh Adam; the last epoch's mean terms."""
    params = [p for name, p in generator.named_parameters() if not name.startswith(FROZEN_PREFIX)]
    optimizer = torch.optim.Adam(params, lr=config.lr)
    weights = {"first": config.w_first, "rest": config.w_rest, "hinge": config.w_hinge}
    generator.train()
    means: dict[str, float] = {}
    for _ in range(config.epochs):
        totals = dict.fromkeys(weights, 0.0)
        count = 0
        for batch in batches(parts, config.batch, rng):
            terms = losses(generator, batch, config.margin)
            loss = sum(weights[k] * v for k, v in terms.items())
            optimizer.zero_grad(set_to_none=True)
            loss.backward()  # type: ignore[union-attr]
            torch.nn.utils.clip_grad_norm_(params, 1.0)
            optimizer.step()
            for k, v in terms.items():
                totals[k] += v.item()
            count += 1
        means = {k: v / count for k, v in totals.items()}
    generator.eval()
    return means


def walk_seed(config: ClosedLoopConfig, round_: int) -> int:
    """The noise seed of a round's walk (1-based round)."""
    return config.seed * 1000 + round_


def tune(
    record: ckpt.Checkpoint,
    path: Path,
    episodes: Episodes,
    config: ClosedLoopConfig,
    save: Callable[[ckpt.Checkpoint], None],
    on_round: Callable[[int, dict[str, Any]], object] | None = None,
) -> ckpt.Checkpoint:
    """Fine-tune a finished NaviGAN-R checkpoint (read from `path`) in closed loop on `episodes`, or
    resume its tuning.

    `record.closed_loop` holds the tuning: its settings, one entry per finished round (`states`:
    the states its walk visited; `states_total`: all rounds' so far, which it trained on; its CPU
    seconds and last epoch's mean terms) and, until the last round, what resuming needs. The
    checkpoint is saved (`save`) after every round; `on_round(round, entry)` is called as each
    finishes. Evasion networks trained beside the starting weights are dropped with them.

    Raises:
        NaviganError: the checkpoint is unfinished, not a NaviGAN-R with noise, or holds a tuning
            with other settings.
    """
    if not record.finished:
        raise NaviganError("closed-loop tuning starts from a finished training; finish it first")
    if not (record.model.variant.resistance and record.model.variant.fluctuation):
        raise NaviganError(f"closed-loop tuning tunes NaviGAN-R only, not {record.model.model}")
    tuning = record.closed_loop or {"settings": asdict(config), "rounds": [], "resume": None}
    if tuning["settings"] != asdict(config):
        raise NaviganError(f"the checkpoint holds a closed-loop tuning with other settings ({tuning['settings']}); "
                           "choose another --out")
    if len(tuning["rounds"]) >= config.rounds:
        return record
    resume = tuning["resume"] or {"learners": [], "rng": None}
    teacher_net = record.build_generator()  # the kept weights stay the starting network's until the last round
    learner_net = copy.deepcopy(teacher_net)
    teacher = Policy(teacher_net, False, record.model.noise, 0, path)
    rng = np.random.default_rng(config.seed)
    if resume["rng"] is not None:
        rng.bit_generator.state = resume["rng"]
    parts: list[States] = []
    for round_ in range(1, config.rounds + 1):
        done = round_ <= len(tuning["rounds"])
        began = time.process_time()
        # a finished round's walk is taken again with the weights that walked it
        if round_ > 1:
            learner_net.load_state_dict(resume["learners"][round_ - 2])
        learner = Policy(learner_net, False, record.model.noise, walk_seed(config, round_), path)
        walk = visited(learner, teacher, episodes, config.margin)
        parts += walk
        if done:
            continue
        means = train_round(learner_net, parts, config, rng)
        entry = {"round": round_, "states": sum(len(p) for p in walk), "states_total": sum(len(p) for p in parts),
                 "cpu_seconds": round(time.process_time() - began, 1), "train": {k: round(v, 6) for k, v in means.items()}}
        tuning["rounds"].append(entry)
        resume["learners"].append(ckpt.weights(learner_net))
        resume["rng"] = rng.bit_generator.state
        last = round_ == config.rounds
        tuning["resume"] = None if last else resume
        record.closed_loop = tuning
        if last:
            record.generator = ckpt.weights(learner_net)
            record.evasion = None  # taught on the starting network's plans, they no longer fit
        save(record)
        if on_round is not None:
            on_round(round_, entry)
    return record
