"""What walkers' legs look like to the lidar of the labelled sample bags, measured from their labels.

The figures `BodyModel.fitted()` and `LidarSpec.fitted()` (robot_logs.lidar_sim) take, so simulated
walkers look like the legs the shipped detector learned from: the sensor's beam geometry, range
noise and dropouts; the width of a leg seen apart from the other, the circle radius that shows that
width, and the points per leg at each range; the two legs' sideways spacing and their gait (swing,
cadence, walking speed) followed along each walk. docs/leg_detector.md gives the figures and why each
estimate was chosen.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from robot_logs.detection import DetectorConfig
from robot_logs.errors import LogError
from robot_logs.labels import labelled_scans
from robot_logs.leg_training import TrainingSettings, candidates, match_labels
from robot_logs.reader import LogReader
from robot_logs.records import Scan

#: Range bands (m) in which points and widths per leg are reported.
RANGE_BANDS = ((1.0, 2.0), (2.0, 3.0), (3.0, 4.0), (4.0, 5.0))

#: Three neighbouring beams whose second difference exceeds this (m) straddle an edge, not a surface.
EDGE = 0.05

#: Scans further apart than this (s) start a new walk; walks shorter than MIN_WALK_S are left out.
WALK_GAP_S = 0.25
MIN_WALK_S = 2.0
#: The walker's velocity is the slope of their centre over this many seconds either side.
VELOCITY_WINDOW_S = 0.7
#: Slower than this (m/s) the walker is standing or turning, and has no walking direction.
MIN_WALKING_SPEED = 0.4
#: Stride frequencies (Hz) tried when fitting the legs' fore-aft swing, and the share of the swing's
#: variance a walk's fit must explain to count (a walk cut by turns and merged legs explains less).
CADENCES_HZ = np.arange(0.5, 1.5, 0.01)
MIN_EXPLAINED = 0.5


@dataclass(frozen=True)
class SensorFit:
    """The bags' lidar: first beam and beam spacing (rad), beams per scan, range limits (m), the range
    noise (m): one beam's standard deviation on a surface, and the share of beams on a surface that
    return nothing."""

    angle_min: float
    angle_increment: float
    beams: int
    range_min: float
    range_max: float
    range_noise_std: float
    dropout: float


@dataclass(frozen=True)
class LegShapes:
    """Legs seen apart (scans whose two labelled legs are two segments): how many, the farthest (m),
    the median width (m), the radius (m) of the circle that shows that width, and per RANGE_BANDS
    the median points and width of a leg (NaN where a band has none)."""

    legs: int
    farthest: float
    width: float
    radius: float
    points: tuple[float, ...]
    widths: tuple[float, ...]


@dataclass(frozen=True)
class Gait:
    """The two legs along the walks: walks fitted, sideways spacing of the leg centres (m), each leg's
    fore-aft swing about the walker's centre (m, half the legs' separation at its largest), stride
    frequency (Hz) and walking speed (m/s), medians over walks and scans."""

    walks: int
    leg_spread: float
    stride: float
    cadence_hz: float
    walking_speed: float


@dataclass(frozen=True)
class LegFit:
    """Everything measured from the labelled bags."""

    sensor: SensorFit
    shapes: LegShapes
    gait: Gait


def _surface(valid: np.ndarray, ranges: np.ndarray) -> np.ndarray:
    """(n - 2,) True where beam k's two neighbours both return and lie within EDGE of each other:
    beam k points at the surface they hit."""
    with np.errstate(invalid="ignore"):
        return valid[2:] & valid[:-2] & (np.abs(ranges[2:] - ranges[:-2]) < EDGE)


def dropout(scans: Sequence[Scan]) -> float:
    """Share of the beams pointing at a surface (`_surface`) that return nothing."""
    surface = [(_surface(scan.valid(), scan.ranges), scan.valid()[1:-1]) for scan in scans]
    pointing = sum(int(on.sum()) for on, _ in surface)
    return sum(int((on & ~returned).sum()) for on, returned in surface) / max(pointing, 1)


def range_noise(scans: Sequence[Scan]) -> float:
    """Range noise (m) from the second differences of neighbouring beams on surfaces: locally a wall
    or a leg is nearly straight, so r[k+1] - 2 r[k] + r[k-1] is noise of variance 6 sigma^2; the
    median absolute value, robust to edges and to the 1 mm steps of the readings, gives sigma."""
    differences = []
    for scan in scans:
        valid = scan.valid()
        r = np.where(valid, scan.ranges, np.nan)
        second = r[2:] - 2.0 * r[1:-1] + r[:-2]
        differences.append(second[valid[2:] & valid[1:-1] & valid[:-2] & (np.abs(second) < EDGE)])
    return float(1.4826 * np.median(np.abs(np.concatenate(differences))) / math.sqrt(6.0))


def sensor_fit(scans: Sequence[Scan]) -> SensorFit:
    """The lidar's geometry and noise.

    Raises:
        LogError: no scans, or scans of lidars with different geometry.
    """
    if not scans:
        raise LogError("no scans to measure the lidar from")
    first = scans[0]
    geometry = (first.angle_min, first.angle_increment, len(first.ranges), first.range_min, first.range_max)
    if any((s.angle_min, s.angle_increment, len(s.ranges), s.range_min, s.range_max) != geometry for s in scans):
        raise LogError("the scans come from lidars with different beam geometry or range limits")
    return SensorFit(*geometry, range_noise(scans), dropout(scans))


def leg_shapes(pairs: Sequence[tuple[Scan, np.ndarray]]) -> LegShapes:
    """Width, radius and points of the legs in scans with two labelled legs, each matched to its own
    segment as the detector's training matches them (`leg_training.match_labels`).

    A circle of radius r seen by beams dtheta apart at range d is hit across 2 r, its outermost hits
    on average half a beam spacing inside each edge, so a leg of width w has r = (w + d dtheta) / 2.

    Raises:
        LogError: no scan shows two legs apart.
    """
    widths, distances, counts, radii = [], [], [], []
    config, settings = DetectorConfig(), TrainingSettings()
    for scan, labels in pairs:
        if len(labels) != 2:
            continue
        segments, mask = candidates(scan, config)
        leg, _ = match_labels(segments.centroids[mask], labels, settings)
        if leg.sum() != 2:
            continue
        chosen = np.flatnonzero(mask)[leg]
        width, distance = segments.widths[chosen], np.hypot(*segments.centroids[chosen].T)
        widths.extend(width)
        distances.extend(distance)
        counts.extend(segments.counts[chosen])
        radii.extend((width + distance * scan.angle_increment) / 2.0)
    if not widths:
        raise LogError("no scan shows two labelled legs as two segments")
    width, distance, count = np.array(widths), np.array(distances), np.array(counts)
    bands = [(distance >= low) & (distance < high) for low, high in RANGE_BANDS]
    return LegShapes(
        legs=len(width),
        farthest=float(distance.max()),
        width=float(np.median(width)),
        radius=float(np.median(radii)),
        points=tuple(float(np.median(count[band])) if band.any() else math.nan for band in bands),
        widths=tuple(float(np.median(width[band])) if band.any() else math.nan for band in bands),
    )


@dataclass(frozen=True)
class _Walk:
    """One walk's two-leg scans: sideways spacing, signed fore-aft separation (left leg minus right)
    and their times, and the walker's speed at every moving scan."""

    times: np.ndarray
    separation: np.ndarray
    spread: np.ndarray
    speed: np.ndarray


