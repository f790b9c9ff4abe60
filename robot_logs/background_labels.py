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


@dataclass(frozen=True)
class Background:
    """Each beam's background range (m; +inf where it mostly sees nothing) of one standing laser."""

    angle_min: float
    angle_increment: float
    ranges: np.ndarray

    @classmethod
    def of(cls, scans: Sequence[Scan], where: str) -> Background:
        """The range each beam reaches in all but the nearest (1 - BACKGROUND_SHARE) of the scans
        (of BACKGROUND_SCANS of them, evenly spaced, in a longer log).

        Raises:
            LogError: the scans differ in their beams (not one laser standing still).
        """
        first = scans[0]
        if any(len(s.ranges) != len(first.ranges) or s.angle_min != first.angle_min
               or s.angle_increment != first.angle_increment for s in scans):
            raise LogError(f"{where}: the scans' beams differ; background labels need one laser standing still")
        sample = scans[:: max(1, len(scans) // BACKGROUND_SCANS)]
        ranges = np.array([np.where(s.valid(), s.ranges, np.inf) for s in sample])
        rank = int(np.floor((1.0 - BACKGROUND_SHARE) * (len(sample) - 1)))
        background = np.partition(ranges, rank, axis=0)[rank]
        return cls(first.angle_min, first.angle_increment, background)

    def in_front(self, points: np.ndarray) -> np.ndarray:
        """(M,) True for the (M, 2) sensor-frame points standing MARGIN or more before the
        background of the beam nearest their bearing (so a scan with fewer beams still fits)."""
        beam = np.rint((np.arctan2(points[:, 1], points[:, 0]) - self.angle_min) / self.angle_increment).astype(int)
        beam = np.clip(beam, 0, len(self.ranges) - 1)
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
