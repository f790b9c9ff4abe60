"""The manipulation check of a live run: did the robot meet the people its plan row asked for?

Every tracked scan counts the people tracked within `people_radius` of the robot. The check takes the most people tracked
at once for at least `HOLD_S` seconds of the robot's clock (so one scan's false track or a moment's occlusion counts for
nothing), and when that many were first seen. The row's condition is met when that is at least `min_people_share` of its
Pedestrians (rounded up): a leg tracker loses people behind one another, so all of them at once is too strict a test,
while a row whose walkers never came, or came too few, fails it.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

#: Seconds a count must hold to count.
HOLD_S = 1.0


@dataclass(frozen=True)
class PeopleCheck:
    """A run's people against its row's: asked for, the most seen at once (held `HOLD_S`), when first (s into the run;
    None when nobody was), and the fewest that meet the condition."""

    asked: int
    seen: int
    seen_at_s: float | None
    needed: int

    @property
    def met(self) -> bool:
        return self.seen >= self.needed

    def describe(self) -> str:
        when = f" (from {self.seen_at_s:.1f} s)" if self.seen_at_s is not None else ""
        verdict = "met" if self.met else "not met"
        return f"condition {verdict}: at most {self.seen} tracked at once{when}, the row asks {self.asked} (at least {self.needed})"


class PeopleCounter:
    """Counts of people tracked near the robot, scan by scan, and the most held for `HOLD_S`."""

    def __init__(self) -> None:
        self._window: deque[tuple[float, int]] = deque()
        self.best, self.best_at = 0, None

    def add(self, t: float, count: int) -> None:
        """`count` people tracked near the robot at run time `t` (s)."""
        self._window.append((t, count))
        while len(self._window) > 1 and self._window[1][0] <= t - HOLD_S:
            self._window.popleft()
        if t - self._window[0][0] >= HOLD_S - 1e-9:
            held = min(c for _, c in self._window)
            if held > self.best:
                self.best, self.best_at = held, self._window[0][0]

    def check(self, asked: int, share: float) -> PeopleCheck:
        return PeopleCheck(asked, self.best, self.best_at, math.ceil(asked * share - 1e-9))
