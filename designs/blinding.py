"""Blinded allocation: opaque arm labels, a sealed key, and a salted SHA-256 commitment to it.

The public files name only arm labels. The key (arm label -> real level) is drawn from its own
secret seed, never from the public study seed, and is committed to by
sha256(salt + "\\n" + canonical JSON of the key), so a changed key is detected on unblinding.
"""

from __future__ import annotations

import hashlib
import json
import secrets
import string
from dataclasses import dataclass

import numpy as np

from designs.errors import DesignError


@dataclass(frozen=True)
class SealedAllocation:
    """The secret key of a blinded factor and what it takes to check it."""

    factor: str
    arms: dict[str, str]
    salt: str
    seed: int

    def commitment(self) -> str:
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


def verify(sealed: SealedAllocation, commitment: str) -> None:
    """Raise DesignError unless the sealed key matches the public commitment."""
    if not secrets.compare_digest(sealed.commitment(), commitment):
        raise DesignError("the sealed key does not match the commitment in design.json: it was changed after the design was made")
