"""The lattice planner on SBPL's own example problems and our pedestrian problems: SBPL's answers."""

from __future__ import annotations

import math

import pytest

from trials.lattice.environment import read_cfg
from trials.lattice.planner import make_planner
from trials.lattice.primitives import read_mprim

#: The 1.0 x 0.7 m rectangle the pedestrian problems were solved with (samples README).
RECTANGLE = [(-0.5, -0.35), (0.5, -0.35), (0.5, 0.35), (-0.5, 0.35)]

#: (environment, primitives, footprint, SBPL's first-solution cost at eps 3, SBPL's eps-1 cost).
SBPL_ANSWERS = [
    ("env1", "pr2", [], 8348, 8348),
    ("ped2_5cm", "unicycle_5cm", RECTANGLE, 36584, 24768),
    ("ped4_5cm", "unicycle_5cm", RECTANGLE, 36584, 25296),
    ("ped6_5cm", "unicycle_5cm", RECTANGLE, 38280, 25296),
    ("ped2_5cm", "unicycle_side_backturn_5cm", RECTANGLE, 21800, 20800),
    ("ped6_5cm", "unicycle_side_backturn_5cm", RECTANGLE, 22000, 21000),
    ("ped2_10cm", "pr2_unicycle_10cm", RECTANGLE, 38543, 23194),
    ("ped6_10cm", "pr2_unicycle_10cm", RECTANGLE, 38543, 23714),
    ("ped2_10cm", "pr2_10cm", RECTANGLE, 29848, 19744),
    ("ped6_10cm", "pr2_10cm", RECTANGLE, 29848, 20266),
]


def _plan(sbpl_dir, env_name, prims_name, footprint):
    env = read_cfg(sbpl_dir / f"{env_name}.cfg")
    planner = make_planner(env, read_mprim(sbpl_dir / f"{prims_name}.mprim"), footprint)
    return planner, planner.plan(eps=3.0, eps_step=0.2, budget=60.0)


@pytest.mark.parametrize("env_name, prims_name, footprint, first_cost, optimal_cost", SBPL_ANSWERS,
                         ids=[f"{e}+{p}" for e, p, *_ in SBPL_ANSWERS])
@pytest.mark.slow
def test_matches_sbpl(sbpl_dir, env_name, prims_name, footprint, first_cost, optimal_cost):
    planner, result = _plan(sbpl_dir, env_name, prims_name, footprint)
    assert result.status == "solved"
    first, last = result.iterations[0], result.iterations[-1]
    assert (last.eps, last.cost) == (1.0, optimal_cost)
    assert result.cost == optimal_cost
    assert first.eps == 3.0 and optimal_cost <= first.cost <= 3.0 * optimal_cost
    assert first.cost == first_cost  # same bookkeeping as SBPL's ARA*, same first solution
    for it in result.iterations:  # every iteration within its own bound, costs never rising
        assert optimal_cost <= it.cost <= it.eps * optimal_cost + 1e-9
    assert [it.cost for it in result.iterations] == sorted((it.cost for it in result.iterations), reverse=True)
    # the path is a chain of valid edges from the start to the goal whose costs add up to the cost
    env = planner.env
    assert result.states[0] == env.to_state(env.start) and result.states[-1] == env.to_state(env.goal)
    assert sum(planner.edge(a, b)[1] for a, b in zip(result.states, result.states[1:])) == optimal_cost
    x0, y0, _ = env.to_pose(result.states[0])
    assert result.poses[0, :2] == pytest.approx([x0, y0])
    assert result.poses[-1, :2] == pytest.approx(env.to_pose(result.states[-1])[:2])
    assert math.isclose(result.times[-1], sum(planner.actions.seconds[h, a] for h, a in result.actions))


def test_search_is_reused_between_calls(sbpl_dir):
    """A second plan on the same planner (reused state arrays) gives the same answer."""
    planner, first = _plan(sbpl_dir, "ped6_10cm", "pr2_10cm", RECTANGLE)
    again = planner.plan(eps=3.0, eps_step=0.2, budget=60.0)
    assert [(i.eps, i.cost, i.expansions) for i in again.iterations] == \
        [(i.eps, i.cost, i.expansions) for i in first.iterations]
    assert again.states == first.states


def test_plain_astar_gives_the_optimum(sbpl_dir):
    """Epsilon 1 from the start is plain A*: the same optimal cost in one iteration."""
    planner = make_planner(read_cfg(sbpl_dir / "ped2_10cm.cfg"), read_mprim(sbpl_dir / "pr2_10cm.mprim"), RECTANGLE)
    result = planner.plan(eps=1.0, budget=60.0)
    assert [(i.eps, i.cost) for i in result.iterations] == [(1.0, 19744)]
