"""`trials log`: look into robot logs and track the people in them.

A command group: `trials log inspect FILE` and `trials log track FILE`. Other modules add
subcommands by naming themselves in `SUBCOMMANDS`; each has `register(log_subparsers)`.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from trials import option_types as types
from trials.progress import add_quiet

if TYPE_CHECKING:
    from robot_logs.summary import LogSummary

#: More `trials log` subcommand modules under trials.commands (e.g. "log_show").
SUBCOMMANDS: tuple[str, ...] = ("log_show", "log_detector", "log_score")


def register(sub: argparse._SubParsersAction) -> None:
    import importlib

    parser = sub.add_parser(
        "log",
        help="inspect robot logs (ROS1/ROS2 bags, MCAP) and track people in their lidar scans",
        description="Robot logs: ROS1 .bag files, ROS2 bag folders (sqlite3 or MCAP storage) and .mcap files.",
    )
    group = parser.add_subparsers(dest="log_command", metavar="SUBCOMMAND", parser_class=type(parser))
    group.required = True
    _register_inspect(group)
    _register_track(group)
    for name in SUBCOMMANDS:
        importlib.import_module(f"trials.commands.{name}").register(group)


def _add_log_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("file", metavar="FILE|RUN", help="a ROS1 .bag, a ROS2 bag folder, an .mcap or a .db3 file, "
                        "or a run code of the study (its runs/<code>.mcap)")
    parser.add_argument("--study", type=types.folder, default=types.folder("."), metavar="DIR",
                        help="the study folder whose run codes FILE may name (default: current folder)")
    parser.add_argument("--salvage", action="store_true", help="read what can be read of a damaged log instead of refusing it")
    add_quiet(parser)


def study_log(text: str, study: Path) -> Path:
    """The log a FILE|RUN argument names: an existing path, else the study's log of that run code.

    Raises:
        StudyError: a bare name that is neither a file nor a finished run of the study.
    """
    from trials.errors import StudyError
    from trials.study import OUTCOMES, RUN_LOG_SUFFIX, RUNS, StudyFolder

    path = Path(text)
    if path.exists() or path.suffix == RUN_LOG_SUFFIX or len(path.parts) != 1:
        return path
    log = StudyFolder(study).run_log(text)
    if not log.exists():
        raise StudyError(f"no log of run {text} in {(study / RUNS).resolve()} (has it finished? see {OUTCOMES})")
    return log


def _register_inspect(group: argparse._SubParsersAction) -> None:
    parser = group.add_parser(
        "inspect",
        help="topics, types, counts, rates, duration and frames of a log",
        description="List a log's topics with their types, message counts, rates and frames, and its duration; "
        "for an MCAP file also its schemas and the fields each JSON schema declares (what Foxglove's panels offer). "
        "Times are header stamps; record times are shown where they differ.",
    )
    _add_log_argument(parser)
    parser.add_argument("--json", action="store_true", help="print the log's format, topics and spans as one JSON object")
    parser.set_defaults(handler=inspect)


def _register_track(group: argparse._SubParsersAction) -> None:
    parser = group.add_parser(
        "track",
        help="detect and track people in a log's LaserScans",
        description="Detect people in every LaserScan (segments a learned classifier calls legs, off the static "
        "world, paired into people) and track them with Kalman filters. Writes one CSV row per track per scan: stamp (header stamp, s), scan_index, "
        "track_id, x, y, vx, vy, frame.",
    )
    _add_log_argument(parser)
    parser.add_argument("--frame", choices=("sensor", "odom"), default="sensor", help="track in the scan's own frame (default) or the odometry frame")
    parser.add_argument("--out", type=types.output_file, metavar="CSV", help="write the tracks here (default: standard output)")
    parser.add_argument("--mcap", type=types.output_file, metavar="FILE", help="also write scans, detections and tracks as an MCAP for Foxglove")
    parser.add_argument("--scan-topic", metavar="TOPIC", help="LaserScan topic (default: the log's only one)")
    parser.add_argument("--odom-topic", metavar="TOPIC", help="Odometry topic (default: the log's only one)")
    parser.add_argument("--odometry", choices=("log", "scan"), default="log",
                        help="the robot's motion: the log's odometry and tf, or tf alone (default; in the scan's frame, scan "
                        "matching where the log has neither), or matching each scan to the earlier ones, for a log "
                        "recorded without odometry (implies --frame odom; frame 'scan_odom')")
    parser.add_argument("--detector", type=types.input_file, metavar="FILE",
                        help="a leg detector from `trials log train-detector` (default: the one shipped with the package)")
    types.add_map(parser)
    parser.set_defaults(handler=track)


def _warn_damage(damage: str | None) -> None:
    if damage:
        sys.stderr.write(f"warning: the log is damaged; read what could be read ({damage})\n")


def inspect(args: argparse.Namespace) -> int:
    import json
    from dataclasses import asdict

    from tqdm import tqdm

    from robot_logs.reader import LogReader
    from robot_logs.summary import summarise
    from trials.progress import Progress, show_bars

    path = study_log(args.file, args.study)
    Progress("msg", "reading", args.quiet).loading(f"Reading {path}")
    with LogReader(path, salvage=args.salvage) as log:
        total = sum(t.count for t in log.topics if not t.service)
        with tqdm(total=total, unit="msg", desc="reading", disable=not show_bars(args.quiet), leave=False) as bar:
            summary = summarise(log, bar.update)
    if args.json:
        record = asdict(summary)
        for topic in record["topics"]:
            topic["frames"] = sorted(topic["frames"])
        print(json.dumps({**record, "span_s": summary.span_s(), "record_span_s": summary.span_s(record=True)}))
    else:
        for line in summary_lines(summary) + schema_lines(path):
            print(line)
    _warn_damage(summary.damage)
    return 0


def schema_lines(path: Path) -> list[str]:
    """The schemas section of `trials log inspect` for an MCAP file (none for bags, or an MCAP without a summary)."""
    from robot_logs.errors import LogError
    from robot_logs.foxglove_log import FoxgloveReader

    if not path.is_file() or path.suffix != ".mcap":
        return []
    try:
        schemas = FoxgloveReader(path).schemas
    except LogError:  # damaged: the summary above already says so
        return []
    lines = ["", "schemas (JSON schemas: the fields Foxglove's panels offer):"]
    lines.extend(f"  {name:<30} {encoding:<10} {', '.join(fields) or '-'}" for name, (encoding, fields) in sorted(schemas.items()))
    return lines


def summary_lines(summary: LogSummary) -> list[str]:
    """The text of `trials log inspect`."""
    from robot_logs.records import seconds, stamp_text

    lines = [f"{summary.path}: {summary.format}"]
    span, record_span = summary.span_s(), summary.span_s(record=True)
    if span is not None:
        lines.append(f"duration: {span:.3f} s by header stamps, {record_span:.3f} s by record times")
    elif record_span is not None:
        lines.append(f"duration: {record_span:.3f} s by record times (no header stamps)")
    starts = [t.first_stamp_ns for t in summary.topics if t.first_stamp_ns is not None]
    if starts:
        lines.append(f"first header stamp: {stamp_text(min(starts))}")
    lines.append("")
    lines.append(f"{'topic':<32} {'type':<36} {'encoding':<8} {'count':>7} {'rate Hz':>8}  frames")
    for t in summary.topics:
        if t.service:
            continue
        rate = f"{t.rate_hz:.2f}" if t.rate_hz is not None else "-"
        frames = ", ".join(sorted(t.frames)) or "-"
        lines.append(f"{t.name:<32} {t.msgtype:<36} {t.encoding:<8} {t.count:>7} {rate:>8}  {frames}")
    services = [t for t in summary.topics if t.service]
    if services:
        lines.append("")
        lines.append("services (recorded service events, not decoded):")
        lines.extend(f"  {t.name:<30} {t.msgtype:<36} {t.encoding:<8} {t.count:>7}" for t in services)
    skipped = [t for t in summary.topics if t.undecoded]
    if skipped:
        lines.append("")
        lines.append("not decoded (skipped):")
        lines.extend(f"  {t.name}: {t.undecoded} of {t.count} messages ({t.why})" for t in skipped)
    notes = []
    for t in summary.topics:
        offset = t.header_minus_record_ns
        if offset is not None and abs(offset) > 1_000_000_000:
            days = seconds(offset) / 86400.0
            when = f"{abs(days):.1f} days" if abs(days) >= 1 else f"{abs(seconds(offset)):.1f} s"
            notes.append(f"{t.name}: header stamps are {when} {'older' if offset < 0 else 'newer'} than record times")
        if t.unstamped:
            notes.append(f"{t.name}: {t.unstamped} messages have unset (zero) header stamps; their record times stand in")
    if notes:
        lines.append("")
        lines.append("times: robot_logs uses header stamps")
        lines.extend(f"  {note}" for note in notes)
    return lines


def track(args: argparse.Namespace) -> int:
    from contextlib import ExitStack

    from tqdm import tqdm

    from robot_logs.foxglove_log import FoxgloveWriter, log_line
    from robot_logs.leg_classifier import LegClassifier
    from robot_logs.log_tracking import LogTracking, result_rows
    from robot_logs.occupancy_map import read_map
    from robot_logs.pipeline import PersonTracker
    from robot_logs.reader import LogReader
    from robot_logs.topics import TopicNames
    from robot_logs.track_mcap import write_tracked_scan
    from robot_logs.tracks import TrackTable, write_rows
    from trials.progress import Progress, show_bars

    topics = TopicNames(scan=args.scan_topic, odometry=args.odom_topic)
    rows = []
    args.file = study_log(args.file, args.study)
    Progress("scan", "tracking", args.quiet).loading(f"Reading {args.file}")
    classifier = LegClassifier.load(args.detector) if args.detector is not None else None
    occupancy = read_map(args.map, args.map_frame) if args.map is not None else None
    with LogReader(args.file, salvage=args.salvage) as log, ExitStack() as outputs:
        frame = "odom" if args.odometry == "scan" else args.frame
        tracking = LogTracking(log, frame, topics, PersonTracker.learned(classifier), occupancy, args.odometry)
        writer = None
        if args.mcap is not None:
            meta = {"source": str(args.file), "frame": frame, "odometry": args.odometry, "scan_topic": tracking.scan_topic.name}
            if tracking.motion_source is not None:
                meta["motion"] = tracking.motion_source  # what placed the scan's frame
            writer = outputs.enter_context(FoxgloveWriter(args.mcap, metadata={"tracking": meta}))
        bar = outputs.enter_context(tqdm(total=tracking.scan_topic.count, unit="scan", desc="tracking",
                                         disable=not show_bars(args.quiet), leave=False))
        last_stamp = 0
        for scan, result in tracking:
            last_stamp = scan.stamp_ns
            rows.extend(result_rows(result))
            if writer is not None:
                write_tracked_scan(writer, scan, result)
            bar.update(1)
        damage = log.damage
        if writer is not None and (damage or tracking.skipped):
            note = f"read up to damage: {damage}" if damage else f"{tracking.skipped} scans had no pose"
            writer.write("/log", "foxglove.Log", log_line(last_stamp, note, "warning"), last_stamp)
    table = TrackTable(rows)
    if args.out is not None:
        table.write_csv(args.out)
    else:
        write_rows(sys.stdout, table.rows)
    _warn_damage(damage)
    if tracking.skipped and tracking.scan_odometry is not None:
        sys.stderr.write(f"warning: scan matching could not place {tracking.skipped} scans (too few points or too few "
                         "matched); they were left out\n")
    elif tracking.skipped:
        sys.stderr.write(f"warning: {tracking.skipped} scans fell outside the odometry's time span and were left out\n")
    if tracking.unmapped:
        sys.stderr.write(f"warning: at {tracking.unmapped} scans tf gave no pose in the map's frame {args.map_frame!r}; "
                         "they were tracked without the map\n")
    where = f" -> {args.out}" if args.out else ""
    if not args.quiet:
        moved = f"; motion from {tracking.motion_source}" if tracking.motion_source else ""
        sys.stderr.write(f"{len(table.ids)} tracks, {len(table)} rows from {tracking.scan_topic.name} of {args.file}{where}{moved}\n")
    return 0
