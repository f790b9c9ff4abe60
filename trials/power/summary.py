"""The power figures of each plan, from the simulated data sets' verdicts, and the files that hold them:
power/power.json (every number, with the power seed and settings) and power/power.md (tables).

Power is the share of data sets whose test rejects at alpha, with its Wilson 95 % Monte Carlo
interval; a data set whose fit gives no test counts as not rejecting.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from analysis.intervals import wilson
from trials.power.closed_loop import STATUSES, CampaignResult
from trials.power.plans import PowerPlan
from trials.power.verdicts import Verdict
from trials.scenario import CONTROLLER

FORMAT = "navtrials.power/1"


@dataclass(frozen=True)
class PowerEstimate:
    """`rejected` of `total` data sets rejected; the power and its Wilson 95 % interval. `untested` of them had no test
    (the fit does not exist, e.g. separated judgments): they count as not rejecting, and are stated apart."""

    rejected: int
    total: int
    low: float
    high: float
    untested: int = 0

    @property
    def power(self) -> float:
        return self.rejected / self.total if self.total else math.nan

    @property
    def power_when_tested(self) -> float:
        """The share rejected among the data sets that had a test."""
        tested = self.total - self.untested
        return self.rejected / tested if tested else math.nan

    def text(self) -> str:
        return "n/a" if not self.total else f"{self.power:.3f} ({self.low:.3f}-{self.high:.3f}){self.untested_text()}"

    def untested_text(self) -> str:
        """The data sets without a test, in words after the power ("" when every one had a test)."""
        if not self.untested:
            return ""
        tested = self.total - self.untested
        among = f"{self.power_when_tested:.3f} of the {tested} tested rejected" if tested else "none had a test"
        return f" [no test on {self.untested} of {self.total} data sets (the fit does not exist), counted as not rejecting; {among}]"


def _estimate_record(e: PowerEstimate) -> dict[str, object]:
    return {**asdict(e), "power": e.power, "power_when_tested": e.power_when_tested}


def estimate(p_values: Iterable[float], alpha: float) -> PowerEstimate:
    """The power of a test from its p-values over the data sets (NaN: no test, not rejected)."""
    values = list(p_values)
    rejected = sum(1 for p in values if not math.isnan(p) and p < alpha)
    interval = wilson(rejected, len(values))
    return PowerEstimate(rejected, len(values), interval.low, interval.high, sum(1 for p in values if math.isnan(p)))


def term_power(verdicts: Sequence[Verdict], alpha: float) -> dict[str, PowerEstimate]:
    if not verdicts:
        return {}
    return {term: estimate((v.term_p[term] for v in verdicts), alpha) for term in verdicts[0].term_p}


def row_power(verdicts: Sequence[Verdict], alpha: float) -> dict[int, PowerEstimate]:
    """Each Table II row's controller comparison (Holm-adjusted), over the data sets that have the row."""
    ks = sorted({row.min_pedestrians for v in verdicts for row in v.rows})
    return {k: estimate((row.holm_p for v in verdicts for row in v.rows if row.min_pedestrians == k), alpha) for k in ks}


def share_spread(results: Sequence[CampaignResult]) -> dict[int, dict[str, dict[str, float]]]:
    """Each Table II share's distribution over the campaigns: mean and 2.5, 50 and 97.5 % quantiles."""
    spread: dict[int, dict[str, dict[str, float]]] = {}
    ks = sorted({row.min_pedestrians for r in results for row in r.verdict.rows})
    for k in ks:
        names = sorted({name for r in results for row in r.verdict.rows if row.min_pedestrians == k for name in row.shares})
        spread[k] = {}
        for name in names:
            values = np.array([row.shares.get(name, math.nan) for r in results for row in r.verdict.rows if row.min_pedestrians == k])
            values = values[np.isfinite(values)]
            if len(values):
                q = np.quantile(values, [0.025, 0.5, 0.975])
                spread[k][name] = {"mean": float(values.mean()), "q2.5": float(q[0]), "median": float(q[1]), "q97.5": float(q[2])}
    return spread


