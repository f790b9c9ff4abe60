"""Bad input to the lattice planner: malformed SBPL files, impossible requests, budgets."""

from __future__ import annotations

import numpy as np
import pytest

from trials.cli import USER_ERRORS
from trials.lattice.actions import build_actions
from trials.lattice.environment import read_cfg
from trials.lattice.errors import LatticeError
from trials.lattice.husky import husky_primitives
from trials.lattice.planner import make_planner
from trials.lattice.primitives import read_mprim

HEADER = """discretization(cells): 4 3
obsthresh: 1
cost_inscribed_thresh: 1
cost_possibly_circumscribed_thresh: 0
cellsize(meters): 0.1
nominalvel(mpersecs): 1.0
timetoturn45degsinplace(secs): 2.0
start(meters,rads): 0.05 0.05 0
end(meters,rads): 0.35 0.25 0
environment:
"""
MAP = "0 0 0 0\n0 1 0 0\n0 0 0 0\n"

MPRIM = """resolution_m: 0.1
numberofangles: 2
totalnumberofprimitives: 2
primID: 0
startangle_c: 0
endpose_c: 1 0 0
additionalactioncostmult: 1
intermediateposes: 2
0.0 0.0 0.0
0.1 0.0 0.0
primID: 1
startangle_c: 1
endpose_c: -1 0 1
additionalactioncostmult: 1
intermediateposes: 2
0.0 0.0 3.141592653589793
-0.1 0.0 3.141592653589793
"""
FIRST_PRIM = MPRIM[MPRIM.index("primID: 0"):MPRIM.index("primID: 1")]


def test_well_formed_fixtures_read(tmp_path):
    (tmp_path / "ok.cfg").write_text(HEADER + MAP)
    env = read_cfg(tmp_path / "ok.cfg")
    assert (env.width, env.height, env.num_thetas) == (4, 3, 16)
    assert env.grid.tolist() == [[0, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 0]]  # row 0 is y = 0
    assert env.to_state(env.start) == (0, 0, 0) and env.to_state(env.goal) == (3, 2, 0)
    (tmp_path / "ok.mprim").write_text(MPRIM)
    prims = read_mprim(tmp_path / "ok.mprim")
    assert (prims.resolution, prims.num_angles, prims.per_heading) == (0.1, 2, 1)
    assert prims.primitives[0].end == (1, 0, 0) and prims.primitives[0].poses.shape == (2, 3)


@pytest.mark.parametrize("text, where, expected", [
    ("discretisation(cells): 4 3\n", "line 1", 'expected "discretization(cells):", got "discretisation(cells):"'),
    (HEADER.replace(" 4 3", " 4.5 3") + MAP, "line 1", "expected the map width in cells (an integer >= 1)"),
    (HEADER.replace("obsthresh: 1", "obsthresh: 300") + MAP, "line 2", "the obstacle threshold (an integer in 0..255)"),
    (HEADER.replace("cellsize(meters): 0.1", "cellsize(meters): -0.1") + MAP, "line 5",
     "the cell size in metres (a positive number)"),
    (HEADER.replace("start(meters,rads): 0.05 0.05 0", "start(meters,rads): 0.05 zero 0") + MAP, "line 8",
     'the start y (a number), got "zero"'),
    (HEADER + "0 0 0 0\n0 x 0 0\n0 0 0 0\n", "line 12", 'value 1 of map row 1 (3 rows of 4 cell values)'
     ' (an integer in 0..255), got "x"'),
    (HEADER + "0 0 0 0\n0 0 0 0\n0 0 256 0\n", "line 13", "value 2 of map row 2"),
    (HEADER + "0 0 0 0\n0 0 0 0\n", "line 12", "value 0 of map row 2 (3 rows of 4 cell values) (an integer in "
     "0..255), got the end of the file"),
    (HEADER + MAP + "0\n", "line 14", 'expected the end of the file after 3 map rows of 4 values, got "0"'),
])
def test_malformed_cfg_names_file_line_and_expectation(tmp_path, text, where, expected):
    path = tmp_path / "bad.cfg"
    path.write_text(text)
    with pytest.raises(LatticeError) as err:
        read_cfg(path)
    assert str(err.value).startswith(f"bad.cfg, {where}: ")
    assert expected in str(err.value)
    assert isinstance(err.value, USER_ERRORS)  # the CLI's user-error family


def test_missing_file_is_a_lattice_error(tmp_path):
    with pytest.raises(LatticeError, match="cannot read .*nothing.cfg"):
        read_cfg(tmp_path / "nothing.cfg")


@pytest.mark.parametrize("edit, where, expected", [
    (lambda t: t.replace("resolution_m:", "resolution:"), "line 1", 'expected "resolution_m:"'),
    (lambda t: t.replace("numberofangles: 2", "min_turning_radius_m: 0.2"), "line 2",
     "non-uniform angle primitives are not supported"),
    (lambda t: t.replace("startangle_c: 1", "startangle_c: 2"), "line 12",
     "the start angle index (an integer in 0..1)"),
    (lambda t: t.replace("additionalactioncostmult: 1", "additionalactioncostmult: 0", 1), "line 7",
     "the cost multiplier (an integer >= 1)"),
    (lambda t: t.replace("intermediateposes: 2", "intermediateposes: 0", 1), "line 8",
     "the number of intermediate poses (an integer >= 1)"),
    (lambda t: t.replace("0.1 0.0 0.0", "0.2 0.0 0.0", 1), "line 6",
     "primitive 0 of angle 0: its last pose (0.2, 0, 0) lies in cell (2, 0, 0), not in its end pose (1, 0, 0)"),
    (lambda t: t.replace(MPRIM[MPRIM.index("primID: 1"):], ""), "line 10",
     'expected "primID:", got the end of the file'),
])
def test_malformed_mprim_names_file_line_and_expectation(tmp_path, edit, where, expected):
    path = tmp_path / "bad.mprim"
    path.write_text(edit(MPRIM))
    with pytest.raises(LatticeError) as err:
        read_mprim(path)
    assert str(err.value).startswith(f"bad.mprim, {where}: ")
    assert expected in str(err.value)


