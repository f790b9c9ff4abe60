"""The analysis plan of a study: study.toml's `[analysis]` table, checked key by key (`analysis.plan.AnalysisPlan`).

`trials design` writes the table with the defaults for its spec (a table the spec already has is kept, checked) and
commits to it in design.json (`commitment`); `trials report` analyses by it and says whether it still matches. Every
key is optional; a missing one takes its default:

    [analysis]
    outcome = "compliant"          # each judgment's answer to "socially compliant?"
    factor = "Controller"          # the factor whose arms are compared ("" for none)
    test = "randomization"         # or "gee": the primary test of the factor
    model = "Controller"           # the primary model: the factor and the design's blocks
    strata = []                    # factors the arm labels are re-randomized within (the blocks: ["Block"])
    exploratory = "main + interactions + Pedestrians^2"   # the design's full model, an exploratory fit ("" for none)
    alpha = 0.05
    sensitivity = ["gee-small-sample", "gee-independence", "random-intercept", "firth"]
    draws = 20000                  # Monte Carlo draws when the allocations are too many to enumerate
    seed = 7                       # their seed (default: the design's seed)
    gee_covariance = "mancl-derouen"   # or "kauermann-carroll": the GEE sandwich's small-sample correction
    gee_alpha = "statsmodels"      # or "geepack": the exchangeable correlation's estimate as R's geeglm makes it
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from analysis.gee_options import ALPHA_ESTIMATORS, COVARIANCES
from analysis.plan import OUTCOMES, RANDOMIZATION, SENSITIVITY, TESTS, AnalysisPlan, PlanStatus, default_plan, table_digest
from designs.errors import DesignError
from designs.factors import CategoricalFactor, DiscreteFactor
from designs.model import parse_model
from designs.spec import StudySpec
from trials.errors import StudyError
from trials.study import study_table

#: The study.toml table this module reads.
TABLE = "analysis"
KEYS = ("outcome", "factor", "test", "model", "strata", "exploratory", "alpha", "sensitivity", "draws", "seed", "gee_covariance", "gee_alpha")
MAX_DRAWS = 200_000  # the drawn allocations are held at once: 8 bytes per run and draw
MAX_SEED = 2**63 - 1  # as study.toml's [study] seed, which the default copies


def read_analysis_plan(spec_path: Path, spec: StudySpec, seed: int) -> AnalysisPlan | None:
    """The plan study.toml declares (missing keys at their defaults for `spec`, `seed` the default seed), None
    when it has no [analysis] table.

    Raises:
        StudyError: a malformed file, an unknown key or a bad value, naming the file, table and key.
    """
    table = study_table(spec_path, TABLE)
    return None if table is None else plan_from_table(table, spec, seed, f"{spec_path} [{TABLE}]")


def analysis_table(spec_path: Path | None, spec: StudySpec, seed: int) -> dict[str, Any]:
    """The [analysis] table `trials design` writes: the spec file's own, checked and completed, else the defaults."""
    plan = read_analysis_plan(spec_path, spec, seed) if spec_path is not None else None
    return (plan or default_plan(spec, seed)).table()


