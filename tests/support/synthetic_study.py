"""Study folders for the report tests: a real plan from `trials design`, runs synthesised per the contract.

A synthetic run drives a unicycle robot 10 m along x past pedestrians walking straight lines
(towards it for Parallel, across its path for Crossing), with optional scripted misbehaviour
(stopping, backing up, turning in place, hesitating, colliding). Its log goes to runs/<code>.mcap
through FoxgloveWriter and its metrics to outcomes.csv, as docs/study_folder.md specifies.
"""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from analysis.run_log import footprint_gap
from robot_logs import run_log as fmt
from robot_logs.foxglove_log import FoxgloveWriter
from trials.cli import main
from trials.outcomes import columns
from trials.study import OUTCOMES, RUNS, StudyFolder

DT = 0.1
GOAL_X = 10.0


@dataclass(frozen=True)
class Behaviour:
    """What a synthetic robot does: its passing clearance (m) and scripted misbehaviour (s)."""

    clearance: float = 1.5
    stop_s: float = 0.0
    backup_s: float = 0.0
    turn_s: float = 0.0
    hesitate_s: float = 0.0
    collide: bool = False


SMOOTH = Behaviour()
#: The lattice-like arm: passes closer and stops now and then (deterministic per run in `behaviour_for`).
CLUMSY = Behaviour(clearance=0.5, stop_s=1.5)


def design(tmp: Path, ab: bool = True, seed: int = 1) -> StudyFolder:
    """A real plan in `tmp`: the 18-run blinded A/B plan, or the 27-run qualitative one."""
    args = ["design", "--study", str(tmp), "--seed", str(seed)] + (["--ab"] if ab else [])
    assert main(args) == 0
    return StudyFolder(tmp)


def controllers(folder: StudyFolder) -> dict[str, str]:
    """Run code -> controller, read the way the runner does (the sealed key for a blinded plan)."""
    plan = folder.read_plan()
    key_path = folder.path("sealed/allocation.json")
    arms = json.loads(key_path.read_text())["arms"] if key_path.exists() else {}
    return {row["run_code"]: arms.get(row.get("Controller", ""), row.get("Controller") or "NaviGAN-R") for row in plan}


def _robot_path(behaviour: Behaviour) -> np.ndarray:
    """(n, 6) t, x, y, theta, v, w of a robot driving to x = 10 with its scripted episodes at x = 3."""
    rows = []
    x = y = theta = t = 0.0
    script: list[tuple[float, float, float]] = []
    if behaviour.stop_s:
        script.append((behaviour.stop_s, 0.0, 0.0))
    if behaviour.hesitate_s:
        script.append((behaviour.hesitate_s, 0.15, 0.0))
    if behaviour.turn_s:
        script += [(behaviour.turn_s / 2, 0.0, 1.0), (behaviour.turn_s / 2, 0.0, -1.0)]
    if behaviour.backup_s:
        script.append((behaviour.backup_s, -0.3, 0.0))
    done_script = False
    while x < GOAL_X - 0.5 and t < 60.0:
        if not done_script and x >= 3.0 and script:
            for duration, v, w in script:
                for _ in range(int(round(duration / DT))):
                    rows.append([t, x, y, theta, v, w])
                    x, y, theta, t = x + v * np.cos(theta) * DT, y + v * np.sin(theta) * DT, theta + w * DT, t + DT
            done_script = True
        v = min(1.0, 0.2 + t)
        rows.append([t, x, y, theta, v, 0.0])
        x, y, t = x + v * np.cos(theta) * DT, y + v * np.sin(theta) * DT, t + DT
    rows.append([t, x, y, theta, rows[-1][4], 0.0])  # the run ends on arrival, still moving
    return np.asarray(rows)