def test_unequal_primitive_counts_per_heading_are_refused(tmp_path):
    text = MPRIM.replace("totalnumberofprimitives: 2", "totalnumberofprimitives: 3") + FIRST_PRIM
    (tmp_path / "uneven.mprim").write_text(text)  # heading 0 has two primitives, heading 1 one
    with pytest.raises(LatticeError, match=r"every heading needs the same number of primitives, got \[2, 1\]"):
        read_mprim(tmp_path / "uneven.mprim")


def test_primitives_must_fit_the_environment(tmp_path):
    (tmp_path / "ok.cfg").write_text(HEADER + MAP)
    env = read_cfg(tmp_path / "ok.cfg")
    with pytest.raises(LatticeError, match="resolution 0.05 m does not match the environment's cell size 0.1 m"):
        build_actions(husky_primitives(0.05), env, [])
    (tmp_path / "two.mprim").write_text(MPRIM)
    with pytest.raises(LatticeError, match="the primitives have 2 angles but the environment has 16 headings"):
        build_actions(read_mprim(tmp_path / "two.mprim"), env, [])


def _open_planner(width=30, height=20, polygon=()):
    from trials.lattice.environment import Environment
    env = Environment(grid=np.zeros((height, width), np.uint8), cell_size=0.1, obsthresh=1,
                      cost_inscribed_thresh=1, cost_possibly_circumscribed_thresh=0,
                      time_to_turn_45=0.8, start=(0.55, 1.05, 0.0), goal=(2.55, 1.05, 0.0))
    return make_planner(env, husky_primitives(0.1), list(polygon))


@pytest.mark.parametrize("start, goal, status, words", [
    ((-1, 10, 0), (25, 10, 0), "start_outside_map", "the start cell (-1, 10) is outside the 30 x 20 map"),
    ((5, 10, 0), (30, 10, 0), "goal_outside_map", "the goal cell (30, 10) is outside"),
    ((5, 10, 0), (25, 1, 0), "goal_in_collision", "the footprint leaves the map"),
])
def test_impossible_requests_get_a_status_not_an_exception(start, goal, status, words):
    planner = _open_planner(polygon=[(-0.3, -0.2), (0.3, -0.2), (0.3, 0.2), (-0.3, 0.2)])
    result = planner.plan(start, goal)
    assert result.status == status and words in result.message
    assert result.states == [] and result.poses.shape == (0, 3) and not result.reached_goal


def test_start_on_an_obstacle_is_in_collision():
    planner = _open_planner()
    grid = planner.env.grid.copy()
    grid[10, 5] = 1
    planner.set_grid(grid)
    result = planner.plan((5, 10, 0), (25, 10, 0))
    assert result.status == "start_in_collision" and "its cell (5, 10) has cost 1" in result.message


@pytest.mark.slow
def test_budget_spent_before_the_goal_gives_the_best_partial_path(sbpl_dir):
    planner = make_planner(read_cfg(sbpl_dir / "ped6_5cm.cfg"), read_mprim(sbpl_dir / "unicycle_5cm.mprim"),
                           [(-0.5, -0.35), (0.5, -0.35), (0.5, 0.35), (-0.5, 0.35)])
    full = planner.plan(eps=1.0, budget=60.0)  # plain A*: about 150 000 expansions
    cap = full.expansions // 10
    result = planner.plan(eps=1.0, budget=60.0, max_expansions=cap)
    assert result.status == "partial" and f"no path to the goal within 60 s or {cap} expansions" in result.message
    assert result.iterations == [] and result.expansions == cap
    start, nearest = result.states[0], result.states[-1]
    assert start == (20, 100, 0) and nearest[0] > start[0] + 10  # on its way towards x = 380
    assert len(result.poses) > 1 and result.cost > 0


def test_a_deadline_already_past_stops_at_the_first_clock_reading(sbpl_dir):
    """The wall-clock budget without timing the test: a deadline that has passed before the search
    starts ends it before its first expansion, with the start as the path."""
    planner = make_planner(read_cfg(sbpl_dir / "ped6_5cm.cfg"), read_mprim(sbpl_dir / "unicycle_5cm.mprim"),
                           [(-0.5, -0.35), (0.5, -0.35), (0.5, 0.35), (-0.5, 0.35)])
    result = planner.plan(eps=1.0, budget=1e-9)
    assert result.status == "partial" and "no path to the goal within 1e-09 s;" in result.message
    assert result.expansions == 0 and result.states == [(20, 100, 0)]


@pytest.mark.slow
def test_budget_cut_after_a_first_solution_keeps_it(sbpl_dir):
    planner = make_planner(read_cfg(sbpl_dir / "ped6_5cm.cfg"), read_mprim(sbpl_dir / "unicycle_5cm.mprim"),
                           [(-0.5, -0.35), (0.5, -0.35), (0.5, 0.35), (-0.5, 0.35)])
    full = planner.plan(budget=60.0)
    # an expansion budget that the first iteration (eps 3) spends exactly
    cut = planner.plan(budget=60.0, max_expansions=full.iterations[0].expansions)
    assert full.eps == 1.0 and len(full.iterations) > 1
    assert cut.status == "solved" and cut.eps == 3.0 and cut.expansions == full.iterations[0].expansions
    assert cut.cost == full.iterations[0].cost <= 3.0 * full.cost
    assert cut.states[-1] == (380, 100, 0)
