"""Benchmark of live runs (issue 37): scan-to-command latency and planning time against the software robot, over
each transport and with each controller, and a whole blinded A/B study of 18 live runs over ROS 1 (or each transport named), unblinded.

    python benchmarks/bench_live.py [--transports ros1 ros2] [--repeats 2] [--studies ros1 ros2]

Latency: the software robot (`trials robot-sim`, its own process) publishes 40 Hz scans of the A/B plan's first row
(6 walkers) in its walled room; this process drives it with `trials.robot.live.LiveRun` and each controller, and times
every scan from its arrival to the velocity command sent after it was tracked, the protective field checked (the
tracking, field and follower path; goal: p99 under 50 ms), and every plan (goal: within its 0.4 s step). `--load N`
keeps N other processes busy meanwhile (N = 2 loads both cores of a 2-core machine). Whole study: `trials design --ab
--robot`, then `trials run --robot` over all 18 rows against the software robot (20 Hz scans, its 22 x 10 m room and
its bumper), its wall time, how each run ended and how often the bumper touched a wall, then `trials report --unblind`
and how many runs' sealed records name the controller the key gives their arm.
A ROS 1 master (Debian's `rosmaster`) is started on a free port; ROS 2 stays on the loopback.
"""

from __future__ import annotations

import argparse
import os
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np

from trials.controllers import registry
from trials.live_checks import read_check_log
from trials.robot.live import LiveRun, LiveSink, RobotLink, StopRequest, warm_up
from trials.robot.one_driver import new_session
from trials.robot.settings import RobotSettings
from trials.sealed_runs import read_sealed_run
from trials.study import OUTCOMES, StudyFolder