@dataclass(frozen=True)
class PlanPower:
    """Every power figure of one plan."""

    runs: int
    source: str
    #: JMP's analytic power of each term (Gaussian, the spec's anticipated coefficients and snr), as design.json gives it.
    analytic: dict[str, float]
    gaussian: dict[str, PowerEstimate]
    judgments: dict[str, PowerEstimate]
    rows: dict[int, PowerEstimate]
    campaigns: int = 0
    closed_terms: dict[str, PowerEstimate] = field(default_factory=dict)
    closed_rows: dict[int, PowerEstimate] = field(default_factory=dict)
    shares: dict[int, dict[str, dict[str, float]]] = field(default_factory=dict)
    statuses: dict[str, int] = field(default_factory=dict)
    #: The planned primary test (study.toml's [analysis]), model-based; None when no data set was given a plan.
    planned: PowerEstimate | None = None


def plan_power(plan: PowerPlan, analytic: dict[str, float], model_based: Sequence[tuple[Verdict, Verdict]],
               campaigns: Sequence[CampaignResult], alpha: float, planned_alpha: float | None = None) -> PlanPower:
    judged = [j for j, _ in model_based]
    closed = [r.verdict for r in campaigns]
    statuses = {s: sum(r.statuses[s] for r in campaigns) for s in STATUSES} if campaigns else {}
    planned = [v.primary_p for v in judged]
    return PlanPower(plan.runs, plan.source, analytic, term_power([g for _, g in model_based], alpha), term_power(judged, alpha),
                     row_power(judged, alpha), len(campaigns), term_power(closed, alpha), row_power(closed, alpha),
                     share_spread(campaigns), statuses,
                     estimate(planned, planned_alpha or alpha) if planned and not all(math.isnan(p) for p in planned) else None)


def focus_terms(plan: PowerPlan) -> list[str]:
    """The terms whose power decides whether a plan is big enough: the Controller term when the model has one, else all."""
    terms = plan.model.term_names[1:]
    return [CONTROLLER] if CONTROLLER in terms else terms


def smallest_planned(powers: Sequence[PlanPower], target: float) -> int | None:
    """The fewest runs whose planned primary test reaches `target` (model-based)."""
    return next((p.runs for p in sorted(powers, key=lambda p: p.runs) if p.planned is not None and p.planned.power >= target), None)


def smallest(powers: Sequence[PlanPower], terms: Sequence[str], target: float, closed: bool) -> int | None:
    """The fewest runs whose power (model-based, or closed-loop) reaches `target` on every one of `terms`."""
    for power in sorted(powers, key=lambda p: p.runs):
        figures = power.closed_terms if closed else power.judgments
        if figures and all(figures[t].power >= target for t in terms):
            return power.runs
    return None


def power_record(powers: Sequence[PlanPower], settings: dict[str, Any], target: float, terms: Sequence[str]) -> dict[str, Any]:
    """power.json: the settings (power seed included) and every figure of every plan."""

    def plain(value: Any) -> Any:
        if isinstance(value, dict):
            return {str(k): plain(v) for k, v in value.items()}
        if isinstance(value, float) and math.isnan(value):
            return None
        return value

    plans = []
    for p in powers:
        record = asdict(p)
        for key in ("gaussian", "judgments", "rows", "closed_terms", "closed_rows"):
            record[key] = {str(k): _estimate_record(e) for k, e in getattr(p, key).items()}
        record["planned"] = _estimate_record(p.planned) if p.planned is not None else None
        plans.append(plain(record))
    has_closed = any(p.campaigns for p in powers)
    return {"format": FORMAT, **settings, "target": target, "target_terms": list(terms),
            "smallest_runs": {"planned": smallest_planned(powers, target), "model_based": smallest(powers, terms, target, False),
                              "closed_loop": smallest(powers, terms, target, True) if has_closed else None},
            "plans": plans}


def power_json(record: dict[str, Any]) -> str:
    return json.dumps(record, indent=1) + "\n"


