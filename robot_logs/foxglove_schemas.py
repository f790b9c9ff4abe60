"""JSON schemas of the Foxglove message types robot_logs writes.

Foxglove recognises a channel by its schema name ("foxglove.SceneUpdate", ...) and reads the
JSON schema for field types; these give the fields of Foxglove's published definitions that
robot_logs uses, with times as {"sec", "nsec"} objects titled "time" as Foxglove expects.
"""

from __future__ import annotations

from typing import Any

Schema = dict[str, Any]

NUMBER: Schema = {"type": "number"}
INTEGER: Schema = {"type": "integer"}
STRING: Schema = {"type": "string"}
BOOLEAN: Schema = {"type": "boolean"}
TIME: Schema = {
    "type": "object",
    "title": "time",
    "properties": {"sec": {"type": "integer", "minimum": 0}, "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999}},
}
DURATION: Schema = {
    "type": "object",
    "title": "duration",
    "properties": {"sec": INTEGER, "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999}},
}


def record(title: str, description: str, **properties: Schema) -> Schema:
    """An object schema with a Foxglove type name as its title."""
    return {"title": title, "description": description, "type": "object", "properties": properties}


def array(items: Schema) -> Schema:
    """A list of `items`."""
    return {"type": "array", "items": items}


VECTOR3 = record("foxglove.Vector3", "3-D vector", x=NUMBER, y=NUMBER, z=NUMBER)
POINT3 = record("foxglove.Point3", "3-D point", x=NUMBER, y=NUMBER, z=NUMBER)
QUATERNION = record("foxglove.Quaternion", "rotation", x=NUMBER, y=NUMBER, z=NUMBER, w=NUMBER)
POSE = record("foxglove.Pose", "position and orientation", position=VECTOR3, orientation=QUATERNION)
COLOR = record("foxglove.Color", "RGBA colour, 0-1", r=NUMBER, g=NUMBER, b=NUMBER, a=NUMBER)
KEY_VALUE = record("foxglove.KeyValuePair", "key and value", key=STRING, value=STRING)

ARROW = record(
    "foxglove.ArrowPrimitive", "arrow", pose=POSE, shaft_length=NUMBER, shaft_diameter=NUMBER,
    head_length=NUMBER, head_diameter=NUMBER, color=COLOR,
)
CUBE = record("foxglove.CubePrimitive", "box", pose=POSE, size=VECTOR3, color=COLOR)
SPHERE = record("foxglove.SpherePrimitive", "sphere or ellipsoid", pose=POSE, size=VECTOR3, color=COLOR)
CYLINDER = record(
    "foxglove.CylinderPrimitive", "cylinder or cone", pose=POSE, size=VECTOR3,
    bottom_scale=NUMBER, top_scale=NUMBER, color=COLOR,
)
LINE = record(
    "foxglove.LinePrimitive", "polyline; type 0 strip, 1 loop, 2 list", type=INTEGER, pose=POSE,
    thickness=NUMBER, scale_invariant=BOOLEAN, points=array(POINT3), color=COLOR,
    colors=array(COLOR), indices=array(INTEGER),
)
TEXT = record(
    "foxglove.TextPrimitive", "text label", pose=POSE, billboard=BOOLEAN, font_size=NUMBER,
    scale_invariant=BOOLEAN, color=COLOR, text=STRING,
)
SCENE_ENTITY = record(
    "foxglove.SceneEntity", "visual element of a 3-D scene", timestamp=TIME, frame_id=STRING, id=STRING,
    lifetime=DURATION, frame_locked=BOOLEAN, metadata=array(KEY_VALUE), arrows=array(ARROW),
    cubes=array(CUBE), spheres=array(SPHERE), cylinders=array(CYLINDER), lines=array(LINE), texts=array(TEXT),
)
SCENE_ENTITY_DELETION = record(
    "foxglove.SceneEntityDeletion", "removal of entities; type 0 matching id, 1 all",
    timestamp=TIME, type=INTEGER, id=STRING,
)

#: Schema name -> JSON schema, for every Foxglove type the run logs use.
FOXGLOVE_SCHEMAS: dict[str, Schema] = {
    "foxglove.SceneUpdate": record(
        "foxglove.SceneUpdate", "update of a 3-D scene",
        deletions=array(SCENE_ENTITY_DELETION), entities=array(SCENE_ENTITY),
    ),
    "foxglove.PoseInFrame": record("foxglove.PoseInFrame", "timestamped pose", timestamp=TIME, frame_id=STRING, pose=POSE),
    "foxglove.PosesInFrame": record(
        "foxglove.PosesInFrame", "timestamped poses", timestamp=TIME, frame_id=STRING, poses=array(POSE)
    ),
    "foxglove.FrameTransform": record(
        "foxglove.FrameTransform", "transform between frames", timestamp=TIME, parent_frame_id=STRING,
        child_frame_id=STRING, translation=VECTOR3, rotation=QUATERNION,
    ),
    "foxglove.LaserScan": record(
        "foxglove.LaserScan", "planar lidar scan", timestamp=TIME, frame_id=STRING, pose=POSE,
        start_angle=NUMBER, end_angle=NUMBER, ranges=array(NUMBER), intensities=array(NUMBER),
    ),
    "foxglove.Log": record(
        "foxglove.Log", "log line; level 1 debug, 2 info, 3 warning, 4 error, 5 fatal", timestamp=TIME,
        level=INTEGER, message=STRING, name=STRING, file=STRING, line=INTEGER,
    ),
}


def open_schema(name: str) -> Schema:
    """Schema of a custom JSON record: any object, titled with its name."""
    return {"title": name, "type": "object"}
