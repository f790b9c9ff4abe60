"""The adversary of a blinded study: every public feature of its runs that does not come from the
robot's or the people's motion, and whether one of them tells the arms apart.

An evaluator without the key sees the study folder (file sizes, modification times, the listing of
sealed/ if they may list it), the MCAP logs (topics, message counts, bytes) and the console of
`trials run`. Each feature maps a run code to a number; a feature separates the arms when the
value ranges of the two arms do not overlap.
"""

from __future__ import annotations

import csv
import os
import subprocess
import sys
import time
from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

from mcap.reader import make_reader

#: The topic with one message per physics step: other periodic topics are counted per message of it.
MOTION_TOPIC = "/robot/state"
#: The topic that is not periodic (the start and the ending), counted as it is.
EVENTS_TOPIC = "/events"


@dataclass(frozen=True)
class TimedRun:
    """A `trials run` in its own process with the time (s since start) at which each console line came."""

    returncode: int
    lines: list[tuple[float, str]]


def timed_trials(*args: str, timeout_s: float = 600.0) -> TimedRun:
    """Run the real `trials` command, stamping every line it prints (stdout and stderr together)."""
    start = time.monotonic()
    # Unbuffered, as a terminal shows it: each line when it is printed.
    environment = {**os.environ, "PYTHONUNBUFFERED": "1"}
    process = subprocess.Popen([sys.executable, "-m", "trials.cli", *args], stdout=subprocess.PIPE,
                               stderr=subprocess.STDOUT, text=True, env=environment)
    assert process.stdout is not None
    lines = [(time.monotonic() - start, line.rstrip("\n")) for line in process.stdout]
    return TimedRun(process.wait(timeout=timeout_s), lines)


def plan_arms(study: Path) -> dict[str, str]:
    """Run code -> the arm label (Controller column) of plan.csv."""
    with (study / "plan.csv").open(newline="") as handle:
        return {row["run_code"]: row["Controller"] for row in csv.DictReader(handle)}


def mcap_features(path: Path) -> dict[str, float]:
    """The log's bytes split as a reader sees them, its topics, and each topic's count per physics step.

    The file size and the size per message are not features of their own: the size is mostly the
    number of steps (the run's duration, which is motion, in outcomes.csv, and does differ by
    controller in these scenes), and so is the size per message, through the fixed part of the
    file spread over more or fewer messages. What is left is the compressed bytes per message
    and the bytes besides the messages (header, schemas, metadata, summary).
    """
    with path.open("rb") as stream:
        reader = make_reader(stream)
        counts = Counter(channel.topic for _, channel, _ in reader.iter_messages())
        chunks = reader.get_summary().chunk_indexes
    messages = sum(counts.values())
    stored = sum(c.chunk_length + c.message_index_length for c in chunks)
    per_state = {f"count {topic} per state": counts[topic] / counts[MOTION_TOPIC] for topic in counts if topic != EVENTS_TOPIC}
    per_state[f"count {EVENTS_TOPIC}"] = counts[EVENTS_TOPIC]
    return {"mcap compressed bytes per message": sum(c.chunk_length for c in chunks) / messages,
            "mcap bytes besides the messages": path.stat().st_size - stored, "topics": len(counts), **per_state}


def mtime_gaps(paths: Mapping[str, Path]) -> dict[str, float]:
    """Each file's modification time minus the one before it (in time order), as an observer of `ls -l` gets."""
    ordered = sorted(paths.items(), key=lambda item: item[1].stat().st_mtime_ns)
    gaps = {ordered[0][0]: 0.0}
    for (_, before), (code, path) in zip(ordered, ordered[1:]):
        gaps[code] = (path.stat().st_mtime_ns - before.stat().st_mtime_ns) / 1e9
    return gaps


#: Console gaps are read to the millisecond: lines that one write brings reach the reader together, and
#: what differs between them below that is the reader's own parsing, noise that may split 6 runs from 6 by chance.
CONSOLE_RESOLUTION_S = 1e-3


def console_gaps(run: TimedRun, codes: list[str]) -> dict[str, float]:
    """For each run, the time its console line came minus the previous line's (to CONSOLE_RESOLUTION_S)."""
    gaps, last = {}, 0.0
    for stamp, line in run.lines:
        code = next((c for c in codes if f", {c} (" in line), None)  # "[n/N] order k, CODE (settings): ..."
        if code is not None:
            gaps[code] = round((stamp - last) / CONSOLE_RESOLUTION_S) * CONSOLE_RESOLUTION_S
        last = stamp
    return gaps


def finished_gaps(study: Path) -> dict[str, float]:
    """Each run's finished_utc in outcomes.csv minus the previous run's."""
    with (study / "outcomes.csv").open(newline="") as handle:
        rows = sorted(csv.DictReader(handle), key=lambda r: r["finished_utc"])
    stamps = [datetime.fromisoformat(r["finished_utc"]).timestamp() for r in rows]
    return {r["run_code"]: (s - p if i else 0.0) for i, (r, s, p) in enumerate(zip(rows, stamps, [0.0, *stamps]))}


def sealed_listing(study: Path) -> dict[str, float]:
    """The size of each run's entry in `ls -l sealed/runs` (a run without its own entry has none)."""
    sizes = {}
    for path in (study / "sealed" / "runs").iterdir():
        code = path.name.split(".")[0]
        sizes[code] = path.stat().st_size
    return sizes


def public_features(study: Path, run: TimedRun) -> dict[str, dict[str, float]]:
    """Feature name -> run code -> value, for every public feature not made of the motion itself."""
    codes = list(plan_arms(study))
    logs = {code: study / "runs" / f"{code}.mcap" for code in codes}
    features: dict[str, dict[str, float]] = {}
    for code, path in logs.items():
        for name, value in mcap_features(path).items():
            features.setdefault(name, {})[code] = value
    features["mcap mtime gap s"] = mtime_gaps(logs)
    features["mcap mtime sub-minute s"] = {code: path.stat().st_mtime % 60 for code, path in logs.items()}
    features["console gap s"] = console_gaps(run, codes)
    features["finished_utc gap s"] = finished_gaps(study)
    sealed = sealed_listing(study) if (study / "sealed" / "runs").is_dir() else {}
    if sealed:
        features["sealed/runs entry bytes"] = sealed
    return features


def separating(features: Mapping[str, Mapping[str, float]], arms: Mapping[str, str]) -> dict[str, tuple[tuple[float, float], ...]]:
    """The features whose value ranges per arm do not overlap, with those ranges (arm order A, B, ...).

    `arms` maps each run to its arm (the real controller when the key is known); a feature a run
    lacks (a topic only one arm's logs have) counts as 0 for that run.
    """
    labels = sorted(set(arms.values()))
    found = {}
    for name, values in features.items():
        ranges = []
        for label in labels:
            own = [values.get(code, 0.0) for code, arm in arms.items() if arm == label]
            ranges.append((min(own), max(own)))
        disjoint = any(a[1] < b[0] or b[1] < a[0] for i, a in enumerate(ranges) for b in ranges[i + 1:])
        if disjoint:
            found[name] = tuple(ranges)
    return found
