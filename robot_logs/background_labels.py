"""Legs labelled without a person labelling them: background subtraction in a log recorded by
a robot standing still.

While the robot stands, each beam sees the same room most of the time; what stands clearly in
front of that background is someone passing. A leg-sized segment whose points lie in front of
the background is taken for a leg, one that lies on it for the room, and one partly in front for
neither (it is left out). This gives legs seen by another laser in another scene, for training
and for a held-out figure, at the cost of a few passing objects taken for legs.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from robot_logs.detection import Segments
from robot_logs.errors import LogError
from robot_logs.records import Scan

#: Share of the log's scans in which a beam reaches at least as far as its background.
BACKGROUND_SHARE = 0.9

#: At most this many scans, evenly spaced, make the background (a long log needs no more).
BACKGROUND_SCANS = 2000

#: A point this much nearer than its beam's background (m) is in front of it.
MARGIN = 0.3

#: Share of a segment's points in front of the background that makes it a passer-by.
IN_FRONT_SHARE = 0.8

#: Share of a scan's beams on their background (within MARGIN, or both seeing nothing) that a laser
#: standing still reaches in the median scan (the standing sample log: 0.82; a robot driving: 0.11).
STILL_SHARE = 0.5


@dataclass(frozen=True)
class Background:
    """Each beam's background range (m; +inf where it mostly sees nothing) of one standing laser."""

    angle_min: float
    angle_increment: float
    ranges: np.ndarray

    @classmethod
    def of(cls, scans: Sequence[Scan], where: str) -> Background:
        """The range each beam reaches in all but the nearest (1 - BACKGROUND_SHARE) of the scans
        (of at most BACKGROUND_SCANS of them, evenly spaced, in a longer log).

        Raises:
            LogError: no scans; a scan's beams differ from the first's (not one laser); or the
                median scan has under STILL_SHARE of its beams on the background (not standing still).
        """
        if not scans:
            raise LogError(f"{where}: no scan to learn from")
        first = scans[0]
        for index, scan in enumerate(scans):
            if (len(scan.ranges), scan.angle_min, scan.angle_increment) != (
                    len(first.ranges), first.angle_min, first.angle_increment):
                raise LogError(f"{where}: scan {index} has {len(scan.ranges)} beams from {scan.angle_min:.4f} rad by "
                               f"{scan.angle_increment:.6f}, the first {len(first.ranges)} from {first.angle_min:.4f} by "
                               f"{first.angle_increment:.6f}; background labels need one laser standing still")
        sample = scans[:: -(-len(scans) // BACKGROUND_SCANS)]
        ranges = np.array([np.where(s.valid(), s.ranges, np.inf) for s in sample])
        rank = int(np.floor((1.0 - BACKGROUND_SHARE) * (len(sample) - 1)))
        background = cls(first.angle_min, first.angle_increment, np.partition(ranges, rank, axis=0)[rank])
        with np.errstate(invalid="ignore"):  # inf - inf: both see nothing, counted apart
            on = (np.abs(ranges - background.ranges) <= MARGIN) | (np.isinf(ranges) & np.isinf(background.ranges))
        still = float(np.median(on.mean(axis=1)))
        if still < STILL_SHARE:
            raise LogError(f"{where}: in the median scan only {still:.0%} of the beams see their background (a laser "
                           f"standing still sees at least {STILL_SHARE:.0%}); expected a robot standing still while "
                           "people pass")
        return background

    def in_front(self, points: np.ndarray) -> np.ndarray:
        """(M,) True for the (M, 2) sensor-frame points standing MARGIN or more before the
        background of the beam nearest their bearing (so a scan with fewer beams still fits)."""
        count = len(self.ranges)
        offset = np.mod(np.arctan2(points[:, 1], points[:, 0]) - self.angle_min, 2.0 * np.pi)
        beam = np.rint(offset / self.angle_increment).astype(int)
        if count * self.angle_increment >= 2.0 * np.pi - 1e-6:
            beam %= count  # a full circle: past the last beam comes the first
        else:
            # Bearings past either end belong to the nearer end (a point found beyond the field of view
            # by rounding); those nearer the last beam than the first wrapped to large offsets.
            past = beam >= count
            beam[past] = np.where(offset[past] - (count - 1) * self.angle_increment
                                  < 2.0 * np.pi - offset[past], count - 1, 0)
        return np.hypot(points[:, 0], points[:, 1]) < self.ranges[beam] - MARGIN


def background_labels(
    background: Background, segments: Segments, mask: np.ndarray, leg_width: tuple[float, float]
) -> tuple[np.ndarray, np.ndarray]:
    """(K,) leg and (K,) ignored masks of the K `mask`ed segments: a leg-wide segment with
    IN_FRONT_SHARE of its points in front of the background is a leg; any other segment with a
    point in front of it is ignored; the rest are the room."""
    share = np.add.reduceat(background.in_front(segments.points).astype(float), segments.starts) / segments.counts
    share, widths = share[mask], segments.widths[mask]
    leg = (share >= IN_FRONT_SHARE) & (widths >= leg_width[0]) & (widths < leg_width[1])
    return leg, ~leg & (share > 0.0)
