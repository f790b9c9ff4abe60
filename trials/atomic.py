"""All-or-nothing file writes: stage every file under a temporary name, then rename."""

from __future__ import annotations

import os
import secrets
from collections.abc import Collection
from pathlib import Path

#: The mode of a file only its owner may read (a blinded study's sealed files).
PRIVATE_FILE = 0o600


def write_files(files: dict[Path, bytes], private: Collection[Path] = ()) -> None:
    """Write several files so that none is left half-written; those in `private` are created 0600.

    Each file is first written and flushed to a temporary name in its own folder; only when
    all are staged are they renamed over their targets, so a failure or an interrupt before
    that point leaves every existing file as it was.
    """
    staged: list[tuple[Path, Path]] = []
    try:
        for target, content in files.items():
            target.parent.mkdir(parents=True, exist_ok=True)
            temporary = target.with_name(f".{target.name}.{secrets.token_hex(4)}.tmp")
            staged.append((temporary, target))
            mode = PRIVATE_FILE if target in private else 0o666  # 0o666: as open() does, less the umask
            with os.fdopen(os.open(temporary, os.O_CREAT | os.O_EXCL | os.O_WRONLY, mode), "wb") as handle:
                handle.write(content)
                handle.flush()
                os.fsync(handle.fileno())
        for temporary, target in staged:
            os.replace(temporary, target)
    finally:
        for temporary, _ in staged:
            temporary.unlink(missing_ok=True)


def write_text(path: Path, text: str) -> None:
    """Write one UTF-8 text file atomically."""
    write_files({path: text.encode("utf-8")})
