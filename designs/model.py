"""Model terms and the model matrix.

A model is written with keywords (`main`, `interactions`, `quadratic`) or explicit terms,
joined by `+`: `Peds + Direction + Peds*Direction + Peds^2` (JMP also writes `Peds*Peds`).
A term is a product of factors, each raised to a power up to 3 (`A*B*C`, `A^3`, `A*B^2`);
only numeric factors take powers above 1. The intercept is always the first column.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from itertools import combinations, product

import numpy as np

from designs.errors import DesignError
from designs.factors import BlockFactor, CategoricalFactor, ContinuousFactor, DesignFactor, column_labels, is_numeric, main_effect_basis

KEYWORDS = ("main", "interactions", "quadratic")
_FACTOR_POWER = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*(?:\^\s*([0-9]+))?\s*$")
#: Highest power of one factor in a term, and most factors in one term.
MAX_POWER = 3
MAX_TERM_FACTORS = 3


@dataclass(frozen=True)
class Term:
    """A product of factor powers: ((factor index, power), ...); () is the intercept."""

    parts: tuple[tuple[int, int], ...]

    @property
    def order(self) -> int:
        return sum(power for _, power in self.parts)


@dataclass(frozen=True)
class Model:
    """The design factors and the terms of the linear model fitted to the runs."""

    factors: tuple[DesignFactor, ...]
    terms: tuple[Term, ...]

    def term_name(self, term: Term) -> str:
        if not term.parts:
            return "Intercept"
        return "*".join(self.factors[i].name + (f"^{power}" if power > 1 else "") for i, power in term.parts)

    @property
    def term_names(self) -> list[str]:
        return [self.term_name(term) for term in self.terms]

    def term_columns(self, term: Term) -> list[str]:
        """Labels of the columns a term contributes, e.g. `Peds*Direction[Parallel]`."""
        labels = [""]
        for i, power in term.parts:
            labels = [f"{a}*{b}" if a else b for a in labels for b in column_labels(self.factors[i], power)]
        return labels if term.parts else ["Intercept"]

    @property
    def columns(self) -> list[str]:
        return [label for term in self.terms for label in self.term_columns(term)]

    @property
    def term_slices(self) -> list[slice]:
        """The slice of model-matrix columns that belongs to each term."""
        slices, start = [], 0
        for term in self.terms:
            width = len(self.term_columns(term))
            slices.append(slice(start, start + width))
            start += width
        return slices

    @property
    def p(self) -> int:
        return len(self.columns)

    def power(self, i: int) -> int:
        """The highest power of factor i in any term (0 when no term uses it)."""
        return max((power for term in self.terms for j, power in term.parts if j == i), default=0)

    @property
    def curved_continuous(self) -> list[int]:
        """Indices of the continuous factors some term raises to a power above 1: their optima may lie off the grid."""
        return [i for i, f in enumerate(self.factors) if isinstance(f, ContinuousFactor) and self.power(i) >= 2]

    def grid(self, i: int) -> np.ndarray:
        """The candidate settings of factor i: its levels; -1, 0, 1 for a continuous factor (5 points when cubed)."""
        factor = self.factors[i]
        if isinstance(factor, ContinuousFactor) and self.power(i) == 3:
            return np.linspace(-1.0, 1.0, 5)
        return factor.candidate_settings

    def moment_matrix(self) -> np.ndarray:
        """(p, p) the mean of f(x) f(x)' over the design region, exact by product quadrature: continuous
        factors uniform on [-1, 1] (Gauss-Legendre with enough nodes for their power), levels equally likely."""
        nodes, weights = [], []
        for i, factor in enumerate(self.factors):
            if isinstance(factor, ContinuousFactor):
                x, w = np.polynomial.legendre.leggauss(max(self.power(i), 1) + 1)
                nodes.append(x)
                weights.append(w / w.sum())
            else:
                settings = factor.candidate_settings
                nodes.append(settings)
                weights.append(np.full(len(settings), 1.0 / len(settings)))
        points = np.array(list(product(*nodes)))
        w = np.prod(np.array(list(product(*weights))), axis=1)
        f = self.matrix(points)
        return f.T @ (w[:, None] * f)

    def column_codes(self) -> tuple[np.ndarray, np.ndarray]:
        """(p, MAX_TERM_FACTORS) for the compiled rows: each column's factors (-1: none) and, per factor,
        its power (numeric) or its effect-coding column (categorical)."""
        factor_of = np.full((self.p, MAX_TERM_FACTORS), -1, dtype=np.int64)
        code = np.zeros((self.p, MAX_TERM_FACTORS), dtype=np.int64)
        column = 0
        for term in self.terms:
            combos: list[list[tuple[int, int]]] = [[]]
            for i, power in term.parts:
                codes = range(len(self.factors[i].levels) - 1) if isinstance(self.factors[i], CategoricalFactor) else [power]
                combos = [[*combo, (i, c)] for combo in combos for c in codes]
            for combo in combos:
                for q, (i, c) in enumerate(combo):
                    factor_of[column, q], code[column, q] = i, c
                column += 1
        return factor_of, code

    def matrix(self, settings: np.ndarray) -> np.ndarray:
        """(n, p) model matrix of design points given as (n, k) factor settings."""
        settings = np.atleast_2d(np.asarray(settings, dtype=float))
        blocks = [self.term_block(term, settings) for term in self.terms]
        return np.hstack(blocks)

    def term_block(self, term: Term, settings: np.ndarray) -> np.ndarray:
        """(n, c) the columns of one term: the row-wise Kronecker product of its parts."""
        block = np.ones((settings.shape[0], 1))
        for i, power in term.parts:
            basis = main_effect_basis(self.factors[i], settings[:, i], power)
            block = (block[:, :, None] * basis[:, None, :]).reshape(settings.shape[0], -1)
        return block


def parse_model(expression: str, factors: tuple[DesignFactor, ...], fixed: tuple[str, ...] = ()) -> Model:
    """Build a Model from keywords and explicit terms; DesignError names the bad term.

    `fixed` names the study's fixed factors, only to say why they cannot be terms.
    """
    index = {factor.name: i for i, factor in enumerate(factors)}
    terms: list[Term] = [Term(())]
    pieces = [piece.strip() for piece in expression.split("+")]
    if not any(pieces):
        raise DesignError("model: empty model; give keywords (main, interactions, quadratic) or terms")
    for piece in pieces:
        if not piece:
            raise DesignError(f"model {expression!r}: empty term between '+' signs")
        for term in _expand(piece, factors, index, fixed):
            if term not in terms:
                terms.append(term)
    return Model(factors, tuple(terms))


def _expand(
    piece: str, factors: tuple[DesignFactor, ...], index: dict[str, int], fixed: tuple[str, ...]
) -> list[Term]:
    """The terms one `+`-separated piece stands for."""
    treatments = [i for i, f in enumerate(factors) if not isinstance(f, BlockFactor)]  # keywords leave the block out
    if piece == "main":
        return [Term(((i, 1),)) for i in treatments]
    if piece == "interactions":
        return [Term(((i, 1), (j, 1))) for i, j in combinations(treatments, 2)]
    if piece == "quadratic":
        return [Term(((i, 2),)) for i in treatments if _can_take_power(factors[i], 2)]
    powers: dict[int, int] = {}
    for part in piece.split("*"):
        match = _FACTOR_POWER.match(part)
        if not match:
            raise DesignError(f"model: cannot read term {piece!r}; expected A, A*B, A^2, A*B*C or A^3 (or {', '.join(KEYWORDS)})")
        name, power = match.group(1), int(match.group(2) or 1)
        if name in fixed:
            raise DesignError(f"model: term {piece!r} uses {name}, a fixed factor, which is no model term")
        if name not in index:
            known = ", ".join(index) or "none"
            raise DesignError(f"model: unknown term {piece!r}: no design factor {name!r} (design factors: {known})")
        powers[index[name]] = powers.get(index[name], 0) + power
    if len(powers) > MAX_TERM_FACTORS:
        raise DesignError(f"model: term {piece!r} joins {len(powers)} factors; at most {MAX_TERM_FACTORS}")
    for i, power in powers.items():
        if not 1 <= power <= MAX_POWER:
            raise DesignError(f"model: term {piece!r} raises {factors[i].name} to the power {power}; powers run from 1 to {MAX_POWER}")
        if power > 1 and not _can_take_power(factors[i], power):
            raise DesignError(f"model: term {piece!r} needs a numeric factor with at least {power + 1} levels; "
                              f"{factors[i].name} is not")
    return [Term(tuple(sorted(powers.items())))]


def _can_take_power(factor: DesignFactor, power: int) -> bool:
    """Whether factor^power is estimable: numeric, with more distinct levels than the power (continuous always)."""
    if isinstance(factor, CategoricalFactor) or not is_numeric(factor):
        return False
    return isinstance(factor, ContinuousFactor) or len(factor.candidate_settings) > power


