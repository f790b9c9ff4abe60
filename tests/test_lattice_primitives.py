"""Motion primitives: SBPL's files as read, their action costs, and the generated Husky set."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robot_logs.physical import ROBOT_FOOTPRINT
from trials.lattice.actions import action_seconds, base_cost, build_actions, centre_cells
from trials.lattice.environment import Environment, heading_to_cont, read_cfg
from trials.lattice.husky import husky_primitives
from trials.lattice.primitives import end_mismatch, read_mprim


@pytest.mark.parametrize("name, resolution, per_heading", [
    ("pr2", 0.025, 7), ("pr2_10cm", 0.1, 16), ("pr2_unicycle_10cm", 0.1, 5), ("unicycle_5cm", 0.05, 5),
    ("unicycle_side_backturn_5cm", 0.05, 11)])
def test_sbpl_primitive_files_read(sbpl_dir, name, resolution, per_heading):
    prims = read_mprim(sbpl_dir / f"{name}.mprim")
    assert (prims.resolution, prims.num_angles, prims.per_heading) == (resolution, 16, per_heading)
    for p in prims.primitives:
        assert end_mismatch(p, resolution, 16) is None
        assert ((0 <= p.poses[:, 2]) & (p.poses[:, 2] <= 2 * math.pi)).all()


def test_sbpl_action_costs(sbpl_dir):
    env = read_cfg(sbpl_dir / "ped2_5cm.cfg")  # 1 m/s, 2 s per 45 degrees in place
    by_end = {p.end: p for p in read_mprim(sbpl_dir / "unicycle_side_backturn_5cm.mprim").for_heading(0)}
    assert base_cost(by_end[(1, 0, 0)], env) == 50            # 0.05 m at 1 m/s
    assert base_cost(by_end[(8, 0, 0)], env) == 400
    assert base_cost(by_end[(-1, 0, 0)], env) == 50 * 5       # backward, multiplier 5
    assert base_cost(by_end[(0, 0, 1)], env) == 1000          # 22.5 degrees in place: 1 s
    assert base_cost(by_end[(8, 1, 1)], env) == 1000 * 3      # the turn (1 s) outlasts the 0.4 m; x3
    centre = centre_cells(by_end[(8, 1, 1)], 0.05)
    assert centre[0].tolist() == [0, 0] and centre[-1].tolist() == [8, 1]
    assert (np.abs(np.diff(centre, axis=0)) <= 1).all() and len(np.unique(centre, axis=0)) == len(centre)


@pytest.mark.parametrize("cell_size, scale", [(0.1, 1), (0.05, 2)])
def test_husky_set(cell_size, scale):
    prims = husky_primitives(cell_size)
    assert (prims.num_angles, prims.per_heading, prims.resolution) == (16, 9, cell_size)
    heading0 = {p.end: p.cost_mult for p in prims.for_heading(0)}
    assert heading0 == {(1, 0, 0): 1, (8 * scale, 0, 0): 1, (-1, 0, 0): 5,
                        (8 * scale, scale, 1): 2, (8 * scale, -scale, 15): 2,
                        (4 * scale, scale, 1): 2, (4 * scale, -scale, 15): 2, (0, 0, 1): 3, (0, 0, 15): 3}
    for p in prims.primitives:
        assert end_mismatch(p, cell_size, 16) is None
        assert np.hypot(*np.diff(p.poses[:, :2], axis=0).T).max() <= cell_size + 1e-9  # no cell skipped
        start = heading_to_cont(p.start_heading, 16)
        assert math.isclose(p.poses[0, 2], start) and p.poses[0, :2].tolist() == [0.0, 0.0]
        turn = np.unwrap(p.poses[:, 2])
        assert (np.diff(turn) >= -1e-9).all() or (np.diff(turn) <= 1e-9).all()  # turns one way only


def test_husky_set_is_symmetric():
    """Rotations by 90 degrees and mirror images take the same times: no direction is favoured.
    (Integer costs may still differ by a millisecond per multiplier unit where SBPL's ceil meets a
    float a hair above an integer, e.g. 0.4000000000000001 s for turning from heading 0 to 15.)"""
    env = Environment(grid=np.zeros((1, 1), np.uint8), cell_size=0.1, time_to_turn_45=0.8)
    prims = husky_primitives(0.1)
    times = {t: sorted(action_seconds(p, env) for p in prims.for_heading(t)) for t in range(16)}
    costs = {t: sorted(base_cost(p, env) for p in prims.for_heading(t)) for t in range(16)}
    for t in range(16):
        assert times[t] == pytest.approx(times[t % 4]) and times[t] == pytest.approx(times[(4 - t % 4) % 4])
        assert np.abs(np.subtract(costs[t], costs[t % 4])).max() <= 3


def test_husky_tables_for_the_husky_footprint():
    env = Environment(grid=np.zeros((1, 1), np.uint8), cell_size=0.1, time_to_turn_45=0.8)
    actions = build_actions(husky_primitives(0.1), env, ROBOT_FOOTPRINT)
    assert actions.cost.shape == (16, 9) and actions.use_footprint
    # turning in place sweeps the corners: a 0.99 x 0.67 m box turned 22.5 degrees
    turn = next(a for a, p in enumerate(actions.primitives[0]) if p.end == (0, 0, 1))
    swept = actions.swept[actions.swept_ptr[turn]:actions.swept_ptr[turn + 1]]
    assert len(swept) > 0 and np.abs(swept).max() <= 6 and actions.reach >= 8