def _walk(times: np.ndarray, labels: Sequence[np.ndarray]) -> _Walk:
    """The legs of one walk's scans (stamps `times`, each scan's labelled legs) about the walker's centre."""
    centre = np.array([legs.mean(axis=0) if 1 <= len(legs) <= 2 else (np.nan, np.nan) for legs in labels])
    known = np.isfinite(centre[:, 0])
    kept_times, separation, spread, speeds = [], [], [], []
    for k, when in enumerate(times):
        near = known & (np.abs(times - when) <= VELOCITY_WINDOW_S)
        if near.sum() < 5:
            continue
        velocity = np.array([np.polyfit(times[near], centre[near, axis], 1)[0] for axis in (0, 1)])
        speed = float(np.hypot(*velocity))
        if speed < MIN_WALKING_SPEED:
            continue
        speeds.append(speed)
        if len(labels[k]) != 2:
            continue
        forward = velocity / speed
        side = np.array([-forward[1], forward[0]])
        apart = labels[k][0] - labels[k][1]
        apart = apart if apart @ side >= 0.0 else -apart  # the left leg minus the right one
        kept_times.append(when)
        separation.append(apart @ forward)
        spread.append(apart @ side)
    return _Walk(np.array(kept_times), np.array(separation), np.array(spread), np.array(speeds))