TRIALS = (sys.executable, "-m", "trials.cli")
#: The latency and planning goals (s).
LATENCY_P99_GOAL, PLAN_GOAL = 0.050, 0.4


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@contextmanager
def middleware(kind: str, home: Path) -> Iterator[str]:
    """A robot URI to use: a fresh ROS 1 master on a free port, or a ROS 2 domain on the loopback."""
    if kind == "ros2":
        os.environ["NAVTRIALS_DDS_LOOPBACK"] = "1"
        yield f"ros2://{100 + os.getpid() % 100}"
        return
    port = free_port()
    master = subprocess.Popen(["rosmaster", "--core", "-p", str(port)], env={**os.environ, "ROS_HOME": str(home)},
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        time.sleep(2.0)
        yield f"ros1://127.0.0.1:{port}"
    finally:
        master.kill()
        master.wait()


@contextmanager
def software_robot(uri: str, study: Path, scan_rate: float) -> Iterator[subprocess.Popen]:
    """`trials robot-sim` for the study, writing its bumper's wall contacts to contacts.csv beside the study."""
    robot = subprocess.Popen([*TRIALS, "robot-sim", "--ros", uri, "--study", str(study), "--scan-rate", f"{scan_rate:g}",
                              "--contacts", str(study.parent / f"{study.name}-contacts.csv")],
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        yield robot
    finally:
        robot.kill()
        robot.wait()


def design(folder: Path, uri: str) -> StudyFolder:
    subprocess.run([*TRIALS, "design", "--ab", "--robot", uri, "--seed", "5", "--study", str(folder)], check=True, capture_output=True)
    return StudyFolder(folder)


@contextmanager
def load(processes: int) -> Iterator[None]:
    """`processes` other processes spinning on the CPU meanwhile."""
    busy = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(processes)]
    try:
        yield
    finally:
        for process in busy:
            process.kill()
            process.wait()


def latency(kind: str, repeats: int, home: Path, loaded: int) -> None:
    """Drive the first row of the A/B plan `repeats` times with each controller; print latency and planning figures."""
    with middleware(kind, home) as uri:
        study = design(home / f"latency-{kind}", uri)
        row = next(r for r in study.read_plan() if r["Pedestrians"] == "6")
        settings = RobotSettings(uri=uri, sensor_wait=60.0)
        link = RobotLink.open(settings, new_session())
        with software_robot(uri, study.root, 40.0), load(loaded):
            for name in registry.AB_PRESET:
                controller = registry.build(name)
                warm_up([controller])
                latencies, plans, ends = [], [], []
                for k in range(repeats):
                    controller.reset(k)
                    live = LiveRun(link, StopRequest())
                    reason = live.wait(row["run_code"], None)  # unstaged: the software robot returns to its start
                    assert reason is None, reason
                    end = live.drive(controller, settings.goal_for(row), LiveSink())
                    latencies += end.latencies
                    plans += end.plan_seconds
                    ends.append(f"{end.status} {end.duration_s:.1f} s, {end.late_plans} late")
                lat = np.array(latencies) * 1e3
                plan = np.array(plans)
                print(f"| {kind} | {loaded} | {name} | {len(lat)} | {np.percentile(lat, 50):.1f} | {np.percentile(lat, 99):.1f} | "
                      f"{'met' if np.percentile(lat, 99) < LATENCY_P99_GOAL * 1e3 else 'NOT met'} | {np.percentile(plan, 50) * 1e3:.0f} | "
                      f"{plan.max() * 1e3:.0f} | {'met' if plan.max() < PLAN_GOAL else 'NOT met'} | {'; '.join(ends)} |", flush=True)
        link.close()


def whole_study(kind: str, home: Path) -> None:
    """All 18 rows of a blinded A/B study driven live over `kind` against the software robot, then unblinded."""
    with middleware(kind, home) as uri:
        study = design(home / f"study-{kind}", uri)
        with software_robot(uri, study.root, 20.0):
            # The start mark, measured once where the software robot stands; every row is staged relative to it.
            subprocess.run([*TRIALS, "run", "--robot", uri, "--mark", "--study", str(study.root)], check=True, capture_output=True)
            began = time.monotonic()
            # The operator's Enter before each row after the first: the software robot is brought to its start by itself.
            run = subprocess.run([*TRIALS, "run", "--robot", uri, "--study", str(study.root)], capture_output=True, text=True,
                                 input="\n" * 17)
            wall = time.monotonic() - began
        finished = StudyFolder(study.root).path(OUTCOMES).read_text(encoding="utf-8").splitlines()[1:]
        statuses = [line.split(",")[1] for line in finished]
        failed = sorted(study.root.glob("runs/*.failed.txt"))
        counts = ", ".join(f"{statuses.count(s)} {s}" for s in sorted(set(statuses)))
        contacts = study.root.parent / f"{study.root.name}-contacts.csv"
        touched = len(contacts.read_text(encoding="utf-8").splitlines()) if contacts.exists() else 0
        print(f"18-run blinded A/B study over {kind}: {wall:.0f} s wall ({wall / 18:.1f} s a run); finished {len(finished)} ({counts}); "
              f"aborted or failed {len(failed)}; wall contacts {touched}; trials run exit code {run.returncode}")
        for path in failed:
            print(f"  {path.name}: {path.read_text(encoding='utf-8').strip()}")
        checks = read_check_log(study)
        print(f"  live checks: {len(checks)}; row's condition met {sum(c.condition_met is True for c in checks)}; flagged "
              f"{sum(bool(c.flag) for c in checks)}" + "".join(f"\n    {c.run_code}: {c.flag}" for c in checks if c.flag))
        digest = study.read_design()["blinding"]["commitment"]["digest"]
        report = subprocess.run([*TRIALS, "report", "--study", str(study.root), "--unblind", "--commitment", digest, "--quiet"],
                                capture_output=True, text=True)
        drove = {row["run_code"]: row["Controller"] for row in study.read_plan()}
        sealed = {code: read_sealed_run(study, code)["controller"] for code in drove if study.sealed_run(code).exists()}
        arms = study.read_sealed().arms
        print(f"  trials report --unblind exit code {report.returncode}; runs whose sealed record names the key's controller for "
              f"their arm: {sum(sealed[c] == arms[a] for c, a in drove.items() if c in sealed)} of {len(drove)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--transports", nargs="*", choices=("ros1", "ros2"), default=["ros1", "ros2"],
                        help="transports to measure the latency over (default both; none: leave it out)")
    parser.add_argument("--repeats", type=int, default=2, help="runs per controller and transport (default 2)")
    parser.add_argument("--load", type=int, default=0, metavar="N", help="busy processes during the latency runs (default 0)")
    parser.add_argument("--studies", nargs="*", choices=("ros1", "ros2"), default=["ros1"],
                        help="transports to drive the whole 18-run study over (default ros1; none: leave it out)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        home = Path(folder)
        print("| transport | busy processes | controller | scans | latency p50 ms | p99 ms | goal p99 < 50 ms | plan p50 ms | plan max ms "
              "| goal < 400 ms | runs |")
        print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
        for kind in args.transports:
            latency(kind, args.repeats, home, args.load)
        for kind in args.studies:
            whole_study(kind, home)


if __name__ == "__main__":
    main()
