"""Blinded allocation: opaque arm labels, a sealed key, and a SHA-256 commitment to the whole key.

The public files name only arm labels. The key (arm label -> real level) is drawn from its own
secret seed, never from the public study seed. The commitment is the SHA-256 of the key file's
canonical bytes (every field: factor, arms, salt, allocation seed), so any change to the key is
detected; the random salt keeps the few possible keys from being tried against it. design.json
holds the commitment, but whoever can rewrite the key can rewrite design.json too, so the
researcher records it elsewhere as well (`trials design` prints it) and unblinding checks the key
against that record when given.

Studies made by earlier releases hold the older commitment, sha256(salt + "\\n" + JSON of factor and
arms), which leaves the allocation seed out; it is still checked as it was.
"""

from __future__ import annotations

import hashlib
import json
import secrets
import string
from dataclasses import dataclass

import numpy as np

from designs.errors import DesignError

#: design.json's name of each commitment format: the whole key, and the older one of factor and arms.
WHOLE_KEY = "sha256 of the sealed key's canonical JSON (every field, sorted keys, no spaces, UTF-8)"
FACTOR_AND_ARMS = "sha256(salt + newline + key json)"


def canonical_bytes(record: dict[str, object]) -> bytes:
    """A JSON record as one byte string: keys sorted, no spaces, UTF-8."""
    return json.dumps(record, sort_keys=True, separators=(",", ":"), ensure_ascii=False).encode()


@dataclass(frozen=True)
class SealedAllocation:
    """The secret key of a blinded factor and what it takes to check it."""

    factor: str
    arms: dict[str, str]
    salt: str
    seed: int

    def commitment(self) -> str:
        """The commitment to the whole key (`WHOLE_KEY`), over exactly what `to_dict` writes."""
        return hashlib.sha256(canonical_bytes(self.to_dict())).hexdigest()

    def factor_and_arms_commitment(self) -> str:
        """The older commitment (`FACTOR_AND_ARMS`): the salt, the factor and the arms, not the seed."""
        key = json.dumps({"factor": self.factor, "arms": self.arms}, sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(f"{self.salt}\n{key}".encode()).hexdigest()

    def to_dict(self) -> dict[str, object]:
        return {"factor": self.factor, "arms": self.arms, "salt": self.salt, "allocation_seed": self.seed}

    @classmethod
    def from_dict(cls, data: dict[str, object], source: str) -> SealedAllocation:
        try:
            arms = data["arms"]
            if not isinstance(arms, dict) or not all(isinstance(v, str) for v in arms.values()):
                raise TypeError("arms")
            return cls(str(data["factor"]), dict(arms), str(data["salt"]), int(data["allocation_seed"]))  # type: ignore[arg-type]
        except (KeyError, TypeError, ValueError) as exc:
            raise DesignError(f"{source}: broken sealed key (field {exc.args[0]!r} missing or malformed)") from None


def arm_labels(count: int) -> tuple[str, ...]:
    """Opaque labels A, B, C, ... for `count` arms."""
    if count > len(string.ascii_uppercase):
        raise DesignError(f"a blind factor can have at most {len(string.ascii_uppercase)} levels, got {count}")
    return tuple(string.ascii_uppercase[:count])


def seal(factor: str, levels: tuple[str, ...], seed: int | None = None) -> SealedAllocation:
    """Allocate the levels to arm labels at random; `seed` defaults to a fresh secret one."""
    seed = secrets.randbits(63) if seed is None else seed
    order = np.random.default_rng(seed).permutation(len(levels))
    arms = dict(zip(arm_labels(len(levels)), (levels[i] for i in order)))
    return SealedAllocation(factor, arms, secrets.token_hex(16), seed)


def verify(key: dict[str, object], sealed: SealedAllocation, algorithm: str, digest: str, recorded: str | None = None) -> str:
    """Check a key file's content (`key`, read as `sealed`) against design.json's commitment
    (`algorithm`, `digest`) and, when given, the commitment the researcher `recorded` elsewhere.

    Returns which check was made, in a sentence for the report.

    Raises:
        DesignError: an unknown commitment format, a malformed recorded value, or a key that
            does not match either commitment.
    """
    if algorithm == WHOLE_KEY:
        actual = hashlib.sha256(canonical_bytes(key)).hexdigest()
        covers = "the whole key (arms, salt, allocation seed)"
    elif algorithm == FACTOR_AND_ARMS:
        actual = sealed.factor_and_arms_commitment()
        covers = "the factor, arms and salt only (the older format: the allocation seed is not covered)"
    else:
        raise DesignError(f"design.json: unknown commitment algorithm {algorithm!r}; expected {WHOLE_KEY!r} or {FACTOR_AND_ARMS!r}")
    if not secrets.compare_digest(actual, str(digest)):
        raise DesignError("the sealed key does not match the commitment in design.json: it was changed after the design was made")
    if recorded is None:
        return (f"The sealed key matched design.json's commitment (sha256 {actual[:16]}...), which covers {covers}; no "
                "independently recorded commitment was given (--commitment), so a key and design.json changed together would pass.")
    value = recorded.strip().lower()
    if len(value) != 64 or any(c not in string.hexdigits for c in value):
        raise DesignError(f"--commitment: expected the 64 hex digits `trials design` printed, got {recorded!r}")
    if not secrets.compare_digest(actual, value):
        raise DesignError(f"the sealed key does not match the commitment you recorded ({value[:16]}...): the key or design.json "
                          "was changed after the design was made, the study's preregistration.md was removed, or the recorded "
                          "value belongs to another study")
    return (f"The sealed key matched the commitment recorded outside the study (--commitment {actual[:16]}...) and "
            f"design.json's, which cover {covers}.")
