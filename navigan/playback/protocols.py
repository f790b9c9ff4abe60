"""The playback protocols by name, and the default: a module without imports, so the CLI can offer them
without loading torch.

A protocol fixes three things the paper's numbers depend on: which pedestrians become targets (a target
rule, `navigan.playback.episodes`), where the distances behind C and S are measured
(`navigan.playback.metrics`), and what goal the networks are handed (`navigan.playback.rollout`).
"""

from __future__ import annotations

from dataclasses import dataclass

#: Target rules. PRESENT: present for T_OBS + 36 consecutive frames, the goal its position 36 steps
#: ahead. OBSERVED: present for T_OBS + T_PRED, the goal its last position if it leaves sooner.
PRESENT, OBSERVED = "present", "observed"
#: Distances at the recorded frames only, or the closest approach within each step, both moving straight.
FRAMES, INTERPOLATED = "frames", "interpolated"
#: Sub-goals at each target's recorded pace (`Episodes.pace`), not at one speed for all.
RECORDED = "recorded"


@dataclass(frozen=True)
class Protocol:
    """One way of running the playback.

    Attributes:
        name: how `--protocol` names it.
        targets: the target rule, PRESENT or OBSERVED.
        distances: FRAMES or INTERPOLATED.
        subgoal_speed: the pace of the sub-goal handed to the networks, RECORDED or m/s; None hands
            them the episode's goal itself.
    """

    name: str
    targets: str
    distances: str
    subgoal_speed: float | str | None


#: As the paper's text states it: targets with a recorded position 36 steps ahead, distances at the
#: recorded frames, the far goal handed to the networks.
PAPER = Protocol("paper", PRESENT, FRAMES, None)
#: Stricter: every pedestrian present for 20 frames, the closest approach within each step, a sub-goal
#: 12 steps ahead at the recorded pace (the networks were trained with goals that far ahead).
STRICT = Protocol("strict", OBSERVED, INTERPOLATED, RECORDED)
PROTOCOLS: dict[str, Protocol] = {p.name: p for p in (PAPER, STRICT)}
#: The default: the stricter measurement, whose targets closed-loop and evasion training also walk.
DEFAULT_PROTOCOL = STRICT.name


def target_rule(name: str) -> str:
    """The target rule of a protocol named `name`, or `name` itself when it is a target rule."""
    return PROTOCOLS[name].targets if name in PROTOCOLS else name
