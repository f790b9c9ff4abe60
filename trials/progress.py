"""The one progress convention of the `trials` commands that take a while.

- on a terminal, a start-up line on standard error naming what is loading before the first item can
  start, then a tqdm bar on standard error, with each item's line written above it;
- piped or redirected, no start-up line and no bar (a log keeps results, not transient status): each
  item's line is printed as it comes, numbered `[n/N]`, and a bad input stays one `error:` line;
- `--quiet`: none of this (no start-up line, bar or item lines); results and errors still print.

Item lines go to standard output (failures to standard error), so `> file` keeps them and drops the bar.
"""

from __future__ import annotations

import argparse
import itertools
import sys
from typing import IO, Any


def add_quiet(parser: argparse.ArgumentParser) -> None:
    """The `--quiet` option every long command has."""
    parser.add_argument("--quiet", action="store_true", help="no start-up line, progress bar or per-item lines")


def on_terminal(stream: IO[str] | None = None) -> bool:
    """Whether `stream` (standard error by default) is a terminal, where a bar may redraw itself."""
    stream = stream or sys.stderr
    return bool(getattr(stream, "isatty", lambda: False)())


def show_bars(quiet: bool) -> bool:
    """Whether a library's own progress bars may be shown: on a terminal and not quiet."""
    return not quiet and on_terminal()


def numbered(n: int, total: int, line: str) -> str:
    """An item's line as the convention numbers it: `[n/N] line`."""
    return f"[{n}/{total}] {line}"


def piped_lines(quiet: bool) -> bool:
    """Whether a command whose library draws its own bar should print `[n/N]` lines instead: when
    piped or redirected (no bar is drawn there) and not quiet."""
    return not quiet and not on_terminal()


class Progress:
    """Counts items of a long command, as a bar on a terminal or `[n/N]` lines when piped; nothing when quiet."""

    def __init__(self, unit: str, desc: str, quiet: bool = False, bar: bool = True) -> None:
        self.unit, self.desc, self.quiet = unit, desc, quiet
        self.total = 0
        self.count = 0
        self._bar: Any = None
        self._want_bar = bar and not quiet and on_terminal()

    def loading(self, what: str) -> None:
        """The start-up line (on a terminal): what is being loaded or prepared before the first item."""
        if not self.quiet and on_terminal():
            sys.stderr.write(f"{what}...\n")
            sys.stderr.flush()

    def start(self, total: int) -> None:
        """N items are about to run."""
        self.total, self.count = total, 0
        if self._want_bar:
            from tqdm import tqdm

            self._bar = tqdm(total=total, unit=self.unit, desc=self.desc, file=sys.stderr)

    def numbered(self, line: str, count: int | None = None) -> str:
        """`[n/N] line`, n the item's number (the next one by default)."""
        return numbered(self.count + 1 if count is None else count, self.total, line)

    def item(self, line: str | None, error: bool = False) -> None:
        """One item done: its line (numbered) printed, the bar advanced."""
        text = self.numbered(line) if line is not None else None
        self.count += 1
        if self.quiet or text is None:
            if self._bar is not None:
                self._bar.update(1)
            return
        stream = sys.stderr if error else sys.stdout
        if self._bar is not None:
            self._bar.write(text, file=stream)
            self._bar.update(1)
        else:
            print(text, file=stream, flush=True)

    def held(self, lines: list[tuple[str, bool]]) -> None:
        """Items whose (line, error) were held back, as a blinded study's runs are: numbered in the order
        given and written as one block per stream, so that no time a reader could measure passes between them."""
        if not self.quiet:
            for error, group in itertools.groupby(enumerate(lines, start=self.count + 1), key=lambda item: item[1][1]):
                stream = sys.stderr if error else sys.stdout
                stream.write("".join(self.numbered(line, n) + "\n" for n, (line, _) in group))
                stream.flush()
        self.count += len(lines)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None
