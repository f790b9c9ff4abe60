"""`trials robot-sim`: the software robot behind ROS topics, to rehearse a field day or test live runs without the robot."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from trials import option_types as types
from trials.robot.transport import TWIST_TYPES

#: What `--unstaged` leaves unstaged (`trials.robot.software_robot.SoftwareRobotConfig.unstaged`).
UNSTAGED = ("robot", "walkers")


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "robot-sim",
        help="a software robot on ROS 1 or ROS 2 for rehearsing live runs: simulated lidar with walkers, odometry, tf; obeys cmd_vel",
        description=(
            "Put the closed-loop simulator behind a robot's ROS topics: LaserScans of a simulated lidar whose walkers look "
            "like real legs, nav_msgs/Odometry and tf, all stamped with this computer's clock, and a base that obeys "
            "geometry_msgs/Twist within the robot's limits and stops by itself when commands stop coming. When `trials run "
            "--robot` starts a run, the robot lays out that plan row's walkers ahead of where it stands. Topics and frames "
            "come from the study's [robot] table (--study), else the defaults. Runs until Ctrl-C."
        ),
    )
    parser.add_argument("--ros", required=True, metavar="URI",
                        help="where to appear: ros1://HOST:PORT (a running ROS 1 master) or ros2://DOMAIN")
    parser.add_argument("--study", type=types.folder, metavar="DIR", help="lay out each announced run's scene from this study's plan")
    parser.add_argument("--scan-rate", type=types.number(1, 100), default=40.0, metavar="HZ", help="lidar scans per second (default 40)")
    parser.add_argument("--scan-latency", type=types.number(0, 0.4), default=0.0, metavar="S",
                        help="publish each scan S seconds after its stamp, as a real laser's driver does (default 0)")
    parser.add_argument("--command-timeout", type=types.number(0.05, 5), default=0.5, metavar="S",
                        help="the base stops when no velocity command has come for this long (default 0.5 s)")
    parser.add_argument("--seed", type=types.whole(0), default=0, metavar="N", help="seeds the lidar's noise and the default scene (default 0)")
    parser.add_argument("--duration", type=types.number(0, math.inf, above=True, below=True), metavar="S", help="stop after S seconds")
    parser.add_argument("--commands", type=Path, metavar="FILE",
                        help="append every velocity command received to FILE as `wall_ns,linear,angular` lines")
    parser.add_argument("--contacts", type=Path, metavar="FILE",
                        help="append `wall_ns,x,y` to FILE each time the robot's footprint comes to touch a wall (its bumper)")
    parser.add_argument("--truth", type=Path, metavar="FILE",
                        help="append the ground truth at each scan's stamp to FILE: `stamp_ns,x,y,theta` of the robot, then "
                        "`x,y` of each walker (odometry frame), to check what a run measured")
    parser.add_argument("--room", metavar="X0,Y0,X1,Y1",
                        help="the walled room in the odometry frame, in metres, the robot's start at the origin facing +x "
                        "(default -6,-5,16,5: 22 x 10 m; written --room=-6,-5,16,5); `none` for open ground")
    parser.add_argument("--cmd-vel-type", choices=TWIST_TYPES, metavar="TYPE",
                        help="the velocity command type the base takes (Twist or TwistStamped; default: the study's cmd_vel_type)")
    parser.add_argument("--fault", action="append", default=[], metavar="KIND@S",
                        help="stage a failure S seconds after each run starts, to rehearse the stop rules: scans-stop, scans-late "
                        "(stamps 1 s old), scans-blank (every range NaN), odometry-stop, odometry-stale (stamp frozen), stall "
                        "(the wheels blocked); may be repeated")
    parser.add_argument("--unstaged", action="append", default=[], choices=UNSTAGED, metavar="WHAT",
                        help="rehearse a row staged wrong: robot (the robot is not brought to its start and stays where it "
                        "stands) or walkers (nobody walks); may be repeated")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    import signal
    import threading
    from dataclasses import replace

    from trials.robot.settings import RobotSettings, read_robot_settings
    from trials.robot.software_robot import ROOM, Fault, SoftwareRobot, SoftwareRobotConfig, open_commands, parse_room
    from trials.robot.transport import RobotUri, open_transport
    from trials.study import SPEC, StudyFolder

    uri = RobotUri.parse(args.ros)
    study = StudyFolder(args.study) if args.study is not None else None
    if study is not None:
        study.read_plan()
    settings = replace((read_robot_settings(study.path(SPEC)) if study else None) or RobotSettings(), uri=str(uri))
    if args.cmd_vel_type is not None:
        settings = replace(settings, cmd_vel_type=args.cmd_vel_type)
    config = SoftwareRobotConfig(scan_rate=args.scan_rate, scan_latency=args.scan_latency, command_timeout=args.command_timeout, seed=args.seed,
                                 faults=tuple(Fault.parse(text) for text in args.fault),
                                 room=ROOM if args.room is None else parse_room(args.room), unstaged=frozenset(args.unstaged))
    stop = threading.Event()

    def quit_(signum: int, frame: object) -> None:
        stop.set()

    signal.signal(signal.SIGTERM, quit_)
    signal.signal(signal.SIGINT, quit_)
    commands, contacts, truth = open_commands(args.commands), open_commands(args.contacts), open_commands(args.truth)
    robot = SoftwareRobot(open_transport(uri, "navtrials_robot"), settings, config, study, commands, contacts, truth)
    print(f"Software robot on {uri}: scans on {settings.scan_topic} at {args.scan_rate:g} Hz, odometry on "
          f"{settings.odometry_topic or '(tf only)'}, commands on {settings.cmd_vel_topic}; Ctrl-C stops it", flush=True)
    try:
        robot.run(stop, args.duration)
    finally:
        robot.close()
        for kept in (commands, contacts, truth):
            if kept is not None:
                kept.close()
    return 0

