"""The adversary of a blinded study: no public feature that is not the motion itself tells the arms apart.

Three blinded 18-run A/B studies (the paper's plan, seeds 5 and 77 simulated on one worker, so each
line and file comes when its run ends; one played from a robot log with `--from-log`). For every
run the test computes what an evaluator without the key can: the MCAP's compressed bytes per
message and its bytes besides the messages, topics and per-topic counts, modification times, the listing of sealed/runs, the time between console
lines, the finished_utc stamps. Knowing the key, it checks that no feature's values for one
controller fall wholly apart from the other's, pooled over the studies and within each Pedestrians
level. The same check finds the record sizes inside the sealed archive, which do differ by
controller, so it is not toothless.
"""

from __future__ import annotations

import csv
import gzip
import json
import re
import stat
from pathlib import Path

import numpy as np
import pytest

from robot_logs.foxglove_log import FoxgloveReader
from robot_logs.run_log import CONTROLLER_TOPICS
from tests.support.side_channels import TimedRun, public_features, separating, timed_trials

pytestmark = pytest.mark.slow  # three 18-run studies run end to end

SIMULATED_SEEDS = (5, 77)
LOGGED_SEED = 9


def _design(study: Path, seed: int) -> None:
    made = timed_trials("design", "--ab", "--seed", str(seed), "--study", str(study))
    assert made.returncode == 0, made.lines


def _run(study: Path, *extra: str) -> TimedRun:
    run = timed_trials("run", "--study", str(study), *extra)
    assert run.returncode == 0, run.lines
    return run


@pytest.fixture(scope="module")
def studies(tmp_path_factory, robot_logs_dir) -> list[tuple[Path, TimedRun]]:
    root = tmp_path_factory.mktemp("adversary")
    made = []
    for seed in SIMULATED_SEEDS:
        _design(root / f"sim{seed}", seed)
        made.append((root / f"sim{seed}", _run(root / f"sim{seed}", "--workers", "1")))
    logged = root / "logged"
    _design(logged, LOGGED_SEED)
    made.append((logged, _run(logged, "--workers", "2", "--from-log", str(robot_logs_dir / "stationary_ros2"),
                              "--start", "8", "--duration", "3")))
    return made


def _truth(study: Path) -> tuple[dict[str, str], dict[str, str]]:
    """Run code -> its real controller (from the key), and -> its Pedestrians level."""
    key = json.loads((study / "sealed" / "allocation.json").read_text())["arms"]
    with (study / "plan.csv").open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    return {r["run_code"]: key[r["Controller"]] for r in rows}, {r["run_code"]: r["Pedestrians"] for r in rows}


def _pooled(studies: list[tuple[Path, TimedRun]]) -> tuple[dict[str, dict[str, float]], dict[str, str], dict[str, str]]:
    """Every study's features with run codes made unique (study/code), the controllers and the groups
    (a simulated run's Pedestrians level; a logged study, which plays one log throughout, is one group)."""
    features: dict[str, dict[str, float]] = {}
    controllers, groups = {}, {}
    for study, run in studies:
        truth, level = _truth(study)
        for name, values in public_features(study, run).items():
            for code, value in values.items():
                features.setdefault(name, {})[f"{study.name}/{code}"] = value
        for code in truth:
            controllers[f"{study.name}/{code}"] = truth[code]
            groups[f"{study.name}/{code}"] = "logged" if study.name == "logged" else f"{level[code]} pedestrians"
    return features, controllers, groups


def test_no_public_feature_separates_the_arms(studies):
    features, controllers, groups = _pooled(studies)
    assert {"mcap compressed bytes per message", "mcap bytes besides the messages", "mcap mtime gap s", "console gap s", "sealed/runs entry bytes",
            "count /events", "finished_utc gap s"} <= set(features)
    assert all(len(values) == len(controllers) for values in features.values())
    for group in [None, *sorted(set(groups.values()))]:
        chosen = {code: arm for code, arm in controllers.items() if group is None or groups[code] == group}
        assert sorted(set(chosen.values())) == ["Lattice", "NaviGAN-R"]
        assert separating({n: {c: v for c, v in values.items() if c in chosen} for n, values in features.items()}, chosen) == {}, group


def _evenly_spaced_plans(record: dict) -> int:
    """How many of a run's plans have way-points exactly 0.4 m apart (the lattice's primitives)."""
    count = 0
    for plan in record["topics"]["/controller/plan"]:
        steps = np.hypot(*np.diff(np.array(plan["waypoints"]), axis=0).T)
        count += bool(len(steps)) and bool(np.all(np.abs(steps - 0.4) < 5e-4))
    return count


def test_the_adversary_finds_what_the_sealed_records_hold(studies):
    """The plans the public logs held before, now sealed, do tell the arms apart (the lattice's
    way-points come 0.4 m apart in some plans of every run, NaviGAN-R's never): the same check
    that passes on the public features finds that."""
    for study, _ in studies[:2]:
        truth, _ = _truth(study)
        spaced = {code: _evenly_spaced_plans(json.loads(gzip.decompress((study / "sealed" / "runs" / f"{code}.json.gz").read_bytes())))
                  for code in truth}
        assert set(separating({"evenly spaced plans": spaced}, truth)) == {"evenly spaced plans"}
        assert max(v for c, v in spaced.items() if truth[c] == "NaviGAN-R") == 0


#: A run's console line, `[n/N] order k, CODE (settings): ...`.
RUN_LINE = re.compile(r"\[\d+/\d+\] order \d+, (\w+) \(")


def test_the_public_record_is_what_an_observer_could_see(studies):
    for study, run in studies:
        assert stat.S_IMODE((study / "sealed").stat().st_mode) == 0o700
        assert all(stat.S_IMODE(p.stat().st_mode) == 0o600 for p in (study / "sealed").rglob("*") if p.is_file())
        for path in (study / "runs").glob("*.mcap"):
            log = FoxgloveReader(path)
            assert not set(log.topics) & {t.name for t in CONTROLLER_TOPICS} and "replay" not in log.metadata
            assert path.stat().st_mtime_ns % 60_000_000_000 == 0
        assert (study / "outcomes.csv").stat().st_mtime_ns % 60_000_000_000 == 0
        # Every run's line comes once all have ended, in plan order, not in the order the runs ended.
        with (study / "plan.csv").open(newline="") as handle:
            plan = [row["run_code"] for row in csv.DictReader(handle)]
        named = [match.group(1) for _, line in run.lines if (match := RUN_LINE.match(line))]
        assert named == plan
