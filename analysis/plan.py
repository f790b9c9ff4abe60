"""The analysis plan a study declares before its first run (study.toml's `[analysis]` table): the outcome, the
compared factor, the primary test and model, alpha, the sensitivity analyses; its defaults for a spec, and its digest.

A randomized comparison of arms defaults to the run-level randomization test (`analysis.randomization`; of more than two
arms, its global form and then every pair, Holm-adjusted: `analysis.k_arm`) with the primary model holding only the arm
factor and the design's blocks, since 18 runs cannot carry the plan's full model as a confirmatory fit; the full design
model stays as an exploratory fit.
"""

from __future__ import annotations

import hashlib
from dataclasses import asdict, dataclass

from analysis.gee_options import GeeOptions
from designs.blinding import canonical_bytes
from designs.factors import BlockFactor, CategoricalFactor
from designs.spec import StudySpec

#: The outcome analysed: each judgment's answer to "socially compliant?" (responses.csv's `compliant`).
OUTCOMES = ("compliant",)
#: Primary tests: the run-level randomization test of the arms, or the small-sample GEE's test of the factor's term.
RANDOMIZATION = "randomization"
GEE = "gee"
TESTS = (RANDOMIZATION, GEE)
#: Sensitivity analyses, each on the primary model: the GEE with small-sample errors and t / F references, the GEE with
#: the independence working correlation, the random-intercept logistic mixed model, Firth's penalized logistic fit.
SENSITIVITY = ("gee-small-sample", "gee-independence", "random-intercept", "firth")
#: The factor an A/B study compares when it names no blinded factor.
ARM_FACTOR = "Controller"
DRAWS = 20_000


@dataclass(frozen=True)
class AnalysisPlan:
    """What the study commits to analyse, and how (see the module docstring; study.toml keys are the field names)."""

    outcome: str
    factor: str
    test: str
    model: str
    strata: tuple[str, ...]
    exploratory: str
    alpha: float
    sensitivity: tuple[str, ...]
    draws: int
    seed: int
    #: The GEE fits' conventions (`analysis.clustered.GeeOptions`): the sandwich's small-sample correction and the
    #: exchangeable correlation's estimator ("geepack" to match R's geeglm).
    gee_covariance: str = "mancl-derouen"
    gee_alpha: str = "statsmodels"

    def gee_options(self, correlation: str = "exchangeable") -> GeeOptions:
        """The GEE options the plan's fits use (`correlation` "independence" for the check fit)."""
        return GeeOptions(covariance=self.gee_covariance, correlation=correlation, alpha_estimator=self.gee_alpha)  # type: ignore[arg-type]

    def describe_test(self) -> str:
        """The primary test in a phrase, e.g. `run-level randomization test of Controller, alpha 0.05`."""
        if self.test == RANDOMIZATION:
            within = f" within {', '.join(self.strata)}" if self.strata else ""
            return f"run-level randomization test of {self.factor}{within}, alpha {self.alpha:g}"
        what = f"the {self.factor} term" if self.factor else "each term"
        return f"small-sample GEE test of {what} in the model {self.model}, alpha {self.alpha:g}"

    def table(self) -> dict[str, object]:
        """The plan as study.toml's `[analysis]` table holds it."""
        return {key: list(value) if isinstance(value, tuple) else value for key, value in asdict(self).items()}

    def digest(self) -> str:
        """What design.json commits to and unblinding.json records (`table_digest` of its table)."""
        return table_digest(self.table())


def table_digest(table: dict[str, object]) -> str:
    """SHA-256 of an [analysis] table as canonical JSON (sorted keys, no spaces, UTF-8)."""
    return hashlib.sha256(canonical_bytes(table)).hexdigest()


def arm_factor(spec: StudySpec) -> CategoricalFactor | None:
    """The factor whose arms the study compares: its blinded factor, else a categorical Controller factor."""
    blind = spec.blind_factor
    if blind is not None:
        return blind
    factor = next((f for f in spec.design_factors if f.name == ARM_FACTOR), None)
    return factor if isinstance(factor, CategoricalFactor) else None


def default_plan(spec: StudySpec, seed: int) -> AnalysisPlan:
    """The plan `trials design` writes for `spec`: an arm study's randomization test on the arm factor plus blocks,
    else the small-sample GEE of the design's model; every sensitivity analysis; alpha from the spec."""
    factor = arm_factor(spec)
    blocks = [f.name for f in spec.design_factors if isinstance(f, BlockFactor)]
    full = spec.full_model
    if factor is None:
        return AnalysisPlan("compliant", "", GEE, full, (), "", spec.alpha, SENSITIVITY, DRAWS, seed)
    return AnalysisPlan("compliant", factor.name, RANDOMIZATION, " + ".join([factor.name, *blocks]), tuple(blocks), full, spec.alpha,
                        SENSITIVITY, DRAWS, seed)


@dataclass(frozen=True)
class PlanStatus:
    """The plan a report analyses by, and whether it is still the one committed to with the design."""

    plan: AnalysisPlan
    #: study.toml has an [analysis] table (else the defaults for its spec, for a study made before plans were declared).
    declared: bool
    #: The digest design.json commits to (None: a design made before plans were committed).
    committed: str | None
    #: The plan digest in force at each opening of the sealed key, oldest first (None: not recorded at that opening).
    opened_with: tuple[str | None, ...] = ()

    @property
    def matches(self) -> bool:
        return self.committed is not None and self.declared and self.committed == self.plan.digest()

    @property
    def changed_after_opening(self) -> bool:
        """The plan now differs from one in force when the key was opened; an opening that recorded none counts when the
        plan is not the committed one (a change after it cannot be ruled out)."""
        current = self.plan.digest()
        recorded_other = any(digest is not None and digest != current for digest in self.opened_with)
        return recorded_other or (not self.matches and None in self.opened_with)

    def describe(self) -> str:
        """The plan's standing in one sentence for the report."""
        digest = self.plan.digest()[:16]
        if self.committed is None:
            source = "study.toml's [analysis] table" if self.declared else "the defaults for this design (study.toml declares no [analysis] table)"
            return f"Analysis plan: {source} (sha256 {digest}...); design.json commits to no plan (a design of an earlier release)."
        if self.matches and not self.changed_after_opening:
            return f"Analysis plan: study.toml's [analysis] table, the one committed to in design.json with the design (sha256 {digest}...)."
        if self.matches:  # committed again (an augmented design) after the key was opened under another plan
            return (f"**The analysis plan changed after the sealed key was opened: the plan in force (sha256 {digest}...) is the one "
                    "design.json commits to now, but not the one in force when the key was opened.** Results below follow the changed plan.")
        what = "study.toml's [analysis] table" if self.declared else "the defaults (study.toml's [analysis] table was removed)"
        text = (f"the analysis plan in force ({what}, sha256 {digest}...) differs from the one committed to in design.json with the "
                f"design (sha256 {self.committed[:16]}...)")
        if self.changed_after_opening:
            recorded = all(d is not None for d in self.opened_with)
            when = ("it was changed after the sealed key was opened" if recorded
                    else "the key was opened before and that opening did not record the plan, so a change after it cannot be ruled out")
            return f"**The analysis plan changed: {text}; {when}.** Results below follow the changed plan."
        when = "before the sealed key was first opened" if self.opened_with else "while the sealed key is closed or the study is not blinded"
        return f"**The analysis plan changed {when}: {text}.** Results below follow the changed plan."
