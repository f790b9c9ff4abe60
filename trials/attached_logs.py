"""logs/, the robot logs uploaded through `trials serve`: one file per run, `logs/<code>.bag` (ROS1) or
`logs/<code>.mcap`, checked by its first bytes and written atomically. A ROS2 bag is a folder, so it is
attached by its path instead."""

from __future__ import annotations

from pathlib import Path

from trials.atomic import write_files
from trials.errors import StudyError
from trials.study import LOGS, StudyFolder

#: What each accepted suffix's file starts with: ROS1 bag version 2.0, MCAP's magic.
MAGIC = {".bag": b"#ROSBAG V2.0\n", ".mcap": b"\x89MCAP0\r\n"}
#: The largest upload: a field run of a few minutes with laser scans is tens of megabytes.
MAX_UPLOAD_BYTES = 512 * 1024 * 1024


def check_upload(name: str, head: bytes) -> str:
    """The suffix of an uploaded log named `name` whose content starts with `head`; StudyError unless it is
    a ROS1 bag or an MCAP file by both its suffix and its first bytes."""
    suffix = Path(name).suffix.lower()
    if suffix not in MAGIC:
        raise StudyError(f"{name or 'the upload'}: a robot log must be a ROS1 .bag or an .mcap file (a ROS2 bag folder: give its path)")
    if not head.startswith(MAGIC[suffix]):
        raise StudyError(f"{name}: not a {'ROS1 bag' if suffix == '.bag' else 'MCAP file'} (its first bytes are not {MAGIC[suffix]!r})")
    return suffix


def save_upload(folder: StudyFolder, code: str, name: str, content: bytes) -> Path:
    """Write an uploaded log of run `code` to logs/<code><suffix> (replacing an earlier upload of that run); returns its path."""
    suffix = check_upload(name, content[:16])
    if len(content) > MAX_UPLOAD_BYTES:
        raise StudyError(f"{name}: {len(content)} bytes, more than the {MAX_UPLOAD_BYTES // 2**20} MiB an upload may have")
    path = folder.path(LOGS) / f"{code}{suffix}"
    write_files({path: content})
    return path
