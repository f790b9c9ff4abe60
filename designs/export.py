"""A built plan as records: `design.json`, the `plan.csv` table and the console summary.

Everything here is public: a blinded factor appears only through its arm labels.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from designs.blinding import WHOLE_KEY
from designs.diagnostics import POWER_CONVENTION, Diagnostics
from designs.errors import DesignError
from designs.exchange import AGREE_BATCH, AGREED, CRITERION_NAMES, KICK_RUNS, PATIENCE, RESTART_KICKS, VALUE_TOL, candidate_set
from designs.factors import CategoricalFactor, ContinuousFactor, DiscreteFactor, Factor, FixedFactor, plain
from designs.plan import StudyPlan
from designs.spec import PLAN_COLUMNS, factor_from_table, factor_table

FORMAT = "navtrials.design/1"


def plan_table(plan: StudyPlan) -> tuple[list[str], list[list[str]]]:
    """Header and rows of the public run sheet, in run order."""
    return _table(plan.spec.factors, [(run.order, run.code, run.values) for run in plan.runs])


def plan_from_record(record: dict[str, Any], source: str) -> tuple[list[str], list[list[str]]]:
    """The run sheet a design.json record describes: its factors decoded from each run's settings.

    plan.csv must equal it cell for cell, so a hand edit of the plan is found even in a design.json
    written before it recorded the plan's digest.

    Raises:
        DesignError: the record's factors or runs are not those of a design this module wrote.
    """
    try:
        factors = tuple(factor_from_table({k: v for k, v in raw.items() if k != "coding"}, f"{source}: factors[{i}]")
                        for i, raw in enumerate(record["factors"]))
        design_factors = [f for f in factors if not isinstance(f, FixedFactor)]
        runs = []
        for run in record["design"]:
            settings = run["settings"]
            if len(settings) != len(design_factors):
                raise DesignError(f"{source}: run {run['run_code']} has {len(settings)} settings for {len(design_factors)} factors")
            values: dict[str, float | str] = {f.name: f.value for f in factors if isinstance(f, FixedFactor)}
            values.update({f.name: f.decode(s) for f, s in zip(design_factors, settings)})
            runs.append((int(run["order"]), str(run["run_code"]), values))
    except (KeyError, TypeError, ValueError, IndexError, AttributeError) as exc:
        raise DesignError(f"{source}: its factors or runs are damaged ({type(exc).__name__}: {exc})") from None
    return _table(factors, runs)


def _table(factors: tuple[Factor, ...], runs: list[tuple[int, str, dict[str, float | str]]]) -> tuple[list[str], list[list[str]]]:
    header = [*PLAN_COLUMNS, *(f.name for f in factors)]
    return header, [[str(order), code, *(_cell(values[f.name]) for f in factors)] for order, code, values in runs]


def design_record(plan: StudyPlan, created: str, key: str) -> dict[str, Any]:
    """The content of design.json; `key` is where the study keeps its sealed key (recorded when blinded)."""
    d = plan.diagnostics
    record: dict[str, Any] = {
        "format": FORMAT,
        "created": created,
        "study": plan.spec.name,
        "runs": plan.spec.runs,
        "seed": plan.seed,
        "factors": [_factor_record(f) for f in plan.spec.factors],
        "criterion": plan.spec.criterion,
        "disallowed": list(plan.spec.disallowed),
        "constraints": list(plan.spec.constraints),
        "model": {
            "expression": plan.spec.model,
            "terms": plan.model.term_names,
            "columns": plan.model.columns,
        },
        "diagnostics": {
            "p": d.p,
            "n": d.n,
            "det_xtx": d.det_xtx,
            "d_efficiency": d.d_efficiency,
            "a_efficiency": d.a_efficiency,
            "g_efficiency": d.g_efficiency,
            "average_prediction_variance": d.average_prediction_variance,
            "max_prediction_variance": d.max_prediction_variance,
            "d_efficiency_bound": plan.bound.d_efficiency,
            "d_efficiency_vs_bound": plan.d_efficiency_vs_bound,
            "standard_errors": d.standard_errors,
            "correlation_map": {"columns": d.correlation_columns, "matrix": _matrix(d.correlations)},
            "power": {
                "alpha": d.alpha,
                "snr": d.snr,
                "convention": POWER_CONVENTION,
                "anticipated": d.anticipated,
                "error_df": d.error_df,
                "terms": [{"term": t.term, "parameters": t.parameters, "power": t.power} for t in d.term_power],
                "parameters": d.parameter_power,
            },
        },
        "search": {
            "algorithm": ("Fedorov's row exchange over the grid points, every start at once in numpy, rank-two updates"
                          if plan.design.row_exchange else
                          "coordinate exchange with candidate-point swaps and replicates, compiled, rank-one updates")
                         + f"; when the starts disagree, iterated local search on the grid (kicks of {KICK_RUNS} runs, restarted from a "
                         f"fresh opening after {PATIENCE} kicks without gain) before a last exchange",
            "criterion": plan.design.criterion,
            "criterion_value": plan.design.value,
            "starts": plan.design.starts,
            "kick_budget_per_start": plan.design.kicks,
            "searched_again": plan.design.searched,
            "agree_batch": AGREE_BATCH,
            "patience": PATIENCE,
            "restart_kicks": RESTART_KICKS,
            "agreed": AGREED,
            "hits": plan.design.hits,
            "hits_tolerance": VALUE_TOL,
            "design_seed": plan.design.seed,
            "log_det_xtx": math.log(d.det_xtx),
        },
        "bound": {
            "method": "approximate D-optimal design on the candidate set (multiplicative algorithm, certified by the equivalence theorem)",
            "d_efficiency": plan.bound.d_efficiency,
            "support": _support(plan),
        },
        "design": [
            {"order": run.order, "run_code": run.code, "settings": run.settings.tolist()} for run in plan.runs
        ],
        "blinding": None,
    }
    if plan.sealed is not None:
        record["blinding"] = {
            "factor": plan.sealed.factor,
            "arms": sorted(plan.sealed.arms),
            "commitment": {"algorithm": WHOLE_KEY, "digest": plan.sealed.commitment()},
            "key": key,
        }
    return record


def summary_lines(plan: StudyPlan) -> list[str]:
    """What `trials design` prints: the design's quality and what it can estimate."""
    d = plan.diagnostics
    spec = plan.spec
    lines = [
        f"Study {spec.name!r}: {spec.runs} runs, model {spec.model!r} with p = {d.p} parameters",
        f"Seed {plan.seed}; criterion {plan.design.criterion} ({CRITERION_NAMES[plan.design.criterion]}); "
        f"{plan.design.starts} exchange starts"
        f"{f', the first {plan.design.searched} searched again with up to {plan.design.kicks} kicks each' if plan.design.kicks else ''}, "
        f"{plan.design.hits} reached the best design",
    ]
    bound = f"  D-efficiency bound           {plan.bound.d_efficiency:9.4f}   this design reaches {plan.d_efficiency_vs_bound:.2f} % of it"
    lines += diagnostics_lines(d, bound)
    if plan.sealed is not None:
        lines += [
            f"Blinded: {plan.sealed.factor} appears as arms {', '.join(sorted(plan.sealed.arms))}; the key is sealed, committed to by",
            f"  {plan.sealed.commitment()}",
        ]
    return lines


