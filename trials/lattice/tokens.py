"""A whitespace token stream over an SBPL text file that knows each token's line, for error messages."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np

from trials.lattice.errors import LatticeError


class Tokens:
    """Reads SBPL's whitespace-separated tokens one at a time, as its `fscanf("%s")` loop does."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        try:
            text = self.path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise LatticeError(f"cannot read {self.path}: {exc}") from exc
        self._items = [(tok, n) for n, line in enumerate(text.splitlines(), 1) for tok in line.split()]
        self._pos = 0

    @property
    def line(self) -> int:
        """The line of the next token (the last line at the end of the file)."""
        if self._pos < len(self._items):
            return self._items[self._pos][1]
        return self._items[-1][1] if self._items else 1

    def error(self, expected: str, got: str | None = None) -> LatticeError:
        """A LatticeError naming the file, the line and what was expected there."""
        found = "the end of the file" if got is None else f'"{got}"'
        return LatticeError(f"{self.path.name}, line {self.line}: expected {expected}, got {found}")

    def peek(self) -> str | None:
        """The next token without consuming it, or None at the end."""
        return self._items[self._pos][0] if self._pos < len(self._items) else None

    def next(self, expected: str) -> str:
        """Consume the next token; `expected` names it for the error at the end of the file."""
        tok = self.peek()
        if tok is None:
            raise self.error(expected)
        self._pos += 1
        return tok

    def label(self, label: str) -> None:
        """Consume a token that must equal `label`."""
        tok = self.peek()
        if tok != label:
            raise self.error(f'"{label}"', tok)
        self._pos += 1

    def integer(self, what: str, low: int | None = None, high: int | None = None) -> int:
        """Consume an integer in [low, high]."""
        tok = self.peek()
        try:
            value = int(tok) if tok is not None else None
        except ValueError:
            value = None
        if value is None or (low is not None and value < low) or (high is not None and value > high):
            bounds = "" if low is None else f" >= {low}" if high is None else f" in {low}..{high}"
            raise self.error(f"{what} (an integer{bounds})", tok)
        self._pos += 1
        return value

    def integers(self, count: int, what: Callable[[int], str], low: int, high: int) -> np.ndarray:
        """Consume `count` integers in [low, high] at once; `what(i)` names the i-th for errors."""
        chunk = [tok for tok, _ in self._items[self._pos:self._pos + count]]
        try:
            values = np.array(chunk, dtype=np.int64) if len(chunk) == count else None
        except ValueError:
            values = None
        if values is not None and values.size and (values.min() < low or values.max() > high):
            values = None
        if values is None:  # slow path: one at a time, so the error names the offending token
            return np.array([self.integer(what(i), low, high) for i in range(count)], dtype=np.int64)
        self._pos += count
        return values

    def number(self, what: str, positive: bool = False) -> float:
        """Consume a finite real number (parsed like C's atof of a well-formed number)."""
        tok = self.peek()
        try:
            value = float(tok) if tok is not None else math.nan
        except ValueError:
            value = math.nan
        if not math.isfinite(value) or (positive and value <= 0):
            raise self.error(f"{what} (a {'positive ' if positive else ''}number)", tok)
        self._pos += 1
        return value

    def end(self, after: str) -> None:
        """Require that nothing but whitespace follows."""
        tok = self.peek()
        if tok is not None:
            raise self.error(f"the end of the file after {after}", tok)
