"""Geometric features of scan segments, for the learned leg detector.

One row per segment, computed for all segments of a scan at once (no Python loop over
segments): the kind of set Arras et al. (ICRA 2007) and leg_tracker use. A leg seen by a
planar lidar is a short arc of a circle about 5-8 cm in radius; furniture legs are similar but
steadier and rounder, wall pieces are straight, and noise is short and irregular.

No feature counts beams: a laser of another angular resolution sees a leg with more or fewer
points, so the surroundings are measured as lengths of surface seen, not as points.
"""

from __future__ import annotations

import numpy as np

#: The segment's own shape, the first columns.
SHAPE_NAMES = (
    "width",
    "distance",
    "spread",
    "linearity",
    "circularity",
    "radius",
    "boundary_length",
    "boundary_regularity",
    "mean_curvature",
    "mean_angular_difference",
    "sagitta",
)

#: What surrounds the segment in its scan, the last columns.
CONTEXT_NAMES = (
    "neighbour_distance",
    "foreground",
    "neighbour_width",
    "clearance",
    "surface_near",
    "surface_around",
    "candidates_around",
)

#: Feature names, in column order.
FEATURE_NAMES = SHAPE_NAMES + CONTEXT_NAMES

#: Radii (m) within which `surface_near` and `surface_around` measure other segments' surface.
CLUTTER_RADII = (0.5, 1.0)


#: Cap of the context features (m): no neighbour reads as this far.
FAR = 3.0

#: How far (m) in front of what its neighbouring beams hit a segment stands free: `foreground`
#: reads no more, as what lies farther behind tells the room's size and the laser's range, not
#: what the segment is.
STANDS_FREE = 1.0

#: Largest fitted circle radius reported (m): a nearly straight segment fits a huge circle.
MAX_RADIUS = 5.0


def _sums(labels: np.ndarray, values: np.ndarray, count: int) -> np.ndarray:
    return np.bincount(labels, weights=values, minlength=count)


def segment_features(
    points: np.ndarray, starts: np.ndarray, beam_angle: float, select: np.ndarray | None = None,
    open_beams: np.ndarray | None = None,
) -> np.ndarray:
    """(K, len(FEATURE_NAMES)) features of K segments (or of the `select`ed ones).

    Args:
        points: (M, 2) scan points in beam order, in the sensor frame (m).
        starts: (K,) index of each segment's first point; segment k ends where k + 1 starts.
        beam_angle: the angle between neighbouring beams (rad).
        select: (K,) True for the segments wanted (default: all); the context features still
            look at every segment.
        open_beams: (M, 2) True where the beam just before or after a point returned nothing
            (`detection.open_beams`; default: every neighbouring beam returned a point).

    The columns: end-to-end width; centroid distance from the sensor; root mean
    square distance of the points from their centroid; root mean square residual of the best
    line (linearity) and of the best circle (circularity), and that circle's radius; summed and
    spread of the point-to-point steps (boundary length and regularity); mean curvature of
    consecutive point triples; mean turning angle between consecutive steps; and how far the
    middle of the segment bulges from its chord (sagitta). Then its context: the distance to
    the nearest other segment's centroid (a leg's partner is near) and that segment's width;
    how far in front of its neighbouring beams the segment stands, on the nearer side
    (foreground, at most STANDS_FREE; a beam that saw nothing within range counts as far behind,
    whatever that range, and beyond the first or last beam as 0); the distance from its centroid
    to the nearest point of any other segment (clearance: people walk in the open, furniture legs
    stand by tables and walls) and the length of other segments' surface within CLUTTER_RADII of
    it (each point standing for the arc its beam spans at its range); how many other wanted
    segments lie within the larger radius (a person's other leg, or the three other legs of a
    chair). Distances are capped at FAR.
    """
    ends = np.append(starts[1:], len(points))
    wanted = np.ones(len(starts), dtype=bool) if select is None else np.asarray(select, dtype=bool)
    if not wanted.any():
        return np.zeros((0, len(FEATURE_NAMES)))
    lengths = ends[wanted] - starts[wanted]
    first = np.cumsum(lengths) - lengths
    taken = np.repeat(starts[wanted] - first, lengths) + np.arange(lengths.sum())
    shape = _shape_features(points[taken], first)
    if open_beams is None:
        open_beams = np.zeros((len(points), 2), dtype=bool)
    return np.column_stack((shape, _context_features(points, starts, ends, wanted, beam_angle, open_beams)))


