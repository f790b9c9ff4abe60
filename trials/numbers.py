"""Numbers typed by people or written by spreadsheets, read one way everywhere in `trials`."""

from __future__ import annotations

import math


def finite_number(text: str, name: str) -> float:
    """`text` as a finite float; ValueError naming `name` when it is not a number, or is inf or NaN."""
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"{name} must be a number, got {text!r}") from None
    if not math.isfinite(value):
        raise ValueError(f"{name} must be a finite number, got {text!r}")
    return value
