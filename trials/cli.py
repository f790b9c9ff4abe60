"""The `trials` console command: one subcommand per module of `trials.commands`.

User mistakes (`trials.errors.USER_ERRORS`, every package's error type) and what the file system refuses (a read-only
folder, a full disk) print `error: ...` on one line and exit 2; a usage error points to the `--help` of the (sub)command
that was typed.
"""

from __future__ import annotations

import argparse
import gc
import importlib
import os
import sys
from collections.abc import Sequence

from trials.errors import USER_ERRORS

#: Subcommand modules under `trials.commands`, in the order `trials --help` lists them.
COMMANDS: tuple[str, ...] = ("design", "run", "controllers", "deviation", "robot_sim", "status", "log", "lattice", "train", "evaluate",
                             "playback", "score", "respond", "report", "serve", "power")

EXIT_USAGE = 2
#: Threads numpy's OpenBLAS starts with unless the user sets OPENBLAS_NUM_THREADS: the matrices the commands
#: multiply are small (a design's X'X, a tracker's covariances), where more threads only cost start-up and spinning.
BLAS_THREADS = "1"


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one `error:` line and exit code 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        sys.stderr.write(f"error: {message} (see `{self.prog} --help`)\n")
        raise SystemExit(EXIT_USAGE)


#: Where each parsed namespace keeps the innermost (sub)command parser that read it.
USAGE_PARSER = "usage_parser"


def version() -> str:
    """The installed distribution's version (`trials --version`)."""
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as installed

    try:
        return installed("navtrials")
    except PackageNotFoundError:
        return "unknown (not installed)"


def build_parser() -> argparse.ArgumentParser:
    """The full parser with every registered subcommand."""
    parser = _Parser(
        prog="trials",
        description="Design, run and report field trials of socially compliant robot navigation.",
    )
    parser.add_argument("--version", action="version", version=f"trials (navtrials) {version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    for name in COMMANDS:
        importlib.import_module(f"trials.commands.{name}").register(sub)
    _name_usage_parsers(parser)
    return parser


def _name_usage_parsers(parser: argparse.ArgumentParser) -> None:
    """Give every subcommand parser a default naming itself, so that an argument left over after
    parsing is reported by the innermost command that was typed, with its own `--help`."""
    parser.set_defaults(**{USAGE_PARSER: parser})
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for child in dict.fromkeys(action.choices.values()):
                _name_usage_parsers(child)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the `trials` command; returns the process exit code."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", BLAS_THREADS)  # read once, when numpy is first imported below
    try:
        args, extras = build_parser().parse_known_args(argv)
        if extras:
            getattr(args, USAGE_PARSER).error(f"unrecognized arguments: {' '.join(extras)}")
    except SystemExit as exc:  # --help, or a usage error already printed as one line
        return int(exc.code or 0)
    try:
        return int(args.handler(args) or 0)
    except USER_ERRORS as exc:
        # One line, always: a name or value holding a line break is shown escaped.
        message = str(exc).replace("\r", "\\r").replace("\n", "\\n")
        sys.stderr.write(f"error: {message}\n")
        return EXIT_USAGE
    except BrokenPipeError:  # the reader went away (`| head`): the rest of the output is not wanted
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except OSError as exc:  # the file system refused (a read-only folder, a full disk): one line naming the file
        from trials.atomic import os_error_text

        sys.stderr.write(f"error: {os_error_text(exc)}\n")
        return EXIT_USAGE
    except KeyboardInterrupt:
        sys.stderr.write("interrupted: finished work is kept; run the command again to continue\n")
        return 130


def console() -> None:
    """The `trials` console script: runs `main` and exits with its code, skipping the interpreter's last garbage
    collection. `main` has closed everything it wrote by then, so that collection would only free memory the exit
    frees anyway, and once numba and SciPy are loaded it costs about 0.3 s, a quarter of the 27-run design."""
    code = main()
    gc.freeze()  # the objects left move to the permanent generation, which no collection visits
    raise SystemExit(code)


if __name__ == "__main__":
    console()
