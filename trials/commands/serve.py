"""`trials serve`: the field-day web console on this machine (loopback unless --host says otherwise)."""

from __future__ import annotations

import argparse

from trials import option_types as types

DEFAULT_PORT = 8765
#: Requests served at once: a few phones and the experimenter's laptop.
THREADS = 8


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "serve",
        help="the field-day web console: run sheet, run pages, score form, participants' questionnaire, progress",
        description=(
            "Serve the study's web console: the run sheet, each run's page (start, finish, abort, notes, attach the "
            "robot's log, played in the background as `trials run --from-log` plays it, or a corrected one; the "
            "outcome and a picture of the run), the evaluator's score form, the participants' "
            "questionnaire (a link and QR code per run) and the progress so far. In a study driven live (a [robot] "
            "table in study.toml, or --robot), a run page's Start drives the run on the robot as `trials run --robot` "
            "does, shows its state and offers E-STOP. The first line printed is the experimenter's link, with its "
            "token; it opens the run sheet. Everything is written into the study folder as the other commands write "
            "it. Ctrl-C stops it (and a live run first)."
        ),
    )
    parser.add_argument("--study", type=types.folder, default=types.folder("."), metavar="DIR", help="the study folder (default: current folder)")
    parser.add_argument("--host", default="127.0.0.1", metavar="ADDRESS",
                        help="address to listen on (default 127.0.0.1, this machine only; 0.0.0.0 lets phones on the network in, "
                        "and the participants' links and QR codes then carry this machine's network address)")
    parser.add_argument("--port", type=types.whole(0, 65535), default=DEFAULT_PORT, metavar="N", help=f"port (default {DEFAULT_PORT}; 0: any free one)")
    parser.add_argument("--robot", metavar="URI",
                        help="drive the runs live on this robot (ros1://HOST:PORT or ros2://DOMAIN), with the [robot] table's topics "
                        "and limits if study.toml has one (default: that table's uri; without one, runs are not driven live)")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    import signal

    from waitress import create_server

    from trials.console.access import console_access
    from trials.console.actions import Console
    from trials.console.address import NETWORK_OPTION, WILDCARDS, participant_reach, url_host
    from trials.console.app import create_app
    from trials.errors import StudyError
    from trials.study import StudyFolder

    folder = StudyFolder(args.study)
    console = Console(folder, args.robot)
    console.sheet()  # a study the console cannot show is refused before it listens
    access = console_access(folder)
    reach = participant_reach(args.host)
    try:
        server = create_server(create_app(console, access, reach), host=args.host, port=args.port, threads=THREADS)
    except OSError as exc:
        raise StudyError(f"cannot listen on {args.host}:{args.port}: {exc.strerror or exc}") from None
    port = server.effective_port
    # On every address, this laptop's own browser reaches the console on loopback.
    shown = ("[::1]" if ":" in args.host else "127.0.0.1") if args.host in WILDCARDS else url_host(args.host)
    print(f"http://{shown}:{port}/?token={access.experimenter_token}", flush=True)
    print("The link above opens the run sheet (keep it to yourself: it lets its holder record runs). Ctrl-C stops the console.", flush=True)
    if reach.local_only:
        print(f"Phones cannot reach {args.host}, this machine only: `trials serve {NETWORK_OPTION}` lets participants' phones on the "
              "lab's network in.", flush=True)
    elif reach.host is not None:
        print(f"Participants' links and QR codes carry http://{url_host(reach.host)}:{port}, this machine's address on the network.", flush=True)
    else:
        print("No network address of this machine was found: participants' links carry the address the experimenter's browser opened.", flush=True)
    if console.live.uri is not None:
        print(f"Runs are driven live on {console.live.uri}: a run page's Start starts one; E-STOP or Ctrl-C here stops it.", flush=True)

    def stop(signum: int, frame: object) -> None:
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, stop)  # `kill` stops the console as Ctrl-C does, and a live run with it
    try:
        server.run()
    finally:
        server.close()
        stopped = console.live.close()
        signal.signal(signal.SIGTERM, previous)
        if stopped is not None:
            print(f"Stopped the live run {stopped} (E-STOP); it is recorded as aborted.", flush=True)
    return 0
