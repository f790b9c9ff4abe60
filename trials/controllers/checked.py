"""Any controller as the runner drives it: its registry name, its optional methods filled in, every plan checked.

A plug-in needs only `plan`; `reset`, `end` and `details` are called when it has them. A plan that is not a `Plan` of
finite way-points, or (in the simulator and on logs) that takes longer than `OFFLINE_PLAN_LIMIT_S`, raises
`ControllerFault`, which ends the run as failed with that reason; live runs time their plans themselves
(`trials.robot.live`), since there a late plan must stop the robot while the controller is still thinking.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from trials.controllers.base import Observation, Plan
from trials.controllers.plugins import BUILT_IN, Source
from trials.errors import StudyError

#: The longest a plan may take in the simulator and on logs (s of this computer's clock): far above any planner's
#: step, so a run's result never depends on the machine's load, yet a runaway planner ends its run.
OFFLINE_PLAN_LIMIT_S = 10.0


class ControllerFault(StudyError):
    """A controller answered outside its interface (a malformed plan, or too late); the run fails with this reason."""


class CheckedController:
    """`inner` driven under `name` (the `Controller` protocol), its plans checked and, with `limit_s`, timed."""

    def __init__(self, inner: Any, name: str, source: Source, limit_s: float | None = OFFLINE_PLAN_LIMIT_S) -> None:
        self.inner, self.name, self.source, self.limit_s = inner, name, source, limit_s

    def details(self) -> dict[str, str]:
        """The controller's own details as strings; a plug-in's add where it came from."""
        own = getattr(self.inner, "details", None)
        found = {str(k): str(v) for k, v in (own() if callable(own) else {}).items()}
        return found if self.source.kind == BUILT_IN else {**found, "source": self.source.describe()}

    def reset(self, seed: int) -> None:
        reset = getattr(self.inner, "reset", None)
        if callable(reset):
            reset(seed)

    def end(self, status: str) -> None:
        end = getattr(self.inner, "end", None)
        if callable(end):
            end(status)

    def plan(self, observation: Observation) -> Plan:
        began = time.perf_counter()
        plan = self.inner.plan(observation)
        took = time.perf_counter() - began
        if self.limit_s is not None and took > self.limit_s:
            raise ControllerFault(f"the controller took {took:.1f} s to plan (the limit is {self.limit_s:g} s)")
        return checked_plan(plan)


def checked_plan(plan: object) -> Plan:
    """`plan` when it is a `Plan` of finite (K, 2) way-points, K >= 1, a positive step and a dict record.

    Raises:
        ControllerFault: what is wrong with it, in words that name no controller.
    """
    if not isinstance(plan, Plan):
        raise ControllerFault(f"the controller answered a {type(plan).__name__}, not a trials.controllers.base.Plan")
    waypoints = np.asarray(plan.waypoints)
    if waypoints.ndim != 2 or waypoints.shape[0] < 1 or waypoints.shape[1] != 2 or not np.issubdtype(waypoints.dtype, np.number):
        raise ControllerFault(f"the controller's plan has way-points of shape {waypoints.shape}, not (K, 2) numbers with K >= 1")
    if not np.isfinite(waypoints).all():
        raise ControllerFault("the controller's plan has a way-point that is not finite")
    if not (isinstance(plan.step, int | float) and math.isfinite(plan.step) and plan.step > 0):
        raise ControllerFault(f"the controller's plan has step {plan.step!r}, not a positive number of seconds")
    if not isinstance(plan.record, dict):
        raise ControllerFault(f"the controller's plan has a record of type {type(plan.record).__name__}, not a dict")
    return plan
