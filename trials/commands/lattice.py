"""`trials lattice`: the lattice planner's own command (`trials.lattice.cli`) as a subcommand."""

from __future__ import annotations

import argparse

from trials.lattice import cli


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("lattice", help=cli.SUMMARY, description=cli.DESCRIPTION)
    cli.add_arguments(parser)
    parser.set_defaults(handler=cli.run)
