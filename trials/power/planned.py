"""The power of a study's planned primary test, as `trials design` prints it: model-based on `trials power`'s own
data sets (same power seed, same draws, so `trials power` gives the same figures), at the plan's size and, when
asked, at multiples of it until the target is reached."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from designs.spec import MAX_RUNS
from trials.analysis_plan import plan_in_force
from trials.power.plans import designed_plan, own_plan, study_spec
from trials.study import SPEC, StudyFolder

if TYPE_CHECKING:
    from trials.power.model_based import Anticipated
    from trials.power.summary import PowerEstimate

#: Data sets per plan size that `trials design` simulates by default, and the most plan sizes it tries.
SIMULATIONS = 200
MULTIPLES = 4
#: Fewest data sets per plan size from which the runs needed are stated: with fewer, the power's Wilson interval is wider
#: than about +-0.1 and a plan size may seem to reach the target by chance (one data set gives power 0 or 1).
MIN_FOR_NEEDED = 100


@dataclass(frozen=True)
class PlannedPower:
    """The planned test's power at each plan size tried, the fewest runs reaching `target` (None: none tried did)."""

    test: str
    assumed: str
    seed: int
    simulations: int
    target: float
    powers: dict[int, PowerEstimate]
    needed: int | None
    #: Whether larger plans were tried (`trials design --power N`).
    searched: bool = True

    def lines(self) -> list[str]:
        sizes = ",".join(map(str, self.powers))
        if self.simulations < MIN_FOR_NEEDED:
            found = (f"not stated from {self.simulations} data sets per plan size (at least {MIN_FOR_NEEDED} are needed for the "
                     "power's interval to be narrow enough)")
        elif self.needed is not None:
            found = f"{self.needed}"
        elif self.searched:
            found = f"more than {max(self.powers)}"
        else:
            found = f"more than {max(self.powers)}; `trials design --power {self.simulations}` tries plans up to {MULTIPLES} times as large"
        return [f"Power of the planned primary test ({self.test}), model-based with {self.simulations} simulated data sets:",
                *(f"  {runs} runs  power {p.power:.3f} (Wilson 95 % {p.low:.3f}-{p.high:.3f}){p.untested_text()}" for runs, p in self.powers.items()),
                f"  runs needed for power {self.target:g}: {found}",
                f"  assumed {self.assumed}; power seed {self.seed} (`trials power --seed {self.seed} --simulations {self.simulations} "
                f"--runs {sizes}` draws the same data sets)"]

    def record(self) -> dict[str, object]:
        return {"test": self.test, "assumed": self.assumed, "power_seed": self.seed, "simulations": self.simulations,
                "target": self.target, "needed_runs": self.needed, "searched": self.searched,
                "power": {str(runs): {"power": p.power, "low": p.low, "high": p.high, "untested": p.untested} for runs, p in self.powers.items()}}


def planned_test_power(folder: StudyFolder, seed: int, simulations: int = SIMULATIONS, search: bool = True, target: float = 0.8,
                       anticipated: Anticipated | None = None) -> PlannedPower | None:
    """The planned test's power at the study's plan size and, with `search`, at 2, 3, ... times it until `target` is
    reached (at most MULTIPLES sizes); None when the plan compares no factor's arms. Larger plans are designed from the
    spec as `trials power --runs` designs them. `anticipated`: by default `trials power`'s, so that its figures and these
    agree."""
    spec, _ = study_spec(folder)
    analysis, _ = plan_in_force(folder.path(SPEC), spec, folder.read_design())
    if not analysis.factor:
        return None
    # The simulation's statistics (statsmodels, scipy.stats) load only for a plan that compares arms.
    from trials.power.model_based import Anticipated, planned_power

    anticipated = anticipated or Anticipated()
    own = own_plan(folder)
    powers: dict[int, PowerEstimate] = {}
    for multiple in range(1, (MULTIPLES if search else 1) + 1):
        runs = own.runs * multiple
        if runs > MAX_RUNS:
            break
        plan = own if multiple == 1 else designed_plan(folder, runs, seed)
        powers[runs] = planned_power(plan, spec, analysis, anticipated, seed, simulations)
        if powers[runs].power >= target:
            break
    needed = next((runs for runs, p in powers.items() if p.power >= target), None) if simulations >= MIN_FOR_NEEDED else None
    return PlannedPower(analysis.describe_test(), anticipated.describe(), seed, simulations, target, powers, needed, search)
