"""What a model is (sizes, variant) and how it is trained, as plain records stored in checkpoints."""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from typing import Any

from navigan.data import Sampling
from navigan.errors import NaviganError


@dataclass(frozen=True)
class Variant:
    """Which generator a model uses and which losses train it.

    Attributes:
        generator: "navigan" (intention + social force) or "goal-social-lstm".
        fde: FDE loss on the intention output.
        adversarial: GAN loss against the social-aware discriminator.
        resistance: resistance loss against the other agents' positions.
        fluctuation: sample the fluctuation noise z (else z = 0, in training and at run time).
    """

    generator: str
    fde: bool
    adversarial: bool
    resistance: bool
    fluctuation: bool


#: The four trainable models of the paper.
MODELS: dict[str, Variant] = {
    "goal-social-lstm": Variant("goal-social-lstm", fde=False, adversarial=False, resistance=False, fluctuation=False),
    "navil2": Variant("navigan", fde=True, adversarial=False, resistance=False, fluctuation=False),
    "navigan": Variant("navigan", fde=True, adversarial=True, resistance=False, fluctuation=True),
    "navigan-r": Variant("navigan", fde=True, adversarial=True, resistance=True, fluctuation=True),
}


def variant(model: str) -> Variant:
    """The variant a model name stands for.

    Raises:
        NaviganError: unknown model.
    """
    if model not in MODELS:
        raise NaviganError(f"unknown model {model!r}: choose one of {', '.join(MODELS)}")
    return MODELS[model]


@dataclass(frozen=True)
class ModelConfig:
    """Network sizes (the paper uses hidden size 32 throughout).

    Attributes:
        model: a key of MODELS.
        hidden: LSTM encoder state size.
        embed: size of the linear embedding of 2-D inputs (positions, forces, displacements).
        goal: size of the goal embedding joined to the decoder's initial state.
        pool: size of PoolNet's output V_i.
        noise: size of the fluctuation noise z.
        mlp: hidden width of the small MLPs (NN_spatial, NN_social, NN_embed, the score).
        pair_pool: pool in the generator with PairPoolNet (a hidden layer of width `mlp` per pair
            of agents, fed a constant-velocity look-ahead) instead of the paper's PoolNet; the
            discriminator keeps PoolNet.
    """

    model: str
    hidden: int = 32
    embed: int = 16
    goal: int = 16
    pool: int = 32
    noise: int = 8
    mlp: int = 32
    pair_pool: bool = False

    @property
    def variant(self) -> Variant:
        return variant(self.model)


@dataclass(frozen=True)
class TrainConfig:
    """How a model is trained (the paper: batch 32 targets, Adam 1e-3, 500 epochs).

    Attributes:
        split: the leave-one-scene-out split, or "all".
        epochs: most epochs to run.
        patience: stop after this many epochs without a better validation loss (None: never).
        batch: target agents per batch (whole scenes, so a batch may hold fewer).
        lr: Adam learning rate of generator and discriminator.
        seed: seeds weights, batch order and noise.
        d_safe: the resistance loss's safe distance (m).
        w_l2, w_fde, w_adversarial, w_resistance: loss weights.
        clip: gradient norm clip.
        augment: turn each training window by a random angle and mirror half of them.
        resist_intention: the resistance loss's gradient also reaches the intention generator
            (the paper's L_resist on y_hat); else only the social-force generator.
        resist_beyond_truth: the resistance loss asks for no more room than the recorded person
            kept from each agent (see `losses.resistance_loss`).
        resist_steps: the resistance loss scores the plan's first this many way-points (None: all).
        encounters: synthetic collision-course rows per target of a batch (`navigan.encounters`).
        force_size: weight of the social force's squared size beside its squared changes in
            encounter rows (`losses.encounter_losses`).
        encounter_crowd: fraction of encounter walkers who keep their window's whole crowd (the
            others keep only the agent they meet, or nobody).
    """

    split: str
    epochs: int = 500
    patience: int | None = None
    batch: int = 32
    lr: float = 1e-3
    seed: int = 0
    d_safe: float = 0.5
    w_l2: float = 1.0
    w_fde: float = 1.0
    w_adversarial: float = 1.0
    w_resistance: float = 1.0
    clip: float = 1.0
    augment: bool = False
    resist_intention: bool = True
    resist_beyond_truth: bool = False
    resist_steps: int | None = None
    encounters: float = 0.0
    encounter_crowd: float = 0.0
    force_size: float = 0.1

    @property
    def sampling(self) -> Sampling:
        """How training batches draw goals (the last future position, as the paper) and turn scenes."""
        return Sampling(augment=self.augment)


@dataclass(frozen=True)
class ClosedLoopConfig:
    """How NaviGAN-R is fine-tuned on the states it visits walking playback episodes (`navigan.closed_loop`).

    Attributes:
        rounds: walk-label-train rounds (DAgger's iterations).
        epochs: passes over all states gathered so far, per round.
        batch: states per batch.
        lr: Adam learning rate.
        seed: seeds the walks' fluctuation noise and the batch order.
        margin: the shield's margin (m) that labels the states (`navigan.shield`), and the
            clearance the hinge term asks of the first step.
        w_first: weight of the first way-point's squared distance from the teacher's, on the states
            where the shield keeps the plan.
        w_rest: weight of the other way-points' squared distance from the teacher's plan.
        w_hinge: weight of the first step's squared shortfall under `margin` from everyone's
            constant-velocity forecast.
    """

    rounds: int = 2
    epochs: int = 2
    batch: int = 512
    lr: float = 1e-3
    seed: int = 0
    margin: float = 0.5
    w_first: float = 10.0
    w_rest: float = 1.0
    w_hinge: float = 50.0


@dataclass(frozen=True)
class EvasionConfig:
    """How NaviGAN-R's evasion networks are trained on the states it visits walking playback episodes
    (`navigan.evasion_training`).

    Attributes:
        rounds: DAgger rounds after the first walk (of the generator alone); each walks the networks
            trained so far and trains a new head on all the states gathered.
        epochs: passes of the head's training over all states, per round.
        batch: states per batch.
        lr: Adam learning rate of both networks.
        seed: seeds the walks' fluctuation noise, the networks' initial weights, batch order and turns.
        margin: the shield's margin (m) that labels the states (`navigan.shield`).
        width: hidden units of each network's two layers.
        shortfall_batches: batches the shortfall network is trained on (once, on the first walk's states).
    """

    rounds: int = 2
    epochs: int = 40
    batch: int = 512
    lr: float = 1e-3
    seed: int = 0
    margin: float = 0.5
    width: int = 128
    shortfall_batches: int = 3000


def to_dict(record: Any) -> dict[str, Any]:
    """A config record as a plain dict."""
    return asdict(record)


def from_dict(cls: type, values: dict[str, Any]) -> Any:
    """A config record from a dict, refusing unknown fields.

    Raises:
        NaviganError: a field is not one of the record's.
    """
    known = {f.name for f in fields(cls)}
    unknown = sorted(set(values) - known)
    if unknown:
        raise NaviganError(f"unknown {cls.__name__} fields {unknown}")
    return cls(**values)