def _pedestrians(robot: np.ndarray, count: int, direction: str, behaviour: Behaviour, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """id -> (n, 2) positions at the robot's times: walkers passing the robot at about `clearance`."""
    t = robot[:, 0]
    paths = {}
    for i in range(count):
        side = 1.0 if i % 2 == 0 else -1.0
        offset = behaviour.clearance + 0.6 + 0.5 * (i // 2) + rng.uniform(0.0, 0.2)
        crossing = direction == "Crossing" or (direction == "ParallelCrossing" and i % 2 == 1)
        meet = rng.uniform(2.0, 8.0)
        if crossing:
            # Crosses x = meet + offset at the moment the robot is at x = meet.
            when = float(np.interp(meet, robot[:, 1], t))
            xy = np.column_stack([np.full_like(t, meet + offset), side * 1.3 * (t - when)])
        else:
            xy = np.column_stack([meet + 1.2 * (float(np.interp(meet, robot[:, 1], t)) - t), np.full_like(t, side * offset)])
        paths[f"{i + 1}"] = xy
    if behaviour.collide:
        paths[f"{count + 1}"] = np.column_stack([np.full_like(t, 6.0), np.zeros_like(t)])
    return paths


def _outcome(code: str, seed: int, robot: np.ndarray, peds: dict[str, np.ndarray], status: str, controller: str | None) -> dict[str, str]:
    t, v, w, theta = robot[:, 0], robot[:, 4], robot[:, 5], robot[:, 3]
    dt = np.diff(t, append=t[-1] + DT)
    gap = np.min([footprint_gap(robot[:, 1:4], xy) for xy in peds.values()], axis=0) if peds else np.full(len(t), 99.0)
    step = np.hypot(np.diff(robot[:, 1]), np.diff(robot[:, 2]))
    accel = np.diff(v) / DT
    length = float(step.sum())
    values = {
        "run_code": code, "status": status, "seed": seed, "perception": "positions",
        "duration_s": float(t[-1]), "time_to_goal_s": float(t[-1]) if status == "goal" else "", "path_length_m": length,
        "min_distance_m": float(gap.min()), "time_within_0_5m_s": float(dt[gap < 0.5].sum()), "time_within_1_2m_s": float(dt[gap < 1.2].sum()),
        "collisions": int(status == "collision"), "max_deceleration_mps2": float(max(0.0, -accel.min())),
        "max_jerk_mps3": float(np.abs(np.diff(accel) / DT).max()), "path_irregularity_rad_per_m": float(np.abs(np.diff(theta)).sum() / max(length, 1e-9)),
        "turn_in_place_s": float(dt[(np.abs(v) < 0.05) & (np.abs(w) > 0.3)].sum()), "backing_up_s": float(dt[v < -0.05].sum()),
        "stopped_s": float(dt[(np.abs(v) < 0.05) & (np.abs(w) < 0.3) & (t >= 1.0)][:-1].sum()),
        "controller": controller or "", "finished_utc": "2026-01-01T00:00:00+00:00",
    }
    return {k: (f"{val:.4f}" if isinstance(val, float) else str(val)) for k, val in values.items()}


def write_run(folder: StudyFolder, row: dict[str, str], behaviour: Behaviour, seed: int, controller: str | None) -> dict[str, str]:
    """Synthesise one run of a plan row: its log and its outcome row (controller None when blind)."""
    code = row["run_code"]
    rng = np.random.default_rng(seed)
    robot = _robot_path(behaviour)
    peds = _pedestrians(robot, int(row.get("Pedestrians", 2)), row.get("Direction", "Parallel"), behaviour, rng)
    status = "goal"
    if behaviour.collide:
        gap = footprint_gap(robot[:, 1:4], peds[str(len(peds))])
        end = int(np.argmax(gap <= 0.0)) + 1
        robot, peds = robot[:end], {k: xy[:end] for k, xy in peds.items()}
        status = "collision"
    factors = {k: v for k, v in row.items() if k not in ("order", "run_code")}
    metadata = {"run_code": code, "study": folder.root.name, "seed": str(seed), "perception": "positions", **factors}
    if controller:
        metadata["controller"] = controller
    folder.path(RUNS).mkdir(exist_ok=True)
    with FoxgloveWriter(folder.run_log(code), {fmt.RUN_METADATA: metadata}) as log:
        log.write(*fmt.EVENTS, {"t": 0.0, "event": "start", "detail": ""}, 0)
        ids = list(peds)
        for i, (t, x, y, theta, v, w) in enumerate(robot):
            stamp = int(round(t * 1e9))
            log.write(*fmt.ROBOT_STATE, {"t": t, "x": x, "y": y, "theta": theta, "v": v, "w": w, "v_cmd": v, "w_cmd": w}, stamp)
            positions = [peds[k][i] for k in ids]
            log.write(*fmt.PEDESTRIANS, {
                "t": t, "ids": [int(k) for k in ids], "x": [float(p[0]) for p in positions], "y": [float(p[1]) for p in positions],
                "vx": [0.0] * len(ids), "vy": [0.0] * len(ids)}, stamp)
        log.write(*fmt.EVENTS, {"t": float(robot[-1, 0]), "event": status, "detail": ""}, int(round(robot[-1, 0] * 1e9)))
    outcome = _outcome(code, seed, robot, peds, status, controller)
    path = folder.path(OUTCOMES)
    new = not path.exists()
    with path.open("a", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, columns(blind=not controller), extrasaction="ignore", lineterminator="\n")
        if new:
            writer.writeheader()
        writer.writerow(outcome)
    return outcome


def behaviour_for(controller: str, order: int) -> Behaviour:
    """NaviGAN-R runs smooth; lattice runs pass closer and stop in every other run."""
    if controller == "Lattice":
        return CLUMSY if order % 2 else Behaviour(clearance=0.9)
    return SMOOTH


def run_all(folder: StudyFolder, limit: int | None = None, blind: bool = True) -> list[dict[str, str]]:
    """Synthesise the first `limit` runs of the plan (all by default), as `trials run [--blind]` would."""
    by_code = controllers(folder)
    outcomes = []
    for row in folder.read_plan()[:limit]:
        controller = by_code[row["run_code"]]
        outcomes.append(write_run(folder, row, behaviour_for(controller, int(row["order"])), 100 + int(row["order"]), None if blind else controller))
    return outcomes


def judged_ab_study(root: Path, limit: int | None = None, seed: int = 5) -> Path:
    """The blinded A/B plan in `root` with its first `limit` runs (all by default) synthesised and judged by simulated
    participants (`seed`)."""
    run_all(design(root), limit=limit)
    assert main(["respond", "--simulate", "--seed", str(seed), "--study", str(root)]) == 0
    return root