def _context_features(
    points: np.ndarray, starts: np.ndarray, ends: np.ndarray, wanted: np.ndarray, beam_angle: float,
    open_beams: np.ndarray,
) -> np.ndarray:
    """The CONTEXT_NAMES columns: what surrounds each wanted segment in its scan."""
    chosen = np.flatnonzero(wanted)
    lengths = ends - starts
    centroids = np.add.reduceat(points, starts, axis=0) / lengths[:, None]
    widths = np.hypot(*(points[ends - 1] - points[starts]).T)
    apart = np.hypot(*(centroids[chosen][:, None, :] - centroids[None, :, :]).transpose(2, 0, 1))
    apart[np.arange(len(chosen)), chosen] = np.inf
    nearest = apart.argmin(axis=1)
    alone = np.isinf(apart[np.arange(len(chosen)), nearest])
    neighbour = np.where(alone, FAR, np.minimum(apart[np.arange(len(chosen)), nearest], FAR))
    neighbour_width = np.where(alone, 0.0, widths[nearest])

    owner = np.repeat(np.arange(len(starts)), lengths)
    to_points = np.hypot(*(centroids[chosen][:, None, :] - points[None, :, :]).transpose(2, 0, 1))
    to_points[owner[None, :] == chosen[:, None]] = np.inf
    clearance = np.minimum(to_points.min(axis=1, initial=np.inf), FAR)
    ranges = np.hypot(points[:, 0], points[:, 1])
    footprint = ranges * beam_angle
    surface = [(to_points < radius) @ footprint for radius in CLUTTER_RADII]
    candidates_around = (apart[:, chosen] < CLUTTER_RADII[1]).sum(axis=1)

    total = len(points)
    head, tail = starts[chosen], ends[chosen]
    previous, following = np.maximum(head - 1, 0), np.minimum(tail, total - 1)
    # Beyond the first and last beam nothing was looked at: no step there, rather than the open
    # space that would make a segment cut by the field of view look like a lone leg.
    before = np.where(head > 0, ranges[previous] - ranges[head], 0.0)
    after = np.where(tail < total, ranges[following] - ranges[tail - 1], 0.0)
    # Next to a beam that saw nothing the segment stands before open space, not before whatever
    # the next beam with a return hit: the laser's range and how it writes a lost beam must not matter.
    before = np.where(open_beams[head, 0], STANDS_FREE, before)
    after = np.where(open_beams[tail - 1, 1], STANDS_FREE, after)
    foreground = np.clip(np.minimum(before, after), -FAR, STANDS_FREE)

    return np.column_stack((neighbour, foreground, neighbour_width, clearance, *surface, candidates_around))


def _shape_features(points: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """The SHAPE_NAMES columns of consecutive segments."""
    count = len(starts)
    total = len(points)
    ends = np.append(starts[1:], total)
    n = (ends - starts).astype(float)
    labels = np.repeat(np.arange(count), ends - starts)
    x, y = points[:, 0], points[:, 1]
    centroid = np.column_stack((_sums(labels, x, count), _sums(labels, y, count))) / n[:, None]
    local = points - centroid[labels]
    u, v = local[:, 0], local[:, 1]
    sxx, syy, sxy = (_sums(labels, w, count) / n for w in (u * u, v * v, u * v))
    spread = np.sqrt(sxx + syy)
    # Smallest eigenvalue of the 2x2 covariance: the mean squared distance from the best line.
    half_gap = np.sqrt(((sxx - syy) / 2.0) ** 2 + sxy**2)
    linearity = np.sqrt(np.maximum((sxx + syy) / 2.0 - half_gap, 0.0))

    # Algebraic circle fit (Kasa) in centroid coordinates: u^2 + v^2 + a u + b v + c = 0.
    q = u * u + v * v
    m = np.empty((count, 3, 3))
    rhs = np.empty((count, 3))
    columns = (u, v, np.ones(total))
    for i, first in enumerate(columns):
        rhs[:, i] = -_sums(labels, first * q, count)
        for j in range(i, 3):
            m[:, i, j] = m[:, j, i] = _sums(labels, first * columns[j], count)
    solution = np.einsum("kij,kj->ki", np.linalg.pinv(m), rhs)
    centre = -solution[:, :2] / 2.0
    radius = np.sqrt(np.maximum((centre**2).sum(axis=1) - solution[:, 2], 0.0))
    radius = np.minimum(radius, MAX_RADIUS)
    off_circle = np.hypot(*(local - centre[labels]).T) - radius[labels]
    circularity = np.sqrt(_sums(labels, off_circle**2, count) / n)
    # Collinear points make the fit singular: they lie on a circle of unbounded radius.
    straight = linearity <= 1e-3 * spread
    radius[straight] = MAX_RADIUS
    circularity[straight] = linearity[straight]

    # Steps between consecutive points of the same segment.
    step = np.diff(points, axis=0)
    step_length = np.hypot(step[:, 0], step[:, 1])
    inside = labels[1:] == labels[:-1]
    step_labels = labels[1:][inside]
    steps = np.maximum(n - 1.0, 1.0)
    lengths = step_length[inside]
    boundary = _sums(step_labels, lengths, count)
    mean_step = boundary / steps
    regularity = np.sqrt(np.maximum(_sums(step_labels, lengths**2, count) / steps - mean_step**2, 0.0))

    # Triples of consecutive points of the same segment: curvature 4 * area / (a b c) and the turn.
    first, second = step[:-1], step[1:]
    triple = inside[:-1] & inside[1:]
    triple_labels = labels[2:][triple]
    a, b = step_length[:-1][triple], step_length[1:][triple]
    cross = (first[:, 0] * second[:, 1] - first[:, 1] * second[:, 0])[triple]
    dot = (first[:, 0] * second[:, 0] + first[:, 1] * second[:, 1])[triple]
    c = np.hypot(*(first[triple] + second[triple]).T)
    with np.errstate(divide="ignore", invalid="ignore"):
        curvature = np.where(a * b * c > 0.0, 2.0 * np.abs(cross) / (a * b * c), 0.0)
    turn = np.abs(np.arctan2(cross, dot))
    triples = np.maximum(n - 2.0, 1.0)
    mean_curvature = _sums(triple_labels, curvature, count) / triples
    mean_turn = _sums(triple_labels, turn, count) / triples

    first_point, last_point = points[starts], points[ends - 1]
    width = np.hypot(*(last_point - first_point).T)
    chord = last_point - first_point
    middle = points[(starts + ends - 1) // 2] - first_point
    with np.errstate(divide="ignore", invalid="ignore"):
        sagitta = np.where(width > 0.0, np.abs(chord[:, 0] * middle[:, 1] - chord[:, 1] * middle[:, 0]) / width, 0.0)
    distance = np.hypot(centroid[:, 0], centroid[:, 1])
    return np.column_stack(
        (width, distance, spread, linearity, circularity, radius, boundary, regularity, mean_curvature, mean_turn, sagitta)
    )
