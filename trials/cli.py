"""The `trials` console command: one subcommand per module of `trials.commands`.

User mistakes (the package error types below) print `error: ...` on one line and exit 2.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from analysis.errors import AnalysisError
from designs.errors import DesignError
from navigan.errors import NaviganError
from robot_logs.errors import LogError
from trials.errors import StudyError
from trials.lattice.errors import LatticeError

#: Subcommand modules under `trials.commands`, in the order `trials --help` lists them.
COMMANDS: tuple[str, ...] = ("design", "run", "log", "lattice", "train", "evaluate", "playback", "score", "respond", "report")

#: Exception types that mean "the user asked for something wrong", never a bug.
USER_ERRORS: tuple[type[Exception], ...] = (DesignError, StudyError, LogError, NaviganError, AnalysisError, LatticeError)

EXIT_USAGE = 2


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one `error:` line and exit code 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        sys.stderr.write(f"error: {message} (see `{self.prog} --help`)\n")
        raise SystemExit(EXIT_USAGE)


def build_parser() -> argparse.ArgumentParser:
    """The full parser with every registered subcommand."""
    parser = _Parser(
        prog="trials",
        description="Design, run and report field trials of socially compliant robot navigation.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    for name in COMMANDS:
        importlib.import_module(f"trials.commands.{name}").register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the `trials` command; returns the process exit code."""
    args = build_parser().parse_args(argv)
    try:
        return int(args.handler(args) or 0)
    except USER_ERRORS as exc:
        sys.stderr.write(f"error: {exc}\n")
        return EXIT_USAGE
    except KeyboardInterrupt:
        sys.stderr.write("interrupted: finished work is kept; run the command again to continue\n")
        return 130


if __name__ == "__main__":
    raise SystemExit(main())
