"""Measure the labelled sample bags' legs and lidar (robot_logs.leg_fit) and print them beside the
simulator's presets fitted to them, `BodyModel.fitted()` and `LidarSpec.fitted()` (issue 37).

    python scripts/fit_sim_legs.py [BAG ...]    # default: the six labelled bags in tests/data/robot_logs

tests/test_robot_logs_sim_legs.py checks that the presets stay within their tolerances of these figures.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from robot_logs.leg_fit import RANGE_BANDS, fit_legs
from robot_logs.lidar_sim import BodyModel, LidarSpec

SAMPLES = Path(__file__).resolve().parents[1] / "tests" / "data" / "robot_logs"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("bags", nargs="*", type=Path, help="labelled logs (default: the sample bags)")
    args = parser.parse_args()
    bags = args.bags or [SAMPLES / "legs_labelled_ros1.bag", *sorted((SAMPLES / "leg_training").glob("positive_*.bag"))]
    fit = fit_legs(bags)
    sensor, shapes, gait = fit.sensor, fit.shapes, fit.gait
    spec, body = LidarSpec.fitted(), BodyModel.fitted()
    print(f"{len(bags)} labelled logs")
    print(f"lidar: {sensor.beams} beams from {math.degrees(sensor.angle_min):.2f} deg at {math.degrees(sensor.angle_increment):.4f} deg, "
          f"{sensor.range_min:.2f}-{sensor.range_max:.1f} m (preset: {spec.beams} beams at {math.degrees(spec.angle_increment):.4f} deg, "
          f"{spec.range_min:.2f}-{spec.range_max:.1f} m)")
    print(f"range noise: {sensor.range_noise_std * 1000:.2f} mm (preset {spec.range_noise_std * 1000:.1f} mm); beams on a surface "
          f"returning nothing: {sensor.dropout:.2%} (preset {spec.dropout:.0%})")
    print(f"legs seen apart: {shapes.legs}, the farthest at {shapes.farthest:.2f} m; median width {shapes.width:.3f} m, "
          f"radius {shapes.radius:.4f} m (preset {body.leg_radius})")
    for (low, high), points, width in zip(RANGE_BANDS, shapes.points, shapes.widths):
        print(f"  {low:.0f}-{high:.0f} m: {points:g} points, width {width:.3f} m (median per leg)")
    print(f"gait over {gait.walks} walks: legs {gait.leg_spread:.3f} m apart sideways (preset {body.leg_spread}), each swinging "
          f"{gait.stride:.3f} m (preset {body.stride}) at {gait.cadence_hz:.3f} Hz (preset {body.cadence_hz}), "
          f"walking at {gait.walking_speed:.2f} m/s (preset {body.walking_speed})")


if __name__ == "__main__":
    main()
