"""`trials run`: run the study's pending plan rows in the closed-loop simulator, play them from robot logs open
loop (`--from-log`, or a plan `Log` column), or drive them live on a robot (`--robot`), logging each to MCAP."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from trials.robot.settings import RobotSettings
    from trials.runner import RunDone
    from trials.study import StudyFolder

from robot_logs.physical import STEP_S
from trials import option_types as types
from trials.progress import add_quiet
from trials.run_settings import MAX_NOISE_M, MAX_TIMEOUT_S, PERCEPTIONS

#: Upper ends of the options' ranges: beyond them a value is a typing slip, not a study.
MAX_WORKERS = 256
MAX_PARTICIPANTS = 1000
MAX_GOAL_M = 1e4



def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "run",
        help="run the pending rows of the plan in simulation or from robot logs (blinded when the study is)",
        description=(
            "Run every pending row of plan.csv in plan order: build its scenario, drive the robot with "
            "the row's controller in closed loop among social-force pedestrians, write runs/<code>.mcap "
            "and append the run's row to outcomes.csv. A row whose Log column names a robot log, or every "
            "row with --from-log, plays that log instead: its tracked people and recorded robot motion go "
            "through the row's controller open loop, and its plans are logged next to what the robot did. With --robot, "
            "each row is driven live on the robot instead, one at a time. "
            "Interrupted, it keeps every finished run; run it again to continue. A blinded study always "
            "runs blind."
        ),
    )
    parser.add_argument("--blind", action="store_true", help="run blind (implied by a blinded study; an error on an open one)")
    parser.add_argument("--study", type=types.folder, default=types.folder("."), metavar="DIR", help="the study folder (default: current folder)")
    parser.add_argument("--workers", type=types.whole(1, MAX_WORKERS), default=1, metavar="N", help="runs in parallel, one process each (default 1)")
    parser.add_argument("--only", nargs="+", default=[], metavar="CODE", help="run only these rows (if pending)")
    parser.add_argument("--rerun", nargs="+", default=[], metavar="CODE", help="redo these finished runs; the old log and row move to superseded/")
    settings = parser.add_argument_group(
        "run settings", "each overrides the [run] table of study.toml (whose values, else the defaults shown, are used); "
        "every run records its settings in outcomes.csv and its log")
    settings.add_argument("--perception", choices=PERCEPTIONS,
                          help="what the controller is told: true positions with noise and dropouts (default), or "
                          "simulated laser scans through the person tracker")
    settings.add_argument("--noise", type=types.number(0, MAX_NOISE_M), metavar="M",
                          help="positions: position noise, standard deviation in metres (default 0.05)")
    settings.add_argument("--dropout", type=types.number(0, 1, below=True), metavar="P",
                          help="positions: chance a pedestrian is missed at a step (default 0.05)")
    settings.add_argument("--weights", metavar="FILE", help="NaviGAN-R checkpoint (default: the shipped all-scenes weights)")
    settings.add_argument("--timeout", type=types.number(STEP_S, MAX_TIMEOUT_S), metavar="S",
                          help=f"simulated seconds before a run times out, from one {STEP_S} s step to {MAX_TIMEOUT_S:g} (default 60)")
    settings.add_argument("--settings-differ", action="store_true",
                          help="run even though finished runs were made with other settings (the report flags the mix)")
    parser.add_argument("--wall-clock", action="store_true",
                        help="stamp each simulated run's MCAP log with the time it ran (blinded: to the minute) instead of from "
                        "1970-01-01; a logged trial keeps its log's own times when they are real (from 2000 on), and with this "
                        "flag always")
    parser.add_argument("--allow-simulated", action="store_true",
                        help="simulate runs (and their participants' judgments) even in a field study, one with a [robot] table "
                        "or runs driven live or played from robot logs; the report says which runs were simulated")
    parser.add_argument("--participants", type=types.whole(1, MAX_PARTICIPANTS), metavar="N",
                        help="simulated participants judging each run (default: one per pedestrian)")
    parser.add_argument("--no-responses", action="store_true",
                        help="do not add simulated participants' judgments of the simulated runs to responses.csv (added in plan "
                        "order once the runs end)")
    parser.add_argument("--robot", metavar="URI",
                        help="drive the runs live on a robot through ROS: ros1://HOST:PORT (a ROS 1 master) or ros2://DOMAIN; "
                        "topics, frames, goal and limits come from study.toml's [robot] table (docs/live_runs.md). "
                        "One run at a time, waiting for the operator (Enter) before each after the first; Ctrl-C or kill stops "
                        "the robot and keeps the run's log in runs/aborted/")
    parser.add_argument("--mark", action="store_true",
                        help="with --robot: measure the study's start mark (the robot's pose in its odometry frame as it stands "
                        "on the lab's mark) into start_mark.json and drive nothing; rows then start and end relative to it "
                        "([robot] goal_frame \"mark\", docs/live_runs.md)")
    logs = parser.add_argument_group("logged trials", "play robot logs (ROS1/ROS2 bags, MCAP) open loop instead of simulating")
    logs.add_argument("--from-log", type=Path, metavar="FILE",
                      help="play this log for every row run (pending rows, or --only / --rerun ones), "
                      "instead of simulating or the plan's Log column")
    logs.add_argument("--goal", type=types.number(-MAX_GOAL_M, MAX_GOAL_M), nargs=2, metavar=("X", "Y"),
                      help="goal in the log's odometry frame (the scan's frame without odometry); "
                      "default: 10 m ahead of the robot's first pose")
    logs.add_argument("--start", type=types.number(0, math.inf, below=True), default=0.0, metavar="S", help="skip the log's first S seconds (default 0)")
    logs.add_argument("--duration", type=types.number(0, math.inf, above=True, below=True), metavar="S",
                      help="play at most S seconds from --start (default: to the end)")
    logs.add_argument("--scan-topic", metavar="TOPIC", help="LaserScan topic (default: the log's only one)")
    logs.add_argument("--odom-topic", metavar="TOPIC",
                      help="Odometry topic (default: the log's only one; a log without one has a robot standing still)")
    logs.add_argument("--salvage", action="store_true", help="read what can be read of a damaged log instead of refusing it")
    types.add_map(logs)
    add_quiet(parser)
    parser.add_argument("--json", action="store_true", help="print what was run as one JSON object instead of lines")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    import json
    import signal
    import sys

    from robot_logs.occupancy_map import read_map
    from robot_logs.topics import TopicNames
    from trials.errors import StudyError
    from trials.log_trial import ReplayOptions
    from trials.outcomes import columns, read_outcomes
    from trials.progress import Progress
    from trials.run_settings import override, read_run_settings
    from trials.runner import RunOptions, StudyRun, run_study
    from trials.simulated_participants import simulate_run
    from trials.study import LIVE_STATE, OUTCOMES, RESPONSES, RUN_LOCK, SPEC, StudyFolder, to_the_minute

    if args.robot is not None and args.from_log is not None:
        raise StudyError("--robot drives the runs live and --from-log plays a recorded log: choose one")
    if args.mark:
        return mark(StudyFolder(args.study), args.robot)
    study = StudyRun.open(StudyFolder(args.study), args.blind, from_log=args.from_log is not None or args.robot is not None)
    robot = live_settings(study.folder.path(SPEC), args.robot)
    replay = ReplayOptions(args.from_log, tuple(args.goal) if args.goal else None, args.start, args.duration,
                           TopicNames(scan=args.scan_topic, odometry=args.odom_topic), args.salvage,
                           read_map(args.map, args.map_frame) if args.map is not None else None)
    given = {"perception": args.perception, "noise_std_m": args.noise, "dropout": args.dropout,
             "timeout_s": args.timeout, "weights": args.weights}
    settings = override(read_run_settings(study.folder.path(SPEC)), given, "the command line")
    options = RunOptions(settings, replay, args.settings_differ, wall_clock=args.wall_clock, robot=robot,
                         allow_simulated=args.allow_simulated)

    def stop(signum: int, frame: object) -> None:
        raise KeyboardInterrupt

    # `kill` stops the run as Ctrl-C does: workers stopped, partial files removed.
    previous = signal.signal(signal.SIGTERM, stop)
    # A blinded study's console shows no run times, nor when each run ended (the time between two
    # lines is a run's time, which differs by controller): no progress bar, and every run's line
    # comes only when all have ended, in plan order.
    progress = Progress("run", "running", quiet=args.quiet or args.json, bar=not study.blind)
    progress.loading(f"Loading the controllers ({settings.describe()}) in {args.workers} worker "
                     f"process{'es' if args.workers > 1 else ''}")
    held: dict[str, tuple[str, bool]] = {}

    def say(code: str, line: str, error: bool = False) -> None:
        if study.blind:
            held[code] = (line, error)
        else:
            progress.item(line, error)

    def started(count: int) -> None:
        if study.blind and not (args.quiet or args.json):
            print(f"Blinded study: {count} runs; each worker opens the sealed key itself, controller output goes to "
                  "sealed/runs/. Run times stay hidden: each run's line comes when all have ended.", flush=True)
        if robot is not None and not (args.quiet or args.json):
            print(f"Driving {count} run{'s' if count > 1 else ''} live on {robot.uri}, one at a time; each waits for scans, "
                  f"odometry and the laser's transform. {study.folder.path(LIVE_STATE)} (and the console) shows the state; "
                  "Ctrl-C stops the robot.", flush=True)
        progress.start(count)

    def done(run: RunDone) -> None:
        say(run.code, run_line(study.task(run.code).row, run.row) + _replayed(run))

    def judge() -> None:
        """Simulated participants judge every finished simulated run that has no judgments yet (analysis.participants),
        seeded by each run's seed, in plan order once the runs have ended (the order runs end in would time them): this
        session's runs, and those a killed session finished but never had judged. A logged trial's robot drove as
        recorded, not as its controller planned, and a live run is judged by real people, so neither is judged here."""
        if args.no_responses:
            return
        finished = {o.run_code: o for o in read_outcomes(study.folder.path(OUTCOMES), study.blind) if o.perception in PERCEPTIONS}
        added = [simulate_run(study.folder, code, finished[code].seed, args.participants, finished[code].finished_utc)
                 for code in study.codes if code in finished]
        if any(added) and study.blind:
            to_the_minute(study.folder.path(RESPONSES), study.folder.root)

    def failed(code: str, message: str) -> None:
        say(code, f"{run_label(study.task(code).row)}: failed: {message}", error=True)

    asked: list[str] = []

    def staged(code: str) -> bool:
        """Before a live row: print where its robot and walkers go; before every row but the first (which the command itself
        started), wait for the operator to stage it (an answer of q, or no standard input, stops)."""
        from trials.robot.staging import staged_scene

        assert robot is not None
        try:
            lines = staged_scene(study.folder, robot, code).lines()
        except StudyError as exc:
            lines = [str(exc)]
        first = not asked
        asked.append(code)
        if args.quiet or args.json:
            return first or _confirmed(code, "")
        print(f"{'First' if first else 'Next'}: {run_label(study.task(code).row)}. Staging:\n  " + "\n  ".join(lines),
              file=sys.stderr, flush=True)
        return first or _confirmed(code, "Stage it (the robot at its start, the walkers at theirs), then press Enter to start it, "
                                   "or q and Enter to stop here: ")

    try:
        summary = run_study(study, args.workers, args.only, args.rerun, options, started, done, failed, staged, judge)
    finally:
        progress.close()
        signal.signal(signal.SIGTERM, previous)
        progress.held([held[code] for code in study.codes if code in held])
    if summary.stale_lock is not None:
        print(f"note: {study.folder.path(RUN_LOCK)} was left by pid {summary.stale_lock}, a `trials run` that no "
              "longer runs (killed, or of an earlier release); it was taken over", file=sys.stderr)
    if args.json:
        # In plan order, as outcomes.csv's columns: the order runs ended in would time them (blinding).
        finished = {run.code: {k: v for k, v in run.row.items() if k in columns(study.blind)} for run in summary.finished}
        print(json.dumps({"study": str(study.folder.root), "settings": settings.recorded(),
                          "finished": [finished[code] for code in study.codes if code in finished],
                          "failed": [{"run_code": c, "message": m} for c, m in summary.failed],
                          "already_finished": summary.skipped, "done": summary.done, "planned": len(study.codes),
                          "superseded": str(summary.superseded) if summary.superseded else None}))
        return 1 if summary.failed else 0
    if summary.skipped:
        shown = ", ".join(summary.skipped[:5]) + (", ..." if len(summary.skipped) > 5 else "")
        print(f"{len(summary.skipped)} of the runs asked for have already finished ({shown}); `trials run --rerun CODE` "
              "redoes one, `trials status` lists them")
    if summary.superseded is not None:
        print(f"The earlier logs and rows of {', '.join(args.rerun)} moved to {summary.superseded}")
    statuses = [run.row["status"] for run in summary.finished]
    counts = ", ".join(f"{statuses.count(s)} {s}" for s in ("goal", "collision", "timeout") if s in statuses)
    print(f"{len(summary.finished)} runs finished{f' ({counts})' if counts else ''}; {summary.done} of {len(study.codes)} "
          f"plan rows are done (outcomes in {study.folder.path(OUTCOMES)})")
    if summary.estopped:
        print("E-STOP: this session stopped there, and no later row was started; release the e-stop, then `trials run --robot` "
              "goes on with the pending rows", file=sys.stderr)
    if summary.failed:
        print(f"{len(summary.failed)} runs failed and stay pending: {', '.join(c for c, _ in summary.failed)}", file=sys.stderr)
        return 1
    return 0


def mark(folder: StudyFolder, uri: str | None) -> int:
    """`trials run --robot URI --mark`: measure and keep the study's start mark."""
    import math

    from trials.errors import StudyError
    from trials.robot.live_trial import measure_mark
    from trials.robot.staging import MARK_FILE, read_mark, write_mark
    from trials.study import SPEC

    if uri is None:
        raise StudyError("--mark measures the start mark on a robot: give --robot URI")
    if not folder.path(SPEC).exists():
        raise StudyError(f"no {SPEC} in {folder.root}: `trials design --robot URI` makes the study first")
    settings = live_settings(folder.path(SPEC), uri)
    assert settings is not None
    previous = read_mark(folder)
    measured = measure_mark(settings)
    write_mark(folder, measured)
    pose = measured.pose
    print(f"Start mark: ({pose.x:.3f}, {pose.y:.3f}) facing {math.degrees(pose.yaw):.1f} deg in {measured.frame}, kept in "
          f"{folder.path(MARK_FILE)}" + (f" (it was ({previous.pose.x:.3f}, {previous.pose.y:.3f}) facing "
                                         f"{math.degrees(previous.pose.yaw):.1f} deg, measured {previous.measured_utc})" if previous else ""))
    return 0


