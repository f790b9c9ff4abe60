"""The interface between perception (simulator, log playback or the live robot) and the controllers: the one a
plug-in implements (docs/writing_a_controller.md).

Everything is in the world frame `map` (metres, seconds, radians), x forward along the robot's nominal path.
Histories are sampled at NaviGAN's step of 0.4 s, oldest first. Each run: `reset(seed)` once before it, `plan` every
0.4 s of the run's time with an `Observation`, `end(status)` once after it however it ended (`goal`, `collision`,
`timeout`, `aborted`, or `failed` when it raised). A plan must come back well within a step: live, one that has not come
within the robot's `plan_timeout` stops the robot and aborts the run; in the simulator and on logs one that takes
longer than 10 s fails the run (`trials.controllers.checked`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from robot_logs.physical import STEP_S


@dataclass(frozen=True)
class Observation:
    """What a controller sees at one planning step.

    Attributes:
        time: seconds since the run started.
        robot_pose: (3,) x, y, heading.
        robot_velocity: (2,) linear (m/s) and angular (rad/s) velocity.
        goal: (2,) goal position.
        robot_history: (T_OBS, 2) the robot's own last positions, the newest equal to its pose.
        pedestrian_ids: one stable id per tracked pedestrian.
        pedestrian_history: (N, T_OBS, 2) each pedestrian's last positions; NaN before a
            track was first seen.
        obstacles: (M, 2) points of the static world near the robot (walls, furniture: what the
            laser has seen stand still), none where nothing is known of it (the simulator's open ground).
    """

    time: float
    robot_pose: np.ndarray
    robot_velocity: np.ndarray
    goal: np.ndarray
    robot_history: np.ndarray
    pedestrian_ids: tuple[int, ...]
    pedestrian_history: np.ndarray
    obstacles: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))


@dataclass(frozen=True)
class Plan:
    """A controller's answer: way-points ahead of the robot, one every `step` seconds.

    `record` holds what the controller wants logged (forces, expansions, timing); it is
    controller-specific, so a blinded study keeps it out of the public log.
    """

    waypoints: np.ndarray
    step: float = STEP_S
    record: dict[str, Any] = field(default_factory=dict)


class Controller(Protocol):
    """A planner the runner drives: `reset` starts a run with its seed, `plan` answers each observation, `end` closes
    the run with its status, `details` is what a run's metadata records about it besides its name. A plug-in needs
    only `plan`; the registry (`trials.controllers.registry`) supplies the name and the missing methods."""

    name: str

    def details(self) -> dict[str, str]: ...

    def reset(self, seed: int) -> None: ...

    def plan(self, observation: Observation) -> Plan: ...

    def end(self, status: str) -> None: ...
