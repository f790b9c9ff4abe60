"""Model-based power, as skpr does it by Monte Carlo: data drawn from anticipated effects on the plan's
model terms, each data set analysed as `trials report` does (`trials.power.verdicts`).

- Judgments (binary): on the logit scale. As skpr converts a binomial effect size, the shares
  (low, high) set the intercept to the mean of their logits and every anticipated column to
  +-c (logit(high) - logit(low)) / 2 (JMP's alternating signs, c the term's anticipated coefficient
  from the spec, default 1); terms outside `terms` get 0. Each run adds its own N(0, run_sd^2) on the
  logit scale (the between-run variance) and has `participants` judgments (default: one per pedestrian).
- A continuous outcome (Gaussian, sigma 1): the coefficients design.json's analytic power assumes
  (snr included), so its power agrees with that figure within Monte Carlo error.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import expit, logit
from threadpoolctl import threadpool_limits

from analysis.plan import AnalysisPlan
from designs.diagnostics import anticipated_coefficients
from designs.spec import StudySpec
from trials.errors import StudyError
from trials.power.plans import PowerPlan
from trials.power.seeds import derived
from trials.power.summary import PowerEstimate, estimate
from trials.power.verdicts import Verdict, gaussian_verdict, judgments_verdict, planned_p


@dataclass(frozen=True)
class Anticipated:
    """What the model-based simulation assumes: the shares whose logits span each effect, the
    between-run standard deviation on the logit scale, judgments per run, and the terms with an effect."""

    low: float = 0.5
    high: float = 0.8
    run_sd: float = 0.5
    participants: int | None = None
    terms: tuple[str, ...] | None = None

    def describe(self) -> str:
        who = f"{self.participants} participants a run" if self.participants else "one participant per pedestrian"
        which = ", ".join(self.terms) if self.terms else "every term"
        return (f"shares {self.low:g} to {self.high:g} (logit scale) on {which}; between-run SD {self.run_sd:g} on the logit scale; {who}")


@dataclass(frozen=True)
class Coefficients:
    """The coefficients of one plan's model columns: on the logit scale for judgments, and for the Gaussian outcome."""

    logit: np.ndarray
    gaussian: np.ndarray


def coefficients(plan: PowerPlan, spec: StudySpec, anticipated: Anticipated) -> Coefficients:
    """The anticipated coefficients of `plan`'s columns under `spec`'s [anticipated] table.

    Raises:
        StudyError: a term named in `anticipated.terms` that the model lacks.
    """
    names = plan.model.term_names
    unknown = [t for t in anticipated.terms or () if t not in names[1:]]
    if unknown:
        raise StudyError(f"--terms: {unknown[0]!r} is not a term of the study's model (terms: {', '.join(names[1:])})")
    signs = anticipated_coefficients(plan.model, 1.0, spec.anticipated)
    half = (logit(anticipated.high) - logit(anticipated.low)) / 2.0
    on = np.zeros(plan.model.p, dtype=bool)
    for name, columns in zip(names, plan.model.term_slices):
        on[columns] = name != "Intercept" and (anticipated.terms is None or name in anticipated.terms)
    slopes = np.where(on, signs * half, 0.0)
    slopes[0] = (logit(anticipated.high) + logit(anticipated.low)) / 2.0
    gaussian = anticipated_coefficients(plan.model, spec.snr, spec.anticipated)
    gaussian[0] = 0.0
    return Coefficients(slopes, np.where(on | (np.arange(plan.model.p) == 0), gaussian, 0.0))


def judgments_per_run(plan: PowerPlan, participants: int | None) -> np.ndarray:
    """Judgments per run: `participants`, else one per pedestrian (at least one)."""
    if participants is not None:
        return np.full(plan.runs, participants)
    return np.maximum(np.array(plan.pedestrians()), 1)


def draw(plan: PowerPlan, beta: Coefficients, anticipated: Anticipated, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One data set of the plan: yes and total judgments per run, and the Gaussian outcome per run."""
    x = plan.model.matrix(plan.settings)
    total = judgments_per_run(plan, anticipated.participants)
    chance = expit(x @ beta.logit + rng.normal(0.0, anticipated.run_sd, plan.runs))
    yes = rng.binomial(total, chance)
    return yes.astype(float), total.astype(float), x @ beta.gaussian + rng.standard_normal(plan.runs)


def simulate(plan: PowerPlan, beta: Coefficients, anticipated: Anticipated, seed: int,
             analysis: AnalysisPlan | None = None) -> tuple[Verdict, Verdict]:
    """One seeded data set of the plan, analysed (with `analysis`, by its primary test too): (judgments' verdict,
    Gaussian outcome's verdict)."""
    yes, total, y = draw(plan, beta, anticipated, np.random.default_rng(seed))
    return judgments_verdict(plan, yes, total, analysis=analysis), gaussian_verdict(plan, y)


def planned_power(plan: PowerPlan, spec: StudySpec, analysis: AnalysisPlan, anticipated: Anticipated, power_seed: int,
                  simulations: int) -> PowerEstimate:
    """The power of the planned primary test alone, on the very data sets `trials power` draws with the same power seed
    (so the two agree exactly), without the other analyses: fast enough for `trials design` to print."""
    beta = coefficients(plan, spec, anticipated)
    p_values = []
    # Many small matrix products: threads of the BLAS only get in each other's way (six times slower on a busy machine).
    with threadpool_limits(1):
        for index in range(simulations):
            yes, total, _ = draw(plan, beta, anticipated, np.random.default_rng(simulation_seed(power_seed, plan, index)))
            p_values.append(planned_p(plan, analysis, yes, total))
    return estimate(p_values, analysis.alpha)


def simulation_seed(power_seed: int, plan: PowerPlan, index: int) -> int:
    return derived(power_seed, "model-based", plan.runs, index)