def _confirmed(code: str, prompt: str) -> bool:
    """The operator's answer before a live row: Enter goes on; q, or no standard input, stops."""
    import sys

    print(prompt, end="", file=sys.stderr, flush=True)
    try:
        answer = input()
    except EOFError:
        print(f"\nNo operator answered (standard input is closed): stopping before run {code}; `trials run --robot` "
              "again goes on with it", file=sys.stderr)
        return False
    return answer.strip().lower() not in ("q", "quit")


def live_settings(spec: Path, uri: str | None) -> RobotSettings | None:
    """The `[robot]` table of study.toml (its defaults when the study has none) with `--robot URI`; None without --robot."""
    from dataclasses import replace

    from trials.robot.settings import RobotSettings, read_robot_settings
    from trials.robot.transport import RobotUri

    if uri is None:
        return None
    RobotUri.parse(uri)
    return replace(read_robot_settings(spec) or RobotSettings(), uri=uri)


def run_label(plan_row: dict[str, str]) -> str:
    """`order 3, PE7Y9 (Pedestrians 2, Direction Crossing, Controller A)`: a run's place in the plan, its
    code and its factor settings as plan.csv has them (the arm label, never the controller, when blinded)."""
    from trials.log_trial import LOG_COLUMN

    factors = ", ".join(f"{k} {v}" for k, v in plan_row.items() if k not in ("order", "run_code", LOG_COLUMN))
    return f"order {plan_row['order']}, {plan_row['run_code']} ({factors})"


def run_line(plan_row: dict[str, str], outcome: dict[str, str]) -> str:
    """A finished run's console line: its label, how it ended after how long (to the simulator's 0.1 s
    step), and the smallest gap between the robot's footprint and a pedestrian's body."""
    duration = float(outcome["duration_s"])
    gap = outcome["min_distance_m"]
    near = f"; smallest gap robot footprint to pedestrian {float(gap):.2f} m" if gap else "; no pedestrian"
    return f"{run_label(plan_row)}: {outcome['status']} after {duration:.1f} s{near}"


def _replayed(run: RunDone) -> str:
    """A logged trial's plans against the log, for its console line (sealed when blind)."""
    if not run.logged:
        return ""
    if not run.replay:
        return " (played from its log; its plans are sealed)"
    replay = run.replay
    deviation, clearance = replay["plan_deviation_mean_m"], replay["plan_min_clearance_m"]
    return (f" (played from its log; {replay['plans']} plans, {deviation or '-'} m from the recorded path on average, "
            f"closest predicted {clearance or '-'} m)")