def _table(header: list[str], rows: list[list[str]]) -> list[str]:
    return ["| " + " | ".join(header) + " |", "|" + " --- |" * len(header), *("| " + " | ".join(r) + " |" for r in rows)]


def power_markdown(record: dict[str, Any], powers: Sequence[PlanPower], study: str, figure: str) -> str:
    """power.md: what was assumed, then each plan's power tables."""
    alpha = record["alpha"]
    lines = [f"# Power of {study}", "",
             f"Power seed {record['power_seed']}; alpha {alpha:g}; every figure is the share of simulated data sets whose test rejects, "
             "with its Wilson 95 % Monte Carlo interval. The judgments are analysed as `trials report` does: the plan's logistic "
             "model by GEE clustered by run (each term's Wald test) and Table II's controller comparison per row (Fisher's exact "
             "test, Holm-adjusted).", "",
             f"- Model-based: {record['model_based']['simulations']} data sets per plan; {record['model_based']['assumed']}.",
             "- Gaussian: one continuous outcome per run (sigma 1) with the coefficients of design.json's analytic power.",
             ]
    if record.get("closed_loop"):
        c = record["closed_loop"]
        lines.append(f"- Closed-loop: {c['campaigns']} campaigns per plan through the real controllers ({', '.join(c['controllers'])}), "
                     f"perception {c['perception']}, timeout {c['timeout_s']:g} s, simulated participants; each campaign draws its "
                     "own allocation (the study's sealed key is never opened).")
    target = record["target"]
    found = record["smallest_runs"]
    terms = ", ".join(record["target_terms"])
    closed = f", closed-loop {found['closed_loop'] or 'none of those tried'}" if record.get("closed_loop") else ""
    lines += ["", f"Smallest plan reaching power {target:g} on {terms}: model-based {found['model_based'] or 'none of those tried'}{closed}."]
    planned = record.get("planned_test")
    if planned:
        lines += ["", f"The planned primary test ({planned}): smallest plan reaching {target:g}, model-based: "
                      f"{found['planned'] or 'none of those tried'}; "
                      + "; ".join(f"{p.runs} runs {p.planned.text()}" for p in powers if p.planned is not None) + "."]
    lines += ["", f"![power]({figure})", ""]
    for p in powers:
        lines += [f"## {p.runs} runs ({p.source})", ""]
        header = ["term", "analytic (Gaussian, JMP)", "Gaussian, simulated", "judgments, model-based"]
        if p.campaigns:
            header.append(f"judgments, closed-loop ({p.campaigns} campaigns)")
        rows = []
        for term in p.judgments:
            row = [term, f"{p.analytic.get(term, math.nan):.3f}", p.gaussian[term].text(), p.judgments[term].text()]
            if p.campaigns:
                row.append(p.closed_terms[term].text())
            rows.append(row)
        lines += _table(header, rows) + [""]
        if p.rows or p.closed_rows:
            header = ["Table II row", "model-based"] + (["closed-loop"] if p.campaigns else [])
            ks = sorted(set(p.rows) | set(p.closed_rows))
            rows = [[f">= {k} pedestrians", p.rows[k].text() if k in p.rows else "n/a"]
                    + ([p.closed_rows[k].text() if k in p.closed_rows else "n/a"] if p.campaigns else []) for k in ks]
            lines += ["Power of the controller comparison in each row of Table II:", ""] + _table(header, rows) + [""]
        if p.shares:
            rows = [[f">= {k}", name, f"{s['mean']:.3f}", f"{s['q2.5']:.3f}", f"{s['median']:.3f}", f"{s['q97.5']:.3f}"]
                    for k, by_name in p.shares.items() for name, s in by_name.items()]
            lines += ["Table II shares over the closed-loop campaigns:", ""]
            lines += _table(["row", "controller", "mean", "2.5 %", "median", "97.5 %"], rows) + [""]
            lines += [f"Run endings: {', '.join(f'{n} {s}' for s, n in p.statuses.items())}.", ""]
    return "\n".join(lines)
