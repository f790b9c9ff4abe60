"""Long-term playback navigation (NaviGAN paper, section V.A, Table I).

Each model walks as one recorded pedestrian of a test scene toward where that pedestrian was
14.4 s later, among the other pedestrians as recorded; the episodes are scored for social
score S, comfort rate C and arrival rate A, and a Table I is written.
"""