def _swing(times: np.ndarray, separation: np.ndarray) -> tuple[float, float, float]:
    """The sinusoid that best fits the legs' fore-aft separation: (frequency Hz, amplitude m, share
    of the variance explained)."""
    best = (math.nan, math.nan, -math.inf)
    spread = float(np.sum((separation - separation.mean()) ** 2))
    for frequency in CADENCES_HZ:
        phase = 2.0 * math.pi * frequency * times
        design = np.column_stack((np.sin(phase), np.cos(phase), np.ones(len(times))))
        coefficients = np.linalg.lstsq(design, separation, rcond=None)[0]
        explained = 1.0 - float(np.sum((design @ coefficients - separation) ** 2)) / spread
        if explained > best[2]:
            best = (float(frequency), float(np.hypot(*coefficients[:2])), explained)
    return best


def gait(logs: Sequence[Sequence[tuple[Scan, np.ndarray]]]) -> Gait:
    """The legs' spacing and swing along the walks of each log's labelled scans (in time order).

    A walk is a run of scans less than WALK_GAP_S apart; the walker's direction is the slope of their
    centre (the mean of the labelled legs); the legs are told apart by their side of it. Over a gait
    cycle the legs' fore-aft separation swings between +-2 x each leg's swing, so a sinusoid fitted to
    it gives the cadence and twice the swing.

    Raises:
        LogError: no walk is long enough and regular enough to fit.
    """
    spreads, swings, cadences, speeds = [], [], [], []
    for pairs in logs:
        stamps = np.array([scan.stamp for scan, _ in pairs])
        for walk in np.split(np.arange(len(pairs)), np.flatnonzero(np.diff(stamps) > WALK_GAP_S) + 1):
            times = stamps[walk]
            if times[-1] - times[0] < MIN_WALK_S:
                continue
            found = _walk(times, [pairs[k][1] for k in walk])
            spreads.extend(found.spread)
            if len(found.times) < 12 or found.times[-1] - found.times[0] < MIN_WALK_S:
                continue
            cadence, amplitude, explained = _swing(found.times, found.separation)
            if explained >= MIN_EXPLAINED:
                cadences.append(cadence)
                swings.append(amplitude / 2.0)
                speeds.append(float(np.median(found.speed)))
    if not cadences:
        raise LogError("no walk is long and regular enough to fit a gait")
    return Gait(len(cadences), float(np.median(spreads)), float(np.median(swings)), float(np.median(cadences)),
                float(np.median(speeds)))


def fit_legs(paths: Sequence[Path | str]) -> LegFit:
    """Measure labelled logs (scans with geometry_msgs/PoseArray leg labels) together; the gait is
    followed walk by walk within each log.

    Raises:
        LogError: a log has no labels, the logs' lidars differ, or no scan or walk can be measured.
    """
    logs = []
    for path in paths:
        with LogReader(path) as log:
            logs.append([(scan, label.points) for scan, label in labelled_scans(log)])
    pairs = [pair for log in logs for pair in log]
    return LegFit(sensor_fit([scan for scan, _ in pairs]), leg_shapes(pairs), gait(logs))
