"""Closed-loop power: whole simulated campaigns of a plan, each run driven by the real controllers among
simulated pedestrians and judged by simulated participants, the campaign analysed as `trials report` does.

Each campaign has its own seed (from the power seed) and from it fresh scenario, crowd, perception,
controller and participant seeds for every run, and, in a blinded study, its own random allocation
of the controllers to the arm labels: the study's sealed key is never opened. A worker builds its
controllers once and runs campaigns until told to stop; nothing it does touches the study folder.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from analysis.participants import judge_run
from analysis.run_log import RunLog as JudgedLog
from trials.controllers import registry
from trials.controllers.nav_stack import is_nav_stack
from trials.errors import StudyError
from trials.power.plans import PowerPlan
from trials.power.seeds import derived
from trials.power.verdicts import Verdict, judgments_verdict
from trials.runner import RunOptions, row_seeds, scene_of
from trials.scenario import CONTROLLER
from trials.sim.closed_loop import COLLISION, GOAL, TIMEOUT, NoSink, RunResult, simulate

STATUSES = (GOAL, COLLISION, TIMEOUT)


@dataclass(frozen=True)
class CampaignBatch:
    """Campaigns for one worker task: the plan's index in the list of plans, and (campaign, seed) pairs."""

    plan: int
    campaigns: tuple[tuple[int, int], ...]


@dataclass(frozen=True)
class CampaignResult:
    """One simulated campaign: which plan (by runs) and campaign, its seed and allocation, how its runs
    ended, its judgments, and its verdict (Table II shares by controller name)."""

    runs: int
    campaign: int
    seed: int
    allocation: dict[str, str]
    statuses: dict[str, int]
    judgments: int
    verdict: Verdict


def campaign_seed(power_seed: int, plan: PowerPlan, campaign: int) -> int:
    return derived(power_seed, "campaign", plan.runs, campaign)


def allocation(plan: PowerPlan, controllers: tuple[str, ...], seed: int) -> dict[str, str]:
    """The campaign's controller for each Controller level: a random allocation when the plan is
    blinded (the levels are arm labels), the levels themselves when they name controllers."""
    if not plan.arms:
        return {}
    if not plan.blinded:
        return {level: level for level in plan.arms}
    order = np.random.default_rng(derived(seed, "allocation")).permutation(len(controllers))
    return {arm: controllers[i] for arm, i in zip(plan.arms, order)}


def judged_log(result: RunResult, walkers: int) -> JudgedLog:
    """The run as the participants' model reads a run log, rounded as the MCAP log stores it."""
    trace = result.trace
    time = np.round(np.array(trace.time), 4)
    robot = np.round(np.column_stack([time, np.array(trace.pose), np.array(trace.velocity)]), 4)
    people = np.round(np.array(trace.pedestrians).reshape(len(time), walkers, 2), 4)
    tracks = {str(i): np.column_stack([time, people[:, i]]) for i in range(walkers)}
    return JudgedLog(robot, dict(sorted(tracks.items())), [], {})


class CampaignWorker:
    """Runs campaigns with controllers built once (one per name the plans may need)."""

    def __init__(self, plans: list[PowerPlan], controllers: tuple[str, ...], options: RunOptions, participants: int | None) -> None:
        self.plans, self.controllers, self.options, self.participants = plans, controllers, options, participants
        built = registry.ControllerOptions(weights=options.settings.weights)
        self._built = {name: registry.build(name, built) for name in controllers}
        if any(is_nav_stack(controller) for controller in self._built.values()):
            raise StudyError("a controller that plans on the robot (NavStack) cannot be simulated: closed-loop power needs "
                             "controllers that run in the simulator")

    def __call__(self, batch: CampaignBatch) -> list[CampaignResult]:
        plan = self.plans[batch.plan]
        return [self.campaign(plan, index, seed) for index, seed in batch.campaigns]

    def campaign(self, plan: PowerPlan, index: int, seed: int) -> CampaignResult:
        """Simulate and judge every run of `plan`, then analyse the campaign."""
        allocated = allocation(plan, self.controllers, seed)
        judges_seed = derived(seed, "participants")
        statuses = dict.fromkeys(STATUSES, 0)
        yes, total, names = [], [], []
        for row in plan.rows:
            level = row.get(CONTROLLER)
            name = allocated[level] if level is not None else registry.DEFAULT
            code = row["run_code"]
            seeds = row_seeds(derived(seed, "run", code))
            factors = {k: v for k, v in row.items() if k not in ("run_code", CONTROLLER)}
            scenario, perception, config = scene_of(factors, f"run {code}", self.options, seeds)
            controller = self._built[name]
            controller.reset(seeds[3])
            result = simulate(scenario, controller, perception, NoSink(), config, seeds[1])
            statuses[result.status] += 1
            judgments = judge_run(judged_log(result, len(scenario.walkers)), code, judges_seed, self.participants)
            yes.append(sum(j.compliant for j in judgments))
            total.append(len(judgments))
            names.append(name)
        verdict = judgments_verdict(plan, np.array(yes, dtype=float), np.array(total, dtype=float), names if plan.arms else None)
        return CampaignResult(plan.runs, index, seed, allocated, statuses, int(sum(total)), verdict)


def setup_worker(plans: list[PowerPlan], controllers: tuple[str, ...], options: RunOptions,
                 participants: int | None) -> Callable[[CampaignBatch], list[CampaignResult]]:
    """A worker process's handler: torch on one thread (the workers share the cores), controllers built once."""
    import torch

    torch.set_num_threads(1)
    return CampaignWorker(plans, controllers, options, participants)
