"""The planner against an independent brute-force Dijkstra over the whole lattice, on small own maps."""

from __future__ import annotations

import heapq
import math

import numpy as np
import pytest

from trials.lattice.environment import cont_to_cell, heading_to_cont, min_angle_diff, read_cfg
from trials.lattice.footprint import footprint_cells
from trials.lattice.husky import husky_primitives
from trials.lattice.planner import make_planner

OBST, INSCRIBED = 10, 8
RECT = [(-0.3, -0.16), (0.3, -0.16), (0.3, 0.16), (-0.3, 0.16)]
START, GOAL = (4, 7, 0), (15, 7, 0)


def write_cfg(path, grid, circumscribed=0, cell_size=0.1):
    """A nav3d .cfg with our thresholds, the start and goal states above, and `grid` (row 0 at y = 0)."""
    def centre(state):
        return f"{(state[0] + 0.5) * cell_size} {(state[1] + 0.5) * cell_size} {heading_to_cont(state[2], 16)}"
    rows = "\n".join(" ".join(str(v) for v in row) for row in grid)
    path.write_text(
        f"discretization(cells): {grid.shape[1]} {grid.shape[0]}\nobsthresh: {OBST}\n"
        f"cost_inscribed_thresh: {INSCRIBED}\ncost_possibly_circumscribed_thresh: {circumscribed}\n"
        f"cellsize(meters): {cell_size}\nnominalvel(mpersecs): 1.0\ntimetoturn45degsinplace(secs): 0.8\n"
        f"start(meters,rads): {centre(START)}\nend(meters,rads): {centre(GOAL)}\nenvironment:\n{rows}\n")
    return path


def random_map(seed: int, width: int = 20, height: int = 14) -> np.ndarray:
    """Obstacle blocks and patches of cost values, kept off the start and the goal."""
    rng = np.random.default_rng(seed)
    grid = np.zeros((height, width), np.uint8)
    for _ in range(5):
        x, y = rng.integers(4, width - 5), rng.integers(0, height - 2)
        grid[y:y + rng.integers(2, 6), x:x + rng.integers(1, 3)] = OBST
    for _ in range(4):
        x, y = rng.integers(0, width - 3), rng.integers(0, height - 3)
        grid[y:y + 3, x:x + 3] = np.maximum(grid[y:y + 3, x:x + 3], rng.integers(1, INSCRIBED))
    for x, y, _ in (START, GOAL):
        grid[y - 3:y + 4, x - 3:x + 4] = 0
    return grid


def brute_force(grid: np.ndarray, prims, polygon, circumscribed: int, cell_size: float, start, goal) -> float:
    """Dijkstra over every (x, y, heading) with the edge rule restated from SBPL's GetActionCost."""
    height, width = grid.shape
    on_map = lambda x, y: 0 <= x < width and 0 <= y < height  # noqa: E731
    moves = {t: [] for t in range(16)}
    for p in prims.primitives:
        length = 0.0
        for (x0, y0), (x1, y1) in zip(p.poses[:-1, :2], p.poses[1:, :2]):
            length += math.sqrt((x1 - x0) ** 2 + (y1 - y0) ** 2)
        turn = min_angle_diff(heading_to_cont(p.end[2], 16), heading_to_cont(p.start_heading, 16))
        base = math.ceil(1000 * max(length / 1.0, turn / ((math.pi / 4) / 0.8))) * p.cost_mult
        centre = {(cont_to_cell(x + cell_size / 2, cell_size), cont_to_cell(y + cell_size / 2, cell_size))
                  for x, y, _ in p.poses}
        swept = set().union(*(footprint_cells(polygon, tuple(q), cell_size) for q in p.poses[1:]))
        swept -= footprint_cells(polygon, tuple(p.poses[0]), cell_size)
        moves[p.start_heading].append((p.end, base, centre, swept))
    best = {start: 0}
    queue = [(0, start)]
    while queue:
        g, (x, y, t) = heapq.heappop(queue)
        if (x, y, t) == goal:
            return g
        if g > best[(x, y, t)] or grid[y, x] >= OBST:
            continue
        for (dx, dy, end_t), base, centre, swept in moves[t]:
            ex, ey = x + dx, y + dy
            if not on_map(ex, ey) or grid[ey, ex] >= OBST or grid[ey, ex] >= INSCRIBED:
                continue
            if not all(on_map(x + cx, y + cy) and grid[y + cy, x + cx] < INSCRIBED for cx, cy in centre):
                continue
            highest = max(grid[y + cy, x + cx] for cx, cy in centre)
            if len(polygon) > 1 and highest >= circumscribed and not all(
                    on_map(x + sx, y + sy) and grid[y + sy, x + sx] < OBST for sx, sy in swept):
                continue
            cost = g + base * (1 + int(max(highest, grid[y, x], grid[ey, ex])))
            if cost < best.get((ex, ey, end_t), math.inf):
                best[(ex, ey, end_t)] = cost
                heapq.heappush(queue, (cost, (ex, ey, end_t)))
    return math.inf


@pytest.mark.parametrize("seed", [0, 1, 4, 6, 7])
@pytest.mark.parametrize("polygon, circumscribed", [([], 0), (RECT, 0), (RECT, 2)],
                         ids=["point", "rectangle", "rectangle-checked-from-2"])
@pytest.mark.slow
def test_optimal_cost_equals_brute_force(tmp_path, seed, polygon, circumscribed):
    env = read_cfg(write_cfg(tmp_path / "map.cfg", random_map(seed), circumscribed))
    prims = husky_primitives(0.1)
    optimum = brute_force(env.grid, prims, polygon, circumscribed, 0.1, START, GOAL)
    planner = make_planner(env, prims, polygon)
    astar = planner.plan(eps=1.0, budget=30.0)
    ara = planner.plan(eps=3.0, eps_step=0.5, budget=30.0)
    if math.isinf(optimum):
        assert astar.status == ara.status == "no_path"
        return
    assert astar.status == "solved" and astar.cost == optimum
    assert ara.iterations[-1].eps == 1.0 and ara.cost == optimum
    assert optimum <= ara.iterations[0].cost <= 3.0 * optimum
    assert sum(planner.edge(a, b)[1] for a, b in zip(ara.states, ara.states[1:])) == optimum


def test_walled_off_goal_has_no_path(tmp_path):
    grid = np.zeros((14, 20), np.uint8)
    grid[:, 12] = OBST  # a wall across the whole map
    env = read_cfg(write_cfg(tmp_path / "wall.cfg", grid))
    prims = husky_primitives(0.1)
    assert brute_force(env.grid, prims, [], 0, 0.1, START, GOAL) == math.inf
    result = make_planner(env, prims, []).plan(budget=30.0)
    assert result.status == "no_path" and result.iterations == []
    assert result.states[0] == START and result.states[-1][0] < 12  # the best partial path stays on its side
