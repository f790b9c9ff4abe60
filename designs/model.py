"""Model terms and the model matrix.

A model is written with keywords (`main`, `interactions`, `quadratic`) or explicit terms,
joined by `+`: `Peds + Direction + Peds*Direction + Peds^2` (JMP also writes `Peds*Peds`).
The intercept is always the first column.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from itertools import combinations

import numpy as np

from designs.errors import DesignError
from designs.factors import CategoricalFactor, DesignFactor, column_labels, is_numeric, main_effect_basis

KEYWORDS = ("main", "interactions", "quadratic")
_NAME = r"[A-Za-z_][A-Za-z0-9_]*"
_TERM = re.compile(rf"^\s*({_NAME})\s*(?:\^\s*(2)|\*\s*({_NAME}))?\s*$")


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
        return "*".join(self.factors[i].name + ("^2" if power == 2 else "") for i, power in term.parts)

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
    if piece == "main":
        return [Term(((i, 1),)) for i in range(len(factors))]
    if piece == "interactions":
        return [Term(((i, 1), (j, 1))) for i, j in combinations(range(len(factors)), 2)]
    if piece == "quadratic":
        return [Term(((i, 2),)) for i, f in enumerate(factors) if _can_be_squared(f)]
    match = _TERM.match(piece)
    if not match:
        raise DesignError(f"model: cannot read term {piece!r}; expected A, A*B or A^2 (or {', '.join(KEYWORDS)})")
    first, square, second = match.groups()
    for name in (first, second):
        if name in fixed:
            raise DesignError(f"model: term {piece!r} uses {name}, a fixed factor, which is no model term")
        if name is not None and name not in index:
            known = ", ".join(index) or "none"
            raise DesignError(f"model: unknown term {piece!r}: no design factor {name!r} (design factors: {known})")
    i = index[first]
    if square or second == first:
        if not _can_be_squared(factors[i]):
            raise DesignError(
                f"model: term {piece!r} needs a numeric factor with at least 3 levels; {first} is not"
            )
        return [Term(((i, 2),))]
    if second is None:
        return [Term(((i, 1),))]
    j = index[second]
    return [Term(((min(i, j), 1), (max(i, j), 1)))]


def _can_be_squared(factor: DesignFactor) -> bool:
    if isinstance(factor, CategoricalFactor) or not is_numeric(factor):
        return False
    return len(factor.candidate_settings) >= 3
