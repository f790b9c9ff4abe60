"""Staging a live run: where the robot starts and where its goal lies in the lab's frame, the study's start mark, whether
the robot stands at its start, and the row's scene (where each walker starts and goes) as the operator lays it out.

A lab gives the start pose and goals in one frame (`[robot] goal_frame`): `map` (or any frame its tf connects to the
odometry frame) where the robot localises; the odometry frame itself; or `mark`, a start mark measured once with
`trials run --robot URI --mark` (the robot's pose in the odometry frame as it stands on a mark on the floor, kept in
start_mark.json), with the start and goals relative to that mark. `start` puts the goal relative to wherever the robot
stands when its run begins: nothing is staged or checked, for rehearsals only.

The walkers' layout is the simulator's scene for the row (`trials.scenario`, seeded as `trials run` seeds it), placed
with the robot's start at its origin: the same scene the software robot lays out and the staging sheet draws.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

import numpy as np

from robot_logs.frames import Pose2D, frame_name
from trials.atomic import write_text
from trials.errors import StudyError
from trials.robot.settings import MARK_FRAME, START_FRAME, RobotSettings
from trials.scenario import CONTROLLER, Scenario, build_scenario, settings_from_row
from trials.study import PLAN, StudyFolder

#: The study's start mark, in its folder.
MARK_FILE = "start_mark.json"
#: The plan columns that are not a row's scene.
NOT_SCENE = ("order", "run_code", CONTROLLER, "Log")


@dataclass(frozen=True)
class StartMark:
    """The robot's pose in `frame` (its odometry frame) as it stood on the lab's start mark, and when that was measured."""

    frame: str
    pose: Pose2D
    measured_utc: str


def read_mark(folder: StudyFolder) -> StartMark | None:
    """The study's start mark, None before one was measured.

    Raises:
        StudyError: a damaged start_mark.json, naming the file and field.
    """
    path = folder.path(MARK_FILE)
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        return None
    except (OSError, ValueError) as exc:
        raise StudyError(f"{path} cannot be read ({exc}): measure the mark again with `trials run --robot URI --mark`") from None
    pose = record.get("pose") if isinstance(record, dict) else None
    if not (isinstance(pose, list) and len(pose) == 3 and all(isinstance(v, int | float) and math.isfinite(v) for v in pose)):
        raise StudyError(f"{path}: field 'pose' must be [x, y, yaw] in metres and radians, got {pose!r}")
    if not isinstance(record.get("frame"), str) or not record["frame"]:
        raise StudyError(f"{path}: field 'frame' must name the odometry frame, got {record.get('frame')!r}")
    return StartMark(record["frame"], Pose2D(*map(float, pose)), str(record.get("measured_utc", "")))


def write_mark(folder: StudyFolder, mark: StartMark) -> None:
    pose = mark.pose
    write_text(folder.path(MARK_FILE), json.dumps({"frame": mark.frame, "pose": [round(pose.x, 4), round(pose.y, 4), round(pose.yaw, 5)],
                                                   "measured_utc": mark.measured_utc}, indent=1) + "\n")


@dataclass(frozen=True)
class Stage:
    """A row's start pose and goal (x, y) in `frame`, a frame the robot's tf connects to its odometry frame."""

    frame: str
    start: Pose2D
    goal: tuple[float, float]


def stage_of(settings: RobotSettings, row: dict[str, str], folder: StudyFolder) -> Stage | None:
    """Where row `row` starts and ends; None when the goal is relative to wherever the robot stands (`goal_frame = "start"`).

    Raises:
        StudyError: `goal_frame = "mark"` and no mark was measured, or its file is damaged.
    """
    goal, start = settings.goal_for(row)[:2], Pose2D(*settings.start)
    if settings.goal_frame == START_FRAME:
        return None
    if settings.goal_frame == MARK_FRAME:
        mark = read_mark(folder)
        if mark is None:
            raise StudyError(f"no start mark in {folder.root} ({MARK_FILE}): [robot] goal_frame is \"mark\"; stand the robot on the "
                             "lab's start mark and run `trials run --robot URI --mark` once")
        placed = mark.pose.apply(np.array(goal))[0]
        return Stage(mark.frame, mark.pose.compose(start), (float(placed[0]), float(placed[1])))
    return Stage(frame_name(settings.goal_frame), start, (float(goal[0]), float(goal[1])))


def off_start(robot: Pose2D, stage: Stage, tolerance: tuple[float, ...]) -> str | None:
    """Why the robot, at `robot` in the stage's frame, does not stand at its start within `tolerance` (m, rad); else None."""
    distance = math.hypot(robot.x - stage.start.x, robot.y - stage.start.y)
    turn = abs((robot.yaw - stage.start.yaw + math.pi) % (2.0 * math.pi) - math.pi)
    if distance <= tolerance[0] and turn <= tolerance[1]:
        return None
    return (f"the robot stands {distance:.2f} m and {math.degrees(turn):.0f} deg from its start {_pose_text(stage.start)} in "
            f"{stage.frame} (tolerance {tolerance[0]:g} m, {math.degrees(tolerance[1]):.0f} deg)")


