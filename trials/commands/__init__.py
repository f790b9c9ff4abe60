"""One module per `trials` subcommand; each defines `register(subparsers)`.

Command modules import only the standard library at the top, so that `trials --help` and the
error path stay fast; the heavy packages are imported inside the handler.
"""
