"""Every seed of a power study, derived from its one power seed, and kept below 2^53 so that a
spreadsheet or a JSON reader holding numbers as doubles keeps them exact."""

from __future__ import annotations

import hashlib
import secrets

#: Seeds stay below 2^53: exact in doubles (spreadsheets, JavaScript).
SEED_BITS = 53


def fresh_seed() -> int:
    """A power seed drawn when the user gives none (and recorded in power.json)."""
    return secrets.randbits(SEED_BITS)


def derived(power_seed: int, *parts: object) -> int:
    """The seed of one part of the study (a campaign, a simulation, a plan's search, a run) from the power seed."""
    text = ":".join(["navtrials-power", str(power_seed), *map(str, parts)])
    return int.from_bytes(hashlib.sha256(text.encode()).digest()[:8], "big") >> (64 - SEED_BITS)
