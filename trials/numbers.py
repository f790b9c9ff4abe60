"""Numbers typed by people or written by spreadsheets, read one way everywhere in `trials`."""

from __future__ import annotations

import math

#: How much of a bad value an error line quotes: enough to find it, never a screenful.
SHOWN = 24


def shown(text: str) -> str:
    """`text` quoted for a one-line error, cut short (saying how long it was) when it is long."""
    return repr(text) if len(text) <= SHOWN else f"{text[:SHOWN]!r}... ({len(text)} characters)"


def finite_number(text: str, name: str) -> float:
    """`text` as a finite float; ValueError naming `name` when it is not a number, or is inf or NaN."""
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"{name} must be a number, got {shown(text)}") from None
    if not math.isfinite(value):
        raise ValueError(f"{name} must be a finite number, got {shown(text)}")
    return value


def number_in(text: str, name: str, low: float, high: float) -> float:
    """`text` as a finite float from `low` to `high`; ValueError naming `name` and the range otherwise."""
    value = finite_number(text, name)
    if not low <= value <= high:
        raise ValueError(f"{name} must be a number from {low:g} to {high:g}, got {shown(text)}")
    return value
