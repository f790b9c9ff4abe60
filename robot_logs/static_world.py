"""Static-world rejection: an occupancy grid of the surroundings, accumulated scan by scan in
the output frame (the odometry frame when tracking a moving robot's log).

Every scan adds a hit to the cells its points fall in, a free count to the known cells its
beams pass through, and a hidden count to the known cells just behind a beam's end; a cell hit
in most of the scans that saw it or hid it close behind something, for long enough, is part of
the static world (furniture legs, wall ends, pillars), and a leg there is not a person;
optionally a cell hit a few times and never seen free is static sooner. Points near a track the
detector is sure of (`PersonTracker` decides which) are not added, so a person standing still
never turns into furniture; a walking leg's cells are soon seen free or hidden again.

What is known to be static beforehand (a ROS map, `robot_logs.occupancy_map`) joins the grid as
`StaticWorld.known_static`: a leg on an occupied map cell is static from the first scan.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from robot_logs.frames import Pose2D
from robot_logs.records import Scan

#: Output-frame positions (N, 2) -> (N,) True where they are known to be static beforehand, at the current scan.
KnownStatic = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class StaticWorldConfig:
    """Grid size and the rule for a static cell.

    Attributes:
        cell: cell side (m).
        half_size: the grid covers this far from the frame's origin each way (m).
        min_hits: scans that must have hit a cell before it can be static.
        min_duration: seconds from a cell's first hit before it can be static (longer than a
            walking leg stands on the ground).
        occupied_share: share of the scans that saw a cell, or hid it within `hidden_gap`, which
            must have hit it.
        hidden_gap: a cell whose beam ends less than this far in front of it (m) counts as seen
            without a hit. A person walking along the beams, towards the lidar, hides the cells
            their legs just left, which would otherwise collect hits alone and turn static; a
            cell seen past something farther ahead (furniture behind furniture) is not counted.
        keep_out: points this close to a protected track are not added (m).
        protect_confidence: tracks whose mean detection confidence reaches this are protected.
        protect_walkers: confirmed tracks that walk are protected too (`Track.walking`), so a
            person walking at a steady distance ahead of a moving robot never turns static.
        never_free_hits, never_free_duration: a cell hit in this many scans over at least this
            many seconds and never seen free is static at once, without the wait and share above:
            a wall or post, whose cells no beam ever passes (a walker's cells are seen free as soon
            as the leg moves on). Off by default: a person standing still is never seen free either.
    """

    cell: float = 0.1
    half_size: float = 40.0
    min_hits: int = 3
    min_duration: float = 1.5
    occupied_share: float = 0.8
    hidden_gap: float = 1.0
    keep_out: float = 0.4
    protect_confidence: float = 0.7
    protect_walkers: bool = True
    never_free_hits: int = 1_000_000
    never_free_duration: float = 0.5


class StaticWorld:
    """Hit, free and hidden counts per cell; `update` once per scan, `is_static` for positions."""

    def __init__(self, config: StaticWorldConfig = StaticWorldConfig()) -> None:
        self.config = config
        self.side = int(np.ceil(2.0 * config.half_size / config.cell))
        self.hits = np.zeros(self.side * self.side, dtype=np.int32)
        self.free = np.zeros(self.side * self.side, dtype=np.int32)
        self.hidden = np.zeros(self.side * self.side, dtype=np.int32)
        self.first_hit = np.full(self.side * self.side, np.inf)
        self.time = -np.inf
        self._known = np.zeros(0, dtype=np.int64)
        self._is_known = np.zeros(self.side * self.side, dtype=bool)
        self._marked = np.zeros(self.side * self.side, dtype=np.int64)
        self._scans = 0
        #: Set before each scan by whoever places a map in the grid's frame (`robot_logs.log_tracking`).
        self.known_static: KnownStatic | None = None

    def cells(self, points: np.ndarray) -> np.ndarray:
        """(N,) flat cell index of each point; -1 outside the grid."""
        index = np.floor((np.asarray(points).reshape(-1, 2) + self.config.half_size) / self.config.cell).astype(np.int64)
        inside = ((index >= 0) & (index < self.side)).all(axis=1)
        return np.where(inside, index[:, 0] * self.side + index[:, 1], -1)

    def centres(self, cells: np.ndarray) -> np.ndarray:
        """(N, 2) centres of flat cell indices."""
        return (np.column_stack(np.divmod(cells, self.side)) + 0.5) * self.config.cell - self.config.half_size

    def update(self, scan: Scan, points: np.ndarray, sensor_pose: Pose2D, people: np.ndarray) -> None:
        """Add one scan: `points` are its valid points in the output frame, `people` the
        protected tracks' positions there (their surroundings are left out)."""
        points = np.asarray(points).reshape(-1, 2)
        if len(people) and len(points):
            near = np.hypot(*(points[:, None, :] - np.asarray(people)[None, :, :]).transpose(2, 0, 1)).min(axis=1)
            points = points[near > self.config.keep_out]
        cells = self.cells(points)
        hit = np.unique(cells[cells >= 0])
        self._scans += 1
        self._free_and_hidden(scan, sensor_pose, hit)
        self.hits[hit] += 1
        self.time = scan.stamp
        self.first_hit[hit] = np.minimum(self.first_hit[hit], scan.stamp)
        new = hit[~self._is_known[hit]]
        self._is_known[new] = True
        self._known = np.concatenate((self._known, new))

    def _free_and_hidden(self, scan: Scan, sensor_pose: Pose2D, hit: np.ndarray) -> None:
        # Cells beside a hit one are not counted free: a beam grazing a wall passes the centre of
        # a wall cell that this scan's points happened to skip.
        offsets = (np.arange(-1, 2)[:, None] * self.side + np.arange(-1, 2)[None, :]).ravel()
        beside = np.clip(hit[:, None] + offsets[None, :], 0, len(self.hits) - 1)
        self._marked[beside] = self._scans
        known = self._known[self._marked[self._known] != self._scans]
        if len(known) == 0:
            return
        local = sensor_pose.inverse().apply(self.centres(known))
        distance = np.hypot(local[:, 0], local[:, 1])
        beam = np.round((np.arctan2(local[:, 1], local[:, 0]) - scan.angle_min) / scan.angle_increment).astype(np.int64)
        seen = (beam >= 0) & (beam < len(scan.ranges))
        ranges = np.where(scan.valid(), scan.ranges, np.where(np.isposinf(scan.ranges), np.inf, np.nan))
        beyond = np.full(len(known), np.nan)
        beyond[seen] = ranges[beam[seen]]
        margin = 2.0 * self.config.cell
        with np.errstate(invalid="ignore"):
            passed = seen & (beyond > distance + margin)
            hidden = seen & (beyond < distance - margin) & (beyond > distance - self.config.hidden_gap)
        self.free[known[passed]] += 1
        self.hidden[known[hidden]] += 1

    def static_points(self, centre: np.ndarray, radius: float) -> np.ndarray:
        """(M, 2) the centres of the static cells within `radius` of `centre`: the walls and furniture seen so far."""
        known = self._known
        if not len(known):
            return np.zeros((0, 2))
        points = self.centres(known)
        near = np.hypot(*(points - np.asarray(centre, dtype=float)[:2]).T) <= radius
        points = points[near]
        return points[self.is_static(points)] if len(points) else points

    def is_static(self, positions: np.ndarray) -> np.ndarray:
        """(N,) True where a position's cell is part of the static world, or `known_static` says it is static."""
        cells = self.cells(positions)
        inside = cells >= 0
        cells = np.maximum(cells, 0)
        hits, free, hidden = self.hits[cells], self.free[cells], self.hidden[cells]
        age = self.time - self.first_hit[cells]
        config = self.config
        settled = (age >= config.min_duration) & (hits >= config.min_hits) & (hits >= config.occupied_share * (hits + free + hidden))
        solid = (free == 0) & (hits >= config.never_free_hits) & (age >= config.never_free_duration)
        static = inside & (settled | solid)
        return static if self.known_static is None else static | self.known_static(positions)
