"""What the blinding tests look for: a controller's name, in any file or in an MCAP's decompressed content."""

from __future__ import annotations

import json
import re
from pathlib import Path

from mcap.reader import make_reader

NAMES = re.compile(rb"navigan|lattice|sbpl", re.IGNORECASE)


def mcap_text(path: Path) -> bytes:
    """Everything an MCAP holds, decompressed: header, metadata, schemas, topics and every message."""
    parts = []
    with path.open("rb") as stream:
        reader = make_reader(stream)
        header = reader.get_header()
        parts += [header.library.encode(), header.profile.encode()]
        parts += [json.dumps(m.metadata).encode() + m.name.encode() for m in reader.iter_metadata()]
        summary = reader.get_summary()
        parts += [s.name.encode() + s.data for s in summary.schemas.values()]
        parts += [c.topic.encode() + json.dumps(c.metadata).encode() for c in summary.channels.values()]
        parts += [message.data for _, _, message in reader.iter_messages()]
    return b"\n".join(parts)
