"""scripts/reactive_reference.py, docs/results.md's yardstick for Table I: it avoids people, and only by avoiding."""

from __future__ import annotations

import numpy as np
import pytest

from navigan.data import load_split
from navigan.playback.episodes import load_episodes
from navigan.playback.evaluate import score_rollout
from navigan.playback.metrics import Scoring
from navigan.playback.protocols import PRESENT
from tests.support.scripts import load_script


@pytest.fixture(scope="module")
def reference():
    return load_script("reactive_reference")


def rates(reference, episodes, margin: float) -> tuple[float, float]:
    """(C, A) of the reactive walker over `episodes` keeping `margin` metres."""
    records = score_rollout(episodes, reference.walk_all(episodes, margin, 3), Scoring())
    return float(np.mean([r["comfortable"] for r in records])), float(np.mean([r["arrived"] for r in records]))


@pytest.mark.slow
def test_the_reactive_walker_arrives_and_keeps_clear_only_when_asked_to(reference, eth_ucy_dir):
    episodes = load_episodes(load_split(eth_ucy_dir, "zara2").test, PRESENT)
    comfort, arrival = rates(reference, episodes, 0.5)
    assert len(episodes) == 33 and arrival == 1.0 and comfort == pytest.approx(31 / 33)  # the present protocol (load_episodes default)
    blind_comfort, blind_arrival = rates(reference, episodes, 0.0)  # no margin: straight at the goal
    assert blind_arrival == 1.0 and blind_comfort < comfort - 0.2
