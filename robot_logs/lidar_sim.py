"""A simulated planar lidar: rays cast against pedestrians and walls, with seeded noise.

Pedestrians are two leg circles that swing with the gait while walking (or one body disc);
walls are line segments and static posts (furniture legs, pillars: `robot_logs.clutter`) circles. The result is a `Scan` like one read from a log, so the same
detector and tracker run on simulated and real data; `LidarSimulator.observe` also says how many
beams fell on each pedestrian, so a benchmark can count only the people the lidar sees.
Conventions follow REP 117: a beam with no return reads +inf, a failed (dropped-out) beam NaN.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from robot_logs.frames import Pose2D
from robot_logs.records import Scan, beam_count

#: Gait phase offset between consecutive pedestrians (the golden angle: never in step).
_PHASE_OFFSET = math.pi * (3.0 - math.sqrt(5.0))


@dataclass(frozen=True)
class LidarSpec:
    """Beam geometry, range limits (m) and noise of the simulated sensor.

    Defaults: a 270-degree scanner at 0.25-degree resolution, 0.05-10 m, 1 cm range noise.
    `fitted()` is the lidar of the labelled sample bags, the one the shipped leg detector learned from.
    """

    angle_min: float = -0.75 * math.pi
    angle_max: float = 0.75 * math.pi
    angle_increment: float = math.radians(0.25)
    range_min: float = 0.05
    range_max: float = 10.0
    range_noise_std: float = 0.01
    dropout: float = 0.0
    frame_id: str = "laser"

    @classmethod
    def fitted(cls) -> LidarSpec:
        """The labelled sample bags' lidar, as `robot_logs.leg_fit` measures it (docs/leg_detector.md): 768
        beams from -135 degrees at 360/1024 degrees, 0.03-11 m, 3 mm range noise."""
        increment = 2.0 * math.pi / 1024
        return cls(angle_min=-0.75 * math.pi, angle_max=-0.75 * math.pi + 767 * increment, angle_increment=increment,
                   range_min=0.03, range_max=11.0, range_noise_std=0.003)

    @property
    def beams(self) -> int:
        """Number of beams per scan."""
        return beam_count(self.angle_min, self.angle_max, self.angle_increment)

    def angles(self) -> np.ndarray:
        """(beams,) beam bearings in the sensor frame."""
        return self.angle_min + self.angle_increment * np.arange(self.beams)


@dataclass(frozen=True)
class BodyModel:
    """What a pedestrian looks like at lidar height (m, s).

    Attributes:
        shape: "legs" (two swinging leg circles) or "disc" (one body circle).
        leg_radius: radius of each leg.
        leg_spread: sideways distance between the two leg centres.
        stride: fore-aft swing amplitude of each leg at `walking_speed` and above.
        walking_speed: speed at which the full stride is reached; slower means shorter swing.
        cadence_hz: gait cycles per second.
        disc_radius: radius of the body disc.

    `fitted()` gives the legs of the labelled sample bags' walkers.
    """

    shape: Literal["legs", "disc"] = "legs"
    leg_radius: float = 0.06
    leg_spread: float = 0.2
    stride: float = 0.25
    walking_speed: float = 1.3
    cadence_hz: float = 0.9
    disc_radius: float = 0.25

    @classmethod
    def fitted(cls) -> BodyModel:
        """Legs like those of the labelled sample bags' walkers, as `robot_logs.leg_fit` measures them
        (docs/leg_detector.md): 6.7 cm in radius, 17 cm apart sideways, each swinging 15 cm fore and aft
        (the full swing from 1 m/s) at 0.77 strides a second."""
        return cls(leg_radius=0.067, leg_spread=0.17, stride=0.15, walking_speed=1.0, cadence_hz=0.77)


def body_circles(
    positions: np.ndarray, velocities: np.ndarray, time: float, body: BodyModel
) -> tuple[np.ndarray, np.ndarray]:
    """World circles of every pedestrian: (K, 2) centres and (K,) radii.

    A walking person's legs swing in antiphase along the walking direction; a standing one
    (speed under 5 cm/s) stands with both legs side by side, facing +x.
    """
    positions = np.asarray(positions, dtype=float).reshape(-1, 2)
    if body.shape == "disc":
        return positions, np.full(len(positions), body.disc_radius)
    velocities = np.asarray(velocities, dtype=float).reshape(-1, 2)
    speed = np.hypot(velocities[:, 0], velocities[:, 1])
    moving = speed > 0.05
    heading = np.where(moving, np.arctan2(velocities[:, 1], velocities[:, 0]), 0.0)
    forward = np.column_stack((np.cos(heading), np.sin(heading)))
    side = np.column_stack((-forward[:, 1], forward[:, 0]))
    phase = 2.0 * math.pi * body.cadence_hz * time + _PHASE_OFFSET * np.arange(len(positions))
    swing = body.stride * np.minimum(speed / body.walking_speed, 1.0) * np.sin(phase)
    offset = side * (body.leg_spread / 2.0) + forward * swing[:, None]
    centres = np.concatenate((positions + offset, positions - offset))
    return centres, np.full(len(centres), body.leg_radius)


def cast_rays(
    origin: np.ndarray, bearings: np.ndarray, centres: np.ndarray, radii: np.ndarray, walls: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Along each world bearing: (B,) distance to the nearest circle or wall (inf if none) and
    (B,) what it hit: a circle's index, len(centres) + a wall's index, or -1 for nothing."""
    directions = np.column_stack((np.cos(bearings), np.sin(bearings)))
    near = np.full((len(bearings), 1), np.inf)
    if len(centres):
        offsets = centres - origin
        along = directions @ offsets.T
        clearance = along**2 - (np.einsum("kd,kd->k", offsets, offsets) - radii**2)
        with np.errstate(invalid="ignore"):
            circles = along - np.sqrt(clearance)
        circles[(clearance < 0.0) | (circles <= 0.0)] = np.inf
        near = np.concatenate((near, circles), axis=1)
    if len(walls):
        start, edge = walls[:, 0, :] - origin, walls[:, 1, :] - walls[:, 0, :]
        denominator = directions[:, 0:1] * edge[:, 1] - directions[:, 1:2] * edge[:, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (start[:, 0] * edge[:, 1] - start[:, 1] * edge[:, 0]) / denominator
            u = (start[:, 0] * directions[:, 1:2] - start[:, 1] * directions[:, 0:1]) / denominator
        t[~((t > 0.0) & (u >= 0.0) & (u <= 1.0))] = np.inf
        near = np.concatenate((near, t), axis=1)
    nearest = near.argmin(axis=1)
    return near[np.arange(len(bearings)), nearest], nearest - 1


class LidarSimulator:
    """Seeded scans of pedestrians (and optional walls) seen from a moving sensor.

    Scans meant for the shipped leg detector (`PersonTracker.learned()`, as on a real robot) take
    `LidarSpec.fitted()` and `BodyModel.fitted()`: its trees learned the sample bags' legs and lidar,
    and it recognises few of the default legs (docs/leg_detector.md has the figures).

    Args:
        spec: beam geometry, limits and noise.
        body: how pedestrians look at lidar height.
        seed: seeds the range noise and dropouts (record it with the run).
        walls: (W, 2, 2) wall segments in the world frame, endpoints in metres.
        posts: static circles in the world frame, (K, 2) centres and (K,) radii (m).
    """

    def __init__(
        self,
        spec: LidarSpec = LidarSpec(),
        body: BodyModel = BodyModel(),
        seed: int = 0,
        walls: np.ndarray | None = None,
        posts: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> None:
        self.spec = spec
        self.body = body
        self.seed = seed
        self.walls = np.zeros((0, 2, 2)) if walls is None else np.asarray(walls, dtype=float).reshape(-1, 2, 2)
        centres, radii = posts if posts is not None else (np.zeros((0, 2)), np.zeros(0))
        self.post_centres = np.asarray(centres, dtype=float).reshape(-1, 2)
        self.post_radii = np.asarray(radii, dtype=float).reshape(-1)
        self._rng = np.random.default_rng(seed)
        self._angles = spec.angles()

    def scan(
        self,
        time: float,
        sensor_pose: Pose2D,
        positions: np.ndarray,
        velocities: np.ndarray | None = None,
    ) -> Scan:
        """The scan taken at `time` (s) from `sensor_pose` (world frame).

        Args:
            time: scan time in seconds; also drives the gait phase.
            sensor_pose: pose of the lidar in the world frame.
            positions: (N, 2) pedestrian positions in the world frame.
            velocities: (N, 2) their velocities (m/s), which orient the legs; None: standing.
        """
        return self.observe(time, sensor_pose, positions, velocities)[0]

    def observe(
        self,
        time: float,
        sensor_pose: Pose2D,
        positions: np.ndarray,
        velocities: np.ndarray | None = None,
    ) -> tuple[Scan, np.ndarray]:
        """The scan `scan` returns, and (N,) how many of its valid beams fell on each pedestrian:
        the ground truth of who the lidar can see (a person hidden behind others or furniture gets 0)."""
        positions = np.asarray(positions, dtype=float).reshape(-1, 2)
        if velocities is None:
            velocities = np.zeros_like(positions)
        centres, radii = body_circles(positions, velocities, time, self.body)
        centres = np.concatenate((centres, self.post_centres))
        radii = np.concatenate((radii, self.post_radii))
        origin = np.array([sensor_pose.x, sensor_pose.y])
        ranges, hit = cast_rays(origin, self._angles + sensor_pose.yaw, centres, radii, self.walls)
        spec = self.spec
        ranges = ranges + self._rng.normal(0.0, spec.range_noise_std, len(ranges))
        ranges[(ranges < spec.range_min) | (ranges > spec.range_max)] = np.inf
        if spec.dropout > 0.0:
            ranges[self._rng.random(len(ranges)) < spec.dropout] = np.nan
        circles_per_person = 1 if self.body.shape == "disc" else 2
        on_person = np.isfinite(ranges) & (hit >= 0) & (hit < circles_per_person * len(positions))
        beams = np.bincount(hit[on_person] % max(len(positions), 1), minlength=len(positions))
        scan = Scan(
            stamp_ns=int(round(time * 1e9)),
            frame_id=spec.frame_id,
            angle_min=spec.angle_min,
            angle_increment=spec.angle_increment,
            range_min=spec.range_min,
            range_max=spec.range_max,
            ranges=ranges,
        )
        return scan, beams
