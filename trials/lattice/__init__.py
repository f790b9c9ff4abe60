"""An SBPL-like (x, y, theta) lattice planner searched by ARA*: a library of its own.

Modules, one concern each: `environment` (SBPL nav3d `.cfg` files and grid conventions),
`primitives` (SBPL `.mprim` files, read through `tokens`), `husky` (the default Husky primitive
set), `footprint` (cells under and swept by the robot polygon), `actions` (precomputed successor
tables), `grid` (the padded flat grid the kernels search), `compiled` (how the kernels compile),
`heap` and `heuristic` (2-D Dijkstra), `search` (ARA*), `planner` (the three put together),
`costmap` (pedestrians to a cost grid), `crowd` (receding-horizon planning among moving
pedestrians), `cli` (its command) and `errors`.

It imports nothing else of `trials`: the trials reach it through `trials.controllers.lattice`.
"""
