"""An SBPL-like (x, y, theta) lattice planner searched by ARA*, and its trial controller.

Modules, one concern each: `environment` (SBPL nav3d `.cfg` files and grid conventions),
`primitives` (SBPL `.mprim` files), `husky` (the default Husky primitive set), `footprint`
(cells under and swept by the robot polygon), `actions` (precomputed successor tables),
`heuristic` (2-D Dijkstra), `search` (ARA*), `planner` (the three put together), `costmap`
(pedestrians to a cost grid) and `controller` (the `Controller` the trials drive).
"""
