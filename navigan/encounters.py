"""Encounters: synthetic rows that teach the social force to make room for one oncoming agent.

Recorded people rarely walk straight at anyone: by the time they are observed they have begun to
make room, and a goal at their recorded future position tells the intention where that room is.
So the recordings seldom ask the social force to act, and a planner trained on them alone walks
into people who, being recordings or a robot's test, do not give way. An encounter takes a real
window, one agent j whose future is known and a step k, and puts beside j alone a walker who,
keeping the replaced target's pace on a straight line, passes where j stands at step k at a random
sideways offset (so some encounters need no room at all); its goal lies farther along that line. A
walker in place of a standing target stands where j will pass. Half the walkers are left alone,
without j, the way a robot crosses an empty stretch. A walker has no recorded future: its
way-points are scored by how smoothly its force departs from the intention (see
`losses.encounter_losses`) and against j's recorded future (the resistance loss), so the social
force learns an early, held side-step that keeps d_safe, and none when nobody is in the way.

By default only j is kept, because the paper's PoolNet max-pools over the others: in a crowd one
agent on a collision course seldom sets any pooled feature, so the crowd would teach a blanket
push, not a response to that agent. A generator with PairPoolNet (`ModelConfig.pair_pool`) can
single that agent out, and then a fraction `crowd` of the walkers keeps the window's whole crowd
(every agent's recorded future counts in the resistance loss): a crowd that never gives way is
where such a planner has to find its way.
"""

from __future__ import annotations

import numpy as np
import torch

from navigan.data import SceneBatch
from robot_logs.physical import STEP_S, T_OBS, T_PRED

#: Steps after the last observed one at which the walker passes its agent.
MEET_STEPS = (1, T_PRED)
#: Largest sideways offset (m) of the walker's line from the agent's position at the meeting.
PASS_OFFSET = 0.75
#: Fraction of walkers left alone (their agent removed): they should need no force.
ALONE = 0.5
#: A target slower than this (m/s) stands: its walker stands where the agent passes, its goal lies
#: as far as a walk at a pace drawn from STANDING_PACE would take it. MAX_PACE caps the walkers' pace.
STANDING = 0.3
STANDING_PACE = (0.6, 1.4)
MAX_PACE = 1.8


def encounter_batch(
    batch: SceneBatch, rate: float, goal_steps: tuple[int, int], rng: np.random.Generator, crowd: float = 0.0
) -> SceneBatch | None:
    """About `rate` encounters per target of `batch`, each in a copy of its window; None if none.

    Each copy's agents are the walker, in the row of the target it replaces, and its agent j
    (unless alone), or with probability `crowd` every agent of the window; `future` and `seen` are
    the window's, the walker's own row unseen. A walker keeps the pace of the target it replaces;
    its goal lies a uniform number of steps in `goal_steps` ahead (at least two beyond the meeting)
    at that pace, or at a drawn walking pace for a standing walker.
    """
    targets, obs, future, seen, mask = (t.numpy() for t in (batch.targets, batch.obs, batch.future, batch.seen, batch.mask))
    rows = np.argwhere(targets)
    count = rng.binomial(len(rows), min(rate, 1.0))
    picked, walkers, goals = [], [], []
    for w, i in rows[rng.choice(len(rows), size=count, replace=False)]:
        meets = mask[w, :, None] & seen[w] & (np.arange(mask.shape[1]) != i)[:, None]
        meets[:, : MEET_STEPS[0] - 1] = False
        options = np.argwhere(meets[:, : MEET_STEPS[1]])
        if not len(options):
            continue
        j, step = options[rng.integers(len(options))]
        pace = min(float(np.linalg.norm(obs[w, i, -1] - obs[w, i, -2])) / STEP_S, MAX_PACE)
        stride = pace * STEP_S if pace >= STANDING else 0.0
        goal_stride = stride or rng.uniform(*STANDING_PACE) * STEP_S
        angle = rng.uniform(0.0, 2 * np.pi)
        heading = np.array([np.cos(angle), np.sin(angle)], dtype=np.float32)
        side = np.array([-heading[1], heading[0]], dtype=np.float32) * rng.uniform(-PASS_OFFSET, PASS_OFFSET)
        start = future[w, j, step] + side - heading * stride * (step + 1)
        far = rng.integers(max(goal_steps[0], step + 3), max(goal_steps[1], step + 3) + 1)
        picked.append((w, i, j))
        walkers.append(start + heading * stride * np.arange(1 - T_OBS, 1, dtype=np.float32)[:, None])
        goals.append(start + heading * goal_stride * far)
    if not picked:
        return None
    windows, walker, partner = (np.array(x) for x in zip(*picked))
    n = np.arange(len(windows))
    new_obs, new_seen = obs[windows].copy(), seen[windows].copy()
    new_obs[n, walker] = np.stack(walkers)
    new_seen[n, walker] = False
    new_targets = np.zeros_like(mask[windows])
    new_targets[n, walker] = True
    new_mask = new_targets.copy()
    new_mask[n, partner] = rng.random(len(windows)) >= ALONE
    if crowd:  # (drawn only when asked for, so that runs without crowds keep their random stream)
        in_crowd = rng.random(len(windows)) < crowd
        new_mask[in_crowd] = mask[windows[in_crowd]]
    return SceneBatch(
        obs=torch.from_numpy(new_obs),
        future=torch.from_numpy(future[windows]),
        seen=torch.from_numpy(new_seen),
        mask=torch.from_numpy(new_mask),
        targets=torch.from_numpy(new_targets),
        goals=torch.from_numpy(np.stack(goals).astype(np.float32)),
    )
