"""Factors of a study and their coding into model columns.

A design point holds one *setting* per design factor: the coded value in [-1, 1] for a
numeric factor, the level index for a categorical one. Fixed factors are recorded in the
plan but are no model term, so they have no setting.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from designs.errors import DesignError


class _LinearCoding:
    """Numeric coding: low -> -1, high -> +1."""

    low: float
    high: float

    def encode(self, value: float) -> float:
        return (float(value) - 0.5 * (self.low + self.high)) / (0.5 * (self.high - self.low))

    def decode(self, setting: float) -> float:
        return 0.5 * (self.low + self.high) + 0.5 * (self.high - self.low) * float(setting)


@dataclass(frozen=True)
class ContinuousFactor(_LinearCoding):
    """A numeric factor that may take any value in [low, high]."""

    name: str
    low: float
    high: float
    units: str = ""

    kind = "continuous"

    @property
    def candidate_settings(self) -> np.ndarray:
        return np.array([-1.0, 0.0, 1.0])


@dataclass(frozen=True)
class DiscreteFactor(_LinearCoding):
    """A numeric factor restricted to a few levels, coded linearly onto [-1, 1]."""

    name: str
    levels: tuple[float, ...]
    units: str = ""

    kind = "discrete"

    @property
    def low(self) -> float:
        return min(self.levels)

    @property
    def high(self) -> float:
        return max(self.levels)

    @property
    def candidate_settings(self) -> np.ndarray:
        return np.array([self.encode(v) for v in self.levels])

    def decode(self, setting: float) -> float:
        """The level nearest to the setting (settings of a discrete factor are its levels)."""
        raw = super().decode(setting)
        return min(self.levels, key=lambda level: abs(level - raw))


@dataclass(frozen=True)
class CategoricalFactor:
    """A factor with named levels, effect-coded: level j < k-1 is e_j, the last level is -1s.

    `blind` marks the factor whose levels are hidden behind opaque arm labels.
    """

    name: str
    levels: tuple[str, ...]
    blind: bool = False

    kind = "categorical"

    @property
    def candidate_settings(self) -> np.ndarray:
        return np.arange(len(self.levels), dtype=float)

    @property
    def effect_coding(self) -> np.ndarray:
        """(k, k-1) the main-effect columns of each level."""
        k = len(self.levels)
        return np.vstack([np.eye(k - 1), -np.ones((1, k - 1))])

    def decode(self, setting: float) -> str:
        return self.levels[int(setting)]

    def encode(self, value: str) -> float:
        return float(self.levels.index(value))


@dataclass(frozen=True)
class BlockFactor(CategoricalFactor):
    """The block of each run (`blocks = b` in the spec): levels "1" .. "b", equal blocks in run order.

    The exchange never moves it; its effect-coded columns join the model. study.toml holds only `blocks`.
    """

    @classmethod
    def of(cls, blocks: int) -> BlockFactor:
        return cls("Block", tuple(str(b + 1) for b in range(blocks)))


@dataclass(frozen=True)
class CovariateFactor(ContinuousFactor):
    """A numeric value measured for each run in advance (a participant's age, the day's wind), coded from its
    observed range; run j takes values[j], and the exchange chooses the other factors around it."""

    values: tuple[float, ...] = ()

    kind = "covariate"


@dataclass(frozen=True)
class FixedFactor:
    """A factor held at one value: recorded in every run, never a model term."""

    name: str
    value: float | str
    units: str = ""

    kind = "fixed"


DesignFactor = ContinuousFactor | DiscreteFactor | CategoricalFactor
Factor = ContinuousFactor | DiscreteFactor | CategoricalFactor | FixedFactor


def plain(value: float | str) -> float | int | str:
    """Whole numbers as int (2, not 2.0), so files show levels as the researcher wrote them."""
    if isinstance(value, float) and value.is_integer():
        return int(value)
    return value


def is_numeric(factor: Factor) -> bool:
    """Whether the factor is coded as a number (continuous or discrete numeric)."""
    return isinstance(factor, (ContinuousFactor, DiscreteFactor))


def main_effect_basis(factor: DesignFactor, settings: np.ndarray, power: int = 1) -> np.ndarray:
    """(n, c) the columns a factor contributes to a term: x**power, or its effect coding."""
    settings = np.asarray(settings, dtype=float)
    if isinstance(factor, CategoricalFactor):
        return factor.effect_coding[settings.astype(int)]
    return (settings**power)[:, None]


def column_labels(factor: DesignFactor, power: int = 1) -> list[str]:
    """JMP-style labels of the columns of `main_effect_basis`."""
    if isinstance(factor, CategoricalFactor):
        return [f"{factor.name}[{level}]" for level in factor.levels[:-1]]
    return [factor.name if power == 1 else f"{factor.name}^{power}"]


def validate_factor(factor: Factor, where: str) -> None:
    """Raise DesignError, prefixed by `where`, when a factor's levels or range cannot be coded."""
    if isinstance(factor, ContinuousFactor):
        if not factor.low < factor.high:
            raise DesignError(f"{where}: low ({factor.low}) must be below high ({factor.high})")
    elif isinstance(factor, (DiscreteFactor, CategoricalFactor)):
        levels = factor.levels
        if len(levels) < 2:
            raise DesignError(f"{where}: needs at least 2 levels, got {len(levels)}")
        if isinstance(factor, CategoricalFactor) and any(not str(level).strip() for level in levels):
            raise DesignError(f"{where}: empty level name in {list(levels)}")
        seen = set()
        for level in levels:
            if level in seen:
                raise DesignError(f"{where}: duplicate level {level!r}")
            seen.add(level)
