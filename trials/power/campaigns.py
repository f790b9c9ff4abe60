"""power/power.csv: one row per finished closed-loop campaign, appended atomically after each batch so an
interrupted `trials power` resumes where it stopped (this module reads and writes it).

Columns: `settings` (a digest of everything that shapes a campaign, so rows of other settings are
never mixed in), `runs`, `campaign`, `seed`, `allocation` (arm=controller;...), one count per run
status, `judgments`, `p:<term>` the GEE test of each model term, and per Table II row k
`share>=k:<controller>` and `holm_p>=k`. Numbers are written exactly (repr); empty means none.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

from trials.csv_table import append_rows, read_table
from trials.errors import StudyError
from trials.power.closed_loop import STATUSES, CampaignResult
from trials.power.plans import PowerPlan
from trials.power.verdicts import RowVerdict, Verdict

FIXED = ("settings", "runs", "campaign", "seed", "allocation", *STATUSES, "judgments")


def header(plans: Sequence[PowerPlan], controllers: Sequence[str]) -> list[str]:
    """power.csv's columns for these plans (the same model; Table II rows for every pedestrian count they hold)."""
    terms = plans[0].model.term_names[1:]
    rows = sorted({k for plan in plans for k in plan.pedestrians()}) if plans[0].arms else []
    names = controllers if plans[0].blinded else plans[0].arms
    shares = [f"share>={k}:{name}" for k in rows for name in names]
    return [*FIXED, *(f"p:{t}" for t in terms), *shares, *(f"holm_p>={k}" for k in rows)]


def _number(value: float) -> str:
    return "" if math.isnan(value) else repr(float(value))


def _float(cell: str) -> float:
    return float(cell) if cell else math.nan


def cells(result: CampaignResult, columns: Sequence[str], settings: str) -> list[str]:
    """One campaign as a row of power.csv."""
    values = {"settings": settings, "runs": str(result.runs), "campaign": str(result.campaign), "seed": str(result.seed),
              "allocation": ";".join(f"{arm}={name}" for arm, name in result.allocation.items()),
              **{s: str(result.statuses[s]) for s in STATUSES}, "judgments": str(result.judgments)}
    values.update({f"p:{term}": _number(p) for term, p in result.verdict.term_p.items()})
    for row in result.verdict.rows:
        values[f"holm_p>={row.min_pedestrians}"] = _number(row.holm_p)
        values.update({f"share>={row.min_pedestrians}:{name}": _number(share) for name, share in row.shares.items()})
    return [values.get(column, "") for column in columns]


def _parse(row: dict[str, str], columns: Sequence[str]) -> CampaignResult:
    allocation = dict(part.split("=", 1) for part in row["allocation"].split(";") if part)
    ks = [int(c.removeprefix("holm_p>=")) for c in columns if c.startswith("holm_p>=")]
    rows = []
    for k in ks:
        prefix = f"share>={k}:"
        shares = {c.removeprefix(prefix): _float(row[c]) for c in columns if c.startswith(prefix)}
        if row[f"holm_p>={k}"] or any(not math.isnan(s) for s in shares.values()):
            rows.append(RowVerdict(k, shares, _float(row[f"holm_p>={k}"])))
    verdict = Verdict({c.removeprefix("p:"): _float(row[c]) for c in columns if c.startswith("p:")}, tuple(rows))
    return CampaignResult(int(row["runs"]), int(row["campaign"]), int(row["seed"]), allocation,
                          {s: int(row[s]) for s in STATUSES}, int(row["judgments"]), verdict)


def read_campaigns(path: Path, columns: Sequence[str], settings: str) -> list[CampaignResult]:
    """The campaigns power.csv holds for these settings (none when there is no file).

    Raises:
        StudyError: other columns, rows of other settings (another seed, plan or options), or a damaged row.
    """
    table = read_table(path, columns)
    if table.header and tuple(table.header) != tuple(columns):
        raise StudyError(f"{path} has columns {', '.join(table.header)}; expected {', '.join(columns)} "
                         "(campaigns of another study or plan: move it away or give another --out)")
    results = []
    for line, row in table.rows:
        if row["settings"] != settings:
            raise StudyError(f"{path} line {line}: a campaign of other settings ({row['settings']}, these are {settings}); "
                             "rerun with the same options and --seed to resume it, or give another --out")
        try:
            results.append(_parse(row, columns))
        except (ValueError, KeyError) as exc:
            raise StudyError(f"{path} line {line}: damaged row ({exc})") from None
    return results


def append_campaigns(path: Path, columns: Sequence[str], results: Sequence[CampaignResult], settings: str) -> None:
    """Add finished campaigns to power.csv (the file is rewritten through a temporary name)."""
    append_rows(path, columns, [cells(r, columns, settings) for r in results])
