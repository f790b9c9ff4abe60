"""Everything `trials report` reads from a study folder, checked, as one `analysis.records.StudyData`.

Blinding: without unblinding a blinded study's arms keep their labels. Unblinding opens the
sealed key only after checking it against design.json's commitment, and the time of every
verified unblinding is kept in report/unblinding.json (the report's metadata), first one first.
"""

from __future__ import annotations

import json
from typing import Any

from analysis.records import EXTERNAL_LOG, LIVE_RUN, SIMULATED_RUN, Blinding, HumanScore, Outcome, Response, StudyData, StudyRun
from designs.spec import read_spec
from trials.controllers import registry
from trials.errors import StudyError
from trials.outcomes import outcome_cells, read_outcomes
from trials.responses import read_responses
from trials.run_settings import LIVE, LOGGED, distinct, recorded_text
from trials.scores import read_scores
from trials.study import (
    OUTCOMES,
    PLAN,
    RESPONSES,
    SCORES,
    SPEC,
    UNBLINDING,
    StudyFolder,
)

UNBLINDING_FORMAT = "navtrials.unblinding/1"
CONTROLLER_FACTOR = "Controller"

#: report.json's key for the digest of the files the report was made from (`StudyFolder.report_inputs`).
INPUTS_KEY = "inputs_sha256"


def load_study(folder: StudyFolder, unblind: bool, now: str, commitment: str | None = None) -> StudyData:
    """Read and cross-check plan, design, outcomes, scores and responses; open the key if asked,
    checked against design.json's commitment and the recorded `commitment` when given."""
    folder.require_plan()
    spec = read_spec(folder.path(SPEC))
    design = folder.read_design()
    plan = folder.read_plan()
    model = spec.build_model()
    codes = [row["run_code"] for row in plan]
    notes: list[str] = []

    outcomes = read_outcomes(folder.path(OUTCOMES))
    _no_unknown_codes([o.run_code for o in outcomes], codes, f"{OUTCOMES} has rows")
    latest = {}
    for outcome in outcomes:
        if outcome.run_code in latest:
            notes.append(f"{OUTCOMES} holds run {outcome.run_code} twice; the later row (finished {outcome.finished_utc}) is used.")
        latest[outcome.run_code] = outcome
    mixed = distinct(outcome_cells(o) for o in latest.values())
    if len(mixed) > 1:
        groups = "; ".join(f"{n} with {recorded_text(key)}" for key, n in mixed.items())
        notes.append(f"The runs were not all made with the same settings ({groups}); their results are pooled "
                     "as if they had been (`trials run --settings-differ`).")
    scores: list[HumanScore] = read_scores(folder.path(SCORES))
    _no_unknown_codes([s.run_code for s in scores], codes, f"{SCORES} has scores")
    responses: list[Response] = read_responses(folder.path(RESPONSES))
    _no_unknown_codes([r.run_code for r in responses], codes, f"{RESPONSES} has judgments")

    blinding = _blinding(folder, design, [f.name for f in spec.factors], unblind, now, notes, commitment)
    runs = []
    for row in plan:
        code = row["run_code"]
        outcome = latest.get(code)
        log = folder.run_log(code)
        if blinding.factor is not None:
            arm = blinding.labels[row[blinding.factor]]
        else:
            arm = (outcome.controller if outcome is not None and outcome.controller else None) or registry.DEFAULT
        values = {f.name: row[f.name] for f in spec.factors}
        runs.append(StudyRun(int(row["order"]), code, values, arm, outcome, log if log.exists() else None, run_origin(outcome)))
    for run in runs:
        if run.finished and run.log is None:
            notes.append(f"Run {run.code} has an outcome row but no log {folder.run_log(run.code).relative_to(folder.root)}; "
                         "it is scored from its outcome row only.")
    correlation = design.get("diagnostics", {}).get("correlation_map", {})
    return StudyData(
        root=folder.root,
        spec=spec,
        model=model,
        seed=design.get("seed"),
        runs=runs,
        scores=scores,
        responses=responses,
        blinding=blinding,
        correlations=(correlation.get("columns", []), correlation.get("matrix", [])),
        diagnostics=design.get("diagnostics", {}),
        notes=notes,
    )


def run_origin(outcome: Outcome | None) -> str:
    """How a run was made, by its outcome row's perception: driven live (`live`), played from an external robot log
    (`log`: the toolkit did not drive that robot), else simulated."""
    perception = outcome.perception if outcome is not None else ""
    return {LIVE: LIVE_RUN, LOGGED: EXTERNAL_LOG}.get(perception, SIMULATED_RUN)


def _no_unknown_codes(found: list[str], codes: list[str], what: str) -> None:
    unknown = list(dict.fromkeys(c for c in found if c not in set(codes)))
    if unknown:
        raise StudyError(f"{what} for unknown run code(s) {', '.join(unknown)}: not in {PLAN}")


def _blinding(folder: StudyFolder, design: dict[str, Any], spec_factor_names: list[str], unblind: bool, now: str, notes: list[str],
              commitment: str | None) -> Blinding:
    record = design.get("blinding")
    if not record:
        if unblind:
            notes.append("The study is not blinded: --unblind had nothing to open.")
        factor = CONTROLLER_FACTOR if CONTROLLER_FACTOR in spec_factor_names else None
        plan_values = {row[factor] for row in folder.read_plan()} if factor else set()
        return Blinding(False, factor, {v: v for v in plan_values})
    digest = record["commitment"]["digest"]
    history = read_unblinding(folder, digest)
    if not unblind:
        return Blinding(True, record["factor"], {arm: arm for arm in record["arms"]}, False, digest, history)
    sealed, check = folder.open_sealed(commitment)
    return Blinding(True, record["factor"], dict(sealed.arms), True, digest, (*history, now), check)


def read_unblinding(folder: StudyFolder, commitment: str) -> tuple[str, ...]:
    """Earlier verified unblindings of this design (by its commitment), oldest first."""
    path = folder.path(UNBLINDING)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        return ()
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise StudyError(f"{path} is damaged: {exc}") from None
    if data.get("commitment") != commitment:
        return ()
    return tuple(str(t) for t in data.get("unblinded_utc", []))


def unblinding_record(blinding: Blinding) -> bytes:
    """report/unblinding.json: when the key of this design was opened, every time."""
    data = {"format": UNBLINDING_FORMAT, "commitment": blinding.commitment, "unblinded_utc": list(blinding.unblinded_utc)}
    return (json.dumps(data, indent=1) + "\n").encode()