def plan_from_table(table: dict[str, Any], spec: StudySpec, seed: int, where: str) -> AnalysisPlan:
    """An AnalysisPlan from a table's keys, each checked against `spec`; StudyError names `where` and the key."""
    unknown = sorted(set(table) - set(KEYS))
    if unknown:
        raise StudyError(f"{where}: unknown key {unknown[0]!r} (expected {', '.join(KEYS)})")
    values = {**default_plan(spec, seed).table(), **table}
    fixed = tuple(f.name for f in spec.fixed_factors)
    names = [f.name for f in spec.design_factors]

    def text(key: str, allowed: tuple[str, ...] | None = None) -> str:
        value = values[key]
        if not isinstance(value, str) or (allowed is not None and value not in allowed):
            expected = f"one of {', '.join(repr(a) for a in allowed)}" if allowed else "a text"
            raise StudyError(f"{where}: {key} must be {expected}, got {value!r}")
        return value

    def model(key: str) -> list[str]:
        expression = text(key)
        try:
            return parse_model(expression, spec.design_factors, fixed).term_names
        except DesignError as exc:
            raise StudyError(f"{where}: {key} {expression!r} is not a model of the study's factors ({exc})") from None

    def names_list(key: str, allowed: tuple[str, ...]) -> tuple[str, ...]:
        value = values[key]
        if not isinstance(value, list) or not all(isinstance(v, str) and v in allowed for v in value) or len(set(value)) < len(value):
            raise StudyError(f"{where}: {key} must be a list of distinct names from {', '.join(allowed) or '(none)'}, got {value!r}")
        return tuple(value)

    def whole(key: str, low: int, high: int) -> int:
        value = values[key]
        if not isinstance(value, int) or isinstance(value, bool) or not low <= value <= high:
            raise StudyError(f"{where}: {key} must be a whole number in [{low}, {high}], got {value!r}")
        return value

    factor = text("factor")
    arm = next((f for f in spec.design_factors if f.name == factor), None)
    if factor and not isinstance(arm, CategoricalFactor):
        categorical = [f.name for f in spec.design_factors if isinstance(f, CategoricalFactor)]
        raise StudyError(f"{where}: factor must be \"\" or a categorical factor of the study ({', '.join(categorical)}), got {factor!r}")
    test = text("test", TESTS)
    if test == RANDOMIZATION and arm is None:
        raise StudyError(f"{where}: test \"{RANDOMIZATION}\" compares the arms of a factor; name one (factor = \"Controller\") "
                         "or use test = \"gee\"")
    terms = model("model")
    if factor and factor not in terms:
        raise StudyError(f"{where}: model {values['model']!r} must hold the compared factor {factor!r}")
    stratifiers = tuple(n for n, f in zip(names, spec.design_factors) if isinstance(f, CategoricalFactor | DiscreteFactor) and n != factor)
    strata = names_list("strata", stratifiers)
    if values["exploratory"] != "":
        model("exploratory")
    alpha = values["alpha"]
    if not isinstance(alpha, int | float) or isinstance(alpha, bool) or not (math.isfinite(alpha) and 0.0 < alpha <= 0.5):
        raise StudyError(f"{where}: alpha must be a number in (0, 0.5], got {alpha!r}")
    return AnalysisPlan(text("outcome", OUTCOMES), factor, test, values["model"], strata, values["exploratory"], float(alpha),
                        names_list("sensitivity", SENSITIVITY), whole("draws", 100, MAX_DRAWS), whole("seed", 0, MAX_SEED),
                        text("gee_covariance", COVARIANCES), text("gee_alpha", ALPHA_ESTIMATORS))


#: design.json's field committing to the analysis plan written with the design.
COMMITMENT = "analysis_plan"


def commitment(table: dict[str, Any]) -> dict[str, str]:
    """design.json's record of the [analysis] table written with the design: its SHA-256 (`AnalysisPlan.digest`)."""
    return {"covers": f"study.toml's [{TABLE}] table, every key, as JSON with sorted keys, no spaces, UTF-8", "sha256": table_digest(table)}


def committed_digest(design: dict[str, Any]) -> str | None:
    """The plan digest design.json commits to (None: a design made before plans were committed)."""
    entry = design.get(COMMITMENT)
    return str(entry["sha256"]) if isinstance(entry, dict) and "sha256" in entry else None


def plan_in_force(spec_path: Path, spec: StudySpec, design: dict[str, Any]) -> tuple[AnalysisPlan, bool]:
    """The plan a study is analysed by: study.toml's [analysis] table, else the defaults for its spec (the design's seed);
    and whether the table is there."""
    seed = int(design.get("seed") or 0)
    declared = read_analysis_plan(spec_path, spec, seed)
    return (declared or default_plan(spec, seed)), declared is not None


def plan_status(spec_path: Path, spec: StudySpec, design: dict[str, Any], opened_with: tuple[str | None, ...]) -> PlanStatus:
    """The plan in force and its standing against design.json's commitment and the plans recorded at the key's openings."""
    plan, declared = plan_in_force(spec_path, spec, design)
    return PlanStatus(plan, declared, committed_digest(design), opened_with)
