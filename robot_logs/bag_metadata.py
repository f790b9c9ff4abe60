"""A ROS2 bag folder's `metadata.yaml`: its storage, files, ROS distribution and compression.

Every metadata version rosbags reads (1 to 9) is accepted; only the fields robot_logs needs are
taken, so the storage files themselves (not the metadata's copies of their counts) are the one
source of what a bag holds, and a folder reads like its files.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path, PurePath

from ruamel.yaml import YAML

from robot_logs.errors import LogError

METADATA = "metadata.yaml"


@dataclass(frozen=True)
class BagMetadata:
    """What `metadata.yaml` says about a bag folder.

    Attributes:
        storage: 'sqlite3' or 'mcap'.
        files: the storage files, in recording order.
        distro: the ROS distribution that recorded it ('humble'), None where not recorded (before version 8).
        compression: '' (none), 'message' or 'file' (zstd).
    """

    storage: str
    files: list[Path]
    distro: str | None
    compression: str


def read_bag_metadata(folder: Path) -> BagMetadata:
    """The metadata of a ROS2 bag folder.

    Raises:
        LogError: metadata.yaml is not YAML, lacks a field every version has, or names
            storage files that are missing.
    """
    path = folder / METADATA
    try:
        info = YAML(typ="safe").load(path.read_text())["rosbag2_bagfile_information"]
        storage = str(info["storage_identifier"])
        names = [PurePath(str(name)).name for name in info["relative_file_paths"]]
    except (KeyError, TypeError) as exc:
        raise LogError(f"{path}: missing field {exc} (expected rosbag2_bagfile_information with storage_identifier and relative_file_paths)") from None
    except Exception as exc:  # ruamel's parser errors
        raise LogError(f"{path} is not valid YAML ({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})") from None
    files = [folder / name for name in names]
    missing = [f.name for f in files if not f.is_file()]
    if missing:
        raise LogError(f"{path} names storage files that are missing: {', '.join(missing)}")
    compression = str(info.get("compression_mode") or "").lower()
    distro = info.get("ros_distro")
    return BagMetadata(storage, files, str(distro) if distro else None, "" if compression == "none" else compression)
