"""Writing tracked scans to a Foxglove MCAP: the scan, its detections and the tracks."""

from __future__ import annotations

from robot_logs.foxglove_log import (
    FoxgloveWriter,
    cylinder,
    entity,
    frame_transform,
    laser_scan,
    scene_update,
    sphere,
    text,
)
from robot_logs.pipeline import ScanResult
from robot_logs.records import Scan

#: Colours of tracks, cycled by id so each person keeps one colour.
PALETTE = (
    (0.90, 0.30, 0.24, 0.8), (0.20, 0.60, 0.86, 0.8), (0.18, 0.80, 0.44, 0.8), (0.95, 0.77, 0.06, 0.8),
    (0.61, 0.35, 0.71, 0.8), (0.90, 0.49, 0.13, 0.8), (0.10, 0.74, 0.61, 0.8), (0.91, 0.12, 0.55, 0.8),
)
LEG = (0.2, 0.9, 0.2, 0.9)
PERSON = (1.0, 1.0, 1.0, 0.6)


def write_tracked_scan(writer: FoxgloveWriter, scan: Scan, result: ScanResult) -> None:
    """Log one scan on /scan, its detections on /detections and the tracks on /tracks.

    When the output frame is not the scan's own, a /tf FrameTransform places the scan in it.
    """
    stamp = scan.stamp_ns
    if result.frame != scan.frame_id:
        writer.write("/tf", "foxglove.FrameTransform", frame_transform(stamp, result.frame, scan.frame_id, result.sensor_pose), stamp)
    writer.write("/scan", "foxglove.LaserScan", laser_scan(scan), stamp)
    found = result.detections
    detections = entity(
        stamp, result.frame, "detections",
        spheres=[sphere(x, y, 0.12, LEG, z=0.3) for x, y in found.legs]
        + [sphere(x, y, 0.3, PERSON, z=0.9) for x, y in found.people],
    )
    writer.write("/detections", "foxglove.SceneUpdate", scene_update([detections], delete_all_before_ns=stamp), stamp)
    tracks = [
        entity(
            stamp, result.frame, f"track {t.track_id}",
            cylinders=[cylinder(t.x, t.y, 0.25, 1.7, PALETTE[t.track_id % len(PALETTE)])],
            texts=[text(t.x, t.y, str(t.track_id))],
        )
        for t in result.tracks
    ]
    writer.write("/tracks", "foxglove.SceneUpdate", scene_update(tracks, delete_all_before_ns=stamp), stamp)