def diagnostics_lines(d: Diagnostics, bound: str = "") -> list[str]:
    """The efficiencies, each term's power and the largest correlation, as the console shows them;
    `bound` is a line placed after the D-efficiency."""
    lines = [f"  D-efficiency                 {d.d_efficiency:9.4f}   det(X'X) = {d.det_xtx:.10g}", *([bound] if bound else []),
             f"  A-efficiency                 {d.a_efficiency:9.4f}",
             f"  G-efficiency                 {d.g_efficiency:9.4f}",
             f"  Average prediction variance  {d.average_prediction_variance:9.4f}",
             "JMP's power of each term's least-squares F test, for a Gaussian response, not the judgments "
             f"(alpha {d.alpha:g}, signal-to-noise {d.snr:g}, error df {d.error_df}; {POWER_CONVENTION}):"]
    width = max(len(t.term) for t in d.term_power)
    lines += [f"  {t.term:<{width}}  {t.parameters} df  power {t.power:.3f}" for t in d.term_power]
    largest = _largest_correlation(d.correlation_columns, d.correlations)
    if largest:
        lines.append(f"Largest correlation between model columns: {largest}")
    return lines


def comparison_lines(names: list[str], results: list[Diagnostics]) -> list[str]:
    """Two or more plans' diagnostics side by side, one row per figure."""
    width = max(12, *(len(name) for name in names))
    rows = [("runs", [f"{d.n}" for d in results]), ("p", [f"{d.p}" for d in results]),
            ("det(X'X)", [f"{d.det_xtx:.6g}" for d in results]),
            ("D-efficiency", [f"{d.d_efficiency:.4f}" for d in results]),
            ("A-efficiency", [f"{d.a_efficiency:.4f}" for d in results]),
            ("G-efficiency", [f"{d.g_efficiency:.4f}" for d in results]),
            ("Average prediction variance", [f"{d.average_prediction_variance:.4f}" for d in results]),
            ("Largest prediction variance", [f"{d.max_prediction_variance:.4f}" for d in results])]
    rows += [(f"Power {t.term}", [f"{next(u.power for u in d.term_power if u.term == t.term):.3f}" for d in results])
             for t in results[0].term_power]
    label = max(len(name) for name, _ in rows)
    lines = [f"{'':<{label}}  " + "  ".join(f"{name:>{width}}" for name in names)]
    lines += [f"{name:<{label}}  " + "  ".join(f"{v:>{width}}" for v in values) for name, values in rows]
    return lines


def _factor_record(factor: Factor) -> dict[str, Any]:
    """The spec's factor table plus its coding."""
    record = factor_table(factor)
    if isinstance(factor, (ContinuousFactor, DiscreteFactor)):
        record["coding"] = {"center": plain(0.5 * (factor.low + factor.high)), "half_range": plain(0.5 * (factor.high - factor.low))}
    elif isinstance(factor, CategoricalFactor):
        record["coding"] = {"effect": factor.effect_coding.tolist()}
    return record


def _support(plan: StudyPlan) -> list[dict[str, Any]]:
    candidates = candidate_set(plan.model, plan.restrictions)
    keep = plan.bound.weights > 1e-6
    return [{"settings": c.tolist(), "weight": float(w)} for c, w in zip(candidates[keep], plan.bound.weights[keep])]


def _matrix(values: np.ndarray) -> list[list[float | None]]:
    return [[None if math.isnan(v) else float(v) for v in row] for row in values]


def _cell(value: float | str) -> str:
    value = plain(value)
    return f"{value:.6g}" if isinstance(value, float) else str(value)


def _largest_correlation(columns: list[str], corr: np.ndarray) -> str:
    if len(columns) < 2:
        return ""
    masked = np.abs(np.where(np.isnan(corr), 0.0, corr))
    np.fill_diagonal(masked, 0.0)
    i, j = np.unravel_index(np.argmax(masked), masked.shape)
    return f"|r| = {masked[i, j]:.3f} ({columns[i]} ~ {columns[j]})"
