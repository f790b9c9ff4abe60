"""The closed-loop simulator of a field trial, one concern per module.

`social_force` (Helbing & Molnar's pedestrians), `pedestrians` (who walks where and when, from a
scenario), `robot` (the Husky-like differential drive and its footprint), `follower` (way-points
to velocity commands), `perception` (what the controller is told) and `closed_loop` (the loop).
"""
