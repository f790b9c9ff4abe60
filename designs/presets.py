"""The paper's two JMP plans as study specs (Tsai & Oh, section V.B)."""

from __future__ import annotations

from designs.factors import CategoricalFactor, ContinuousFactor, DiscreteFactor, FixedFactor
from designs.spec import StudySpec

PEDESTRIANS = DiscreteFactor("Pedestrians", (2.0, 4.0, 6.0))
DIRECTION = CategoricalFactor("Direction", ("Parallel", "ParallelCrossing", "Crossing"))


def qualitative(runs: int = 27) -> StudySpec:
    """The 27-run qualitative plan: main effects of pedestrians, direction and crossing distance."""
    return StudySpec(
        name="qualitative",
        factors=(PEDESTRIANS, DIRECTION, ContinuousFactor("CrossingDistance", 1.0, 3.0, "m")),
        model="main",
        runs=runs,
    )


def ab(controllers: tuple[str, ...], runs: int = 18) -> StudySpec:
    """The 18-run blinded A/B plan of `controllers` (the paper's: NaviGAN-R against the lattice planner;
    the names come from the caller, which knows the controllers)."""
    return StudySpec(
        name="ab",
        factors=(
            PEDESTRIANS,
            DIRECTION,
            CategoricalFactor("Controller", controllers, blind=True),
            FixedFactor("CrossingDistance", 2.0, "m"),
        ),
        model="main + interactions + Pedestrians^2",
        runs=runs,
    )
