"""`trials log score-tracks BAG TRACKS`: CLEAR-MOT of a tracks CSV against the people labelled in a log."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from trials import option_types as types


def register(group: argparse._SubParsersAction) -> None:
    parser = group.add_parser(
        "score-tracks",
        help="CLEAR-MOT (MOTA, MOTP, misses, false positives, id switches) of tracks against labelled people",
        description="Score a tracks CSV (trials log track) against the people labelled in the log it came from "
        "(leg_tracker Person, one message per person, or PersonArray, or geometry_msgs/PoseArray), by Leigh et al.'s protocol: a match within 0.75 m, "
        "matches carried over while they hold, then Hungarian assignment; every scan counts, a scan without a "
        "label holding nobody. Figures are printed over all scans and over the labelled scans.",
    )
    parser.add_argument("file", type=Path, metavar="BAG", help="the log with the labels")
    parser.add_argument("tracks", type=types.input_file, metavar="TRACKS", help="the tracks CSV")
    parser.add_argument("--scan-topic", metavar="TOPIC", help="LaserScan topic whose scans are scored (default: the only one)")
    parser.add_argument("--gt-topic", metavar="TOPIC", help="topic of the labelled people (default: the only Person, PersonArray or PoseArray topic)")
    parser.add_argument("--gt-frame", metavar="FRAME", help="frame of the labels when their header names none or a wrong one")
    parser.add_argument("--radius", type=types.number(0.0, 100.0, above=True), default=0.75, metavar="M",
                        help="largest distance of a match (default 0.75 m)")
    parser.add_argument("--window", type=types.number(-180.0, 180.0), nargs=2, metavar=("LOW", "HIGH"),
                        help="count only people and tracks at bearings from LOW to HIGH degrees (sensor-frame tracks), "
                        "e.g. -80 12")
    parser.set_defaults(handler=score_tracks)


def score_tracks(args: argparse.Namespace) -> int:
    from robot_logs.track_scoring import Window, score_tracks
    from robot_logs.tracks import TrackTable

    window = None
    if args.window is not None:
        low, high = sorted(args.window)
        window = Window(math.radians(low), math.radians(high))
    tracks = TrackTable.read_csv(args.tracks)
    results = score_tracks(args.file, tracks, args.radius, scan_topic=args.scan_topic, gt_topic=args.gt_topic,
                           gt_frame=args.gt_frame, window=window)
    for name, s in results.items():
        print(f"{name} ({s.scans} scans, {s.objects} labelled person-scans): MOTA {s.mota:.3f}, MOTP {s.motp:.3f} m, "
              f"recall {s.recall:.3f}, misses {s.misses}, false positives {s.false_positives}, id switches {s.id_switches}")
    return 0
