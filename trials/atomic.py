"""All-or-nothing file writes: stage every file under a temporary name, then rename."""

from __future__ import annotations

import os
import secrets
from pathlib import Path


def write_files(files: dict[Path, bytes]) -> None:
    """Write several files so that none is left half-written.

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
            with temporary.open("xb") as handle:
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
