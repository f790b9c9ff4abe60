"""A plan the researcher brings, read as design settings under a spec's factors and coding, so that it
can be diagnosed (`trials design --evaluate`) or set beside another (`--compare`)."""

from __future__ import annotations

import math

import numpy as np

from designs.errors import DesignError
from designs.factors import CategoricalFactor, ContinuousFactor, DesignFactor


def settings_from_rows(factors: tuple[DesignFactor, ...], header: list[str], rows: list[tuple[int, list[str]]],
                       source: str) -> np.ndarray:
    """(n, k) coded settings of the rows' factor columns; other columns are ignored.

    Raises:
        DesignError: a factor's column is missing, or a cell is not one of its levels or outside its
            range, naming the file, line and column.
    """
    missing = [f.name for f in factors if f.name not in header]
    if missing:
        raise DesignError(f"{source}: no column {missing[0]!r} (the spec's design factors: {', '.join(f.name for f in factors)})")
    if not rows:
        raise DesignError(f"{source}: no runs below the header")
    columns = [header.index(f.name) for f in factors]
    settings = np.empty((len(rows), len(factors)))
    for r, (line, cells) in enumerate(rows):
        for j, (factor, column) in enumerate(zip(factors, columns)):
            text = cells[column] if column < len(cells) else ""
            settings[r, j] = _setting(factor, text, f"{source} line {line}, column {factor.name}")
    return settings


def _setting(factor: DesignFactor, text: str, where: str) -> float:
    if isinstance(factor, CategoricalFactor):
        if text not in factor.levels:
            raise DesignError(f"{where}: {text!r} is no level of {factor.name} (levels: {', '.join(factor.levels)})")
        return factor.encode(text)
    try:
        value = float(text)
    except ValueError:
        raise DesignError(f"{where}: expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise DesignError(f"{where}: expected a finite number, got {text!r}")
    if isinstance(factor, ContinuousFactor):
        if not factor.low - 1e-9 <= value <= factor.high + 1e-9:
            raise DesignError(f"{where}: {value:g} lies outside {factor.name}'s range [{factor.low:g}, {factor.high:g}]")
        return factor.encode(value)
    if not any(math.isclose(value, level, rel_tol=1e-9, abs_tol=1e-12) for level in factor.levels):
        raise DesignError(f"{where}: {value:g} is no level of {factor.name} (levels: {', '.join(f'{v:g}' for v in factor.levels)})")
    return factor.encode(value)
