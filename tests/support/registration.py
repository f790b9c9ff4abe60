"""The digest an experimenter records outside a study when `trials design` prints it: the pre-registration's SHA-256."""

from __future__ import annotations

import hashlib
from pathlib import Path


def recorded_digest(study: Path) -> str:
    """The SHA-256 of the study's preregistration.md, as `trials design` printed it."""
    return hashlib.sha256((study / "preregistration.md").read_bytes()).hexdigest()
