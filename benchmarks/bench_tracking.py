"""Benchmark of lidar person tracking (issue 8): speed, CLEAR-MOT on simulated scans, and
detection against the hand-labelled legs of a real recording.

    python benchmarks/bench_tracking.py [--seeds 10] [--duration 60]

Speed: detection plus tracking of pre-simulated scans with 6 walking people, one thread
(goal: 200 scans/s, five times a 40 Hz lidar). Quality: CLEAR-MOT (match radius 0.5 m) on
held-out seeds with 6 pedestrians (goal: MOTA >= 0.9).
"""

from __future__ import annotations

import os

for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")  # one core, before numpy loads its BLAS

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository root, for tests.support

import numpy as np

from robot_logs.detection import detect
from robot_logs.frames import Pose2D
from robot_logs.lidar_sim import BodyModel, LidarSimulator, LidarSpec
from robot_logs.pipeline import PersonTracker
from robot_logs.reader import LogReader
from tests.support.crowd import walking_crowd
from tests.support.evaluation import clear_mot, labelled_scans, score_detections

SAMPLES = Path(__file__).resolve().parents[1] / "tests" / "data" / "robot_logs"
PEOPLE = 6


def simulate(seed: int, duration: float, shape: str, rate_hz: float = 10.0):
    """Ground truth and scans of one simulated walk, seen from a lidar at the origin."""
    crowd = walking_crowd(PEOPLE, duration, rate_hz, seed=seed)
    lidar = LidarSimulator(LidarSpec(), BodyModel(shape=shape), seed=seed)
    scans = [lidar.scan(t, Pose2D(), p, v) for t, p, v in zip(crowd.times, crowd.positions, crowd.velocities)]
    return crowd, scans


def speed(duration: float) -> float:
    """Scans per second of detection plus tracking (best of three passes)."""
    _, scans = simulate(seed=1, duration=duration, shape="legs", rate_hz=40.0)
    best = 0.0
    for _ in range(3):
        tracker = PersonTracker()
        start = time.perf_counter()
        for scan in scans:
            tracker.process(scan)
        best = max(best, len(scans) / (time.perf_counter() - start))
    return best


def quality(seeds: range, duration: float, shape: str) -> dict[str, float]:
    """CLEAR-MOT summed over seeds (MOTA and MOTP over all frames together)."""
    totals = {"id_switches": 0.0, "false_positives": 0.0, "misses": 0.0, "objects": 0.0}
    weighted_motp = matches = 0.0
    for seed in seeds:
        crowd, scans = simulate(seed, duration, shape)
        tracker = PersonTracker()
        tracks = [tracker.process(scan).tracks for scan in scans]
        figures = clear_mot(list(crowd.positions), tracks)
        for key in totals:
            totals[key] += figures[key]
        found = figures["objects"] - figures["misses"]
        weighted_motp += figures["motp"] * found
        matches += found
    errors = totals["false_positives"] + totals["misses"] + totals["id_switches"]
    return {**totals, "mota": 1.0 - errors / totals["objects"], "motp": weighted_motp / matches}


def labelled_legs() -> str:
    """Detected legs against the hand-labelled legs of legs_labelled_ros1.bag."""
    path = SAMPLES / "legs_labelled_ros1.bag"
    if not path.exists():
        return f"(no {path})"
    with LogReader(path) as log:
        pairs = labelled_scans(log)
    lines = []
    for radius in (0.1, 0.15):
        score = score_detections(((detect(scan).legs, label.points) for scan, label in pairs), radius)
        lines.append(
            f"  within {radius:.2f} m: recall {score.recall:.3f}, precision {score.precision:.3f} "
            f"({score.matched} matched, {score.missed} missed, {score.spurious} unlabelled segments), "
            f"mean error {1000 * score.mean_error:.1f} mm over {len(pairs)} scans"
        )
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10, help="held-out seeds for CLEAR-MOT (100, 101, ...)")
    parser.add_argument("--duration", type=float, default=60.0, help="seconds simulated per seed")
    args = parser.parse_args()
    spec = LidarSpec()
    print(f"lidar: {spec.beams} beams over 270 deg at {np.degrees(spec.angle_increment):.2f} deg, {PEOPLE} people")
    print(f"speed: {speed(min(args.duration, 30.0)):.0f} scans/s for detection + tracking on one core (goal >= 200)")
    seeds = range(100, 100 + args.seeds)
    for shape in ("legs", "disc"):
        q = quality(seeds, args.duration, shape)
        print(
            f"CLEAR-MOT, {shape} model, {len(seeds)} seeds x {args.duration:.0f} s at 10 Hz: MOTA {q['mota']:.3f} "
            f"(goal >= 0.9), MOTP {q['motp']:.3f} m, id switches {q['id_switches']:.0f}, "
            f"false positives {q['false_positives']:.0f}, misses {q['misses']:.0f} of {q['objects']:.0f}"
        )
    print("detection vs hand-labelled legs (real scans):")
    print(labelled_legs())


if __name__ == "__main__":
    main()