def row_scenario(folder: StudyFolder | None, code: str, default_seed: int = 0) -> Scenario:
    """The simulator's scene of plan row `code`, seeded as `trials run` seeds it; the default scene, seeded by `default_seed`,
    without a study (a software robot on its own) or when the plan has no such row.

    Raises:
        StudyError: a row the simulator cannot lay out, naming the plan and run.
    """
    from trials.runner import row_seeds, run_seed

    plan = {r["run_code"]: r for r in folder.read_plan()} if folder is not None and folder.path(PLAN).exists() else {}
    if folder is not None and code in plan:
        row = {k: v for k, v in plan[code].items() if k not in NOT_SCENE}
        seed = run_seed(int(folder.read_design()["seed"]), code)
    else:
        row, seed = {}, default_seed
    where = f"{folder.path(PLAN)} run {code}" if folder is not None else "the default scene"
    return build_scenario(settings_from_row(row, where), row_seeds(seed)[0])


@dataclass(frozen=True)
class StagedScene:
    """A row's scene in the lab's frame: the robot's start and goal, and each walker's start and goal, as the operator
    stages them (positions rounded to the centimetre when shown)."""

    code: str
    frame: str
    start: Pose2D
    goal: tuple[float, float]
    scenario: Scenario

    @classmethod
    def of(cls, scenario: Scenario, stage: Stage | None, code: str) -> StagedScene:
        """`scenario` placed at the stage's start (unstaged: in the frame of the robot's own start)."""
        if stage is None:
            return cls(code, START_FRAME, Pose2D(), (float(scenario.goal[0]), float(scenario.goal[1])), scenario)
        return cls(code, stage.frame, stage.start, stage.goal, scenario)

    def place(self, points: np.ndarray) -> np.ndarray:
        """(N, 2) scene points (robot's start at the origin, facing +x) in the lab's frame."""
        return self.start.apply(np.asarray(points, dtype=float).reshape(-1, 2))

    def lines(self) -> list[str]:
        """The scene in words, one line each for the robot and every walker, as the staging sheet and `trials run` print it."""
        s = self.scenario.settings
        where = "relative to the robot's own start (goal_frame \"start\": not staged)" if self.frame == START_FRAME else f"in {self.frame}"
        out = [f"{s.direction}, {s.pedestrians} pedestrian{'s' * (s.pedestrians != 1)}, crossing distance {s.crossing_distance:g} m; "
               f"positions in metres {where}",
               f"robot: start {_pose_text(self.start)}, goal ({self.goal[0]:.2f}, {self.goal[1]:.2f})"]
        for walker in self.scenario.walkers:
            start, goal = self.place(np.array([walker.start, walker.goal]))
            when = (f"sets off {walker.delay_s:.1f} s after the start" if walker.role == "oncoming"
                    else f"crosses {s.crossing_distance:g} m ahead of the robot's bumper")
            out.append(f"walker {walker.id + 1} ({walker.role}): from ({start[0]:.2f}, {start[1]:.2f}) to ({goal[0]:.2f}, {goal[1]:.2f}), "
                       f"{when}")
        return out


def staged_scene(folder: StudyFolder, settings: RobotSettings, code: str) -> StagedScene:
    """Plan row `code`'s scene in the lab's frame.

    Raises:
        StudyError: as `stage_of` and `row_scenario`.
    """
    row = next((r for r in folder.read_plan() if r["run_code"] == code), {})
    return StagedScene.of(row_scenario(folder, code), stage_of(settings, row, folder), code)


def _pose_text(pose: Pose2D) -> str:
    return f"({pose.x:.2f}, {pose.y:.2f}) facing {math.degrees(pose.yaw):.0f} deg"
