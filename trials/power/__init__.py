"""`trials power`: how likely a study's plan is to show an effect, by model-based and closed-loop simulation.

`plans` the plans to test (the study's own, or D-optimal ones of other sizes), `seeds` every seed
from the one power seed, `verdicts` one data set analysed as `trials report` does, `model_based`
data drawn from anticipated effects, `closed_loop` whole simulated campaigns, `execution` running
campaigns in local processes or on a Ray cluster, `campaigns` the power.csv file of finished
campaigns, `summary` power.json and power.md, `figure` the power figure.
"""
