"""Everything `trials report` reads from a study folder, checked, as one `analysis.records.StudyData`.

Blinding: without unblinding a blinded study's arms keep their labels. Unblinding opens the
sealed key only after checking it against design.json's commitment, and the time of every
verified unblinding is kept in unblinding.json, outside report/ so that no remaking of the report erases it, first one first.
An interim look at the blinded arms (a report that compares them before every run has finished) is kept there too.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from analysis.records import (
    EXTERNAL_LOG,
    LIVE_RUN,
    SIMULATED,
    SIMULATED_RUN,
    SOFTWARE_ROBOT_RUN,
    Blinding,
    HumanScore,
    Look,
    Outcome,
    Response,
    StudyData,
    StudyRun,
    recorded_key,
)
from designs.spec import read_spec
from trials.analysis_plan import plan_in_force, plan_status
from trials.controllers import registry
from trials.errors import StudyError
from trials.live_checks import FILE as LIVE_CHECKS
from trials.live_checks import read_check_log
from trials.outcomes import outcome_cells, read_outcomes
from trials.preregistration import registration
from trials.responses import read_responses
from trials.run_settings import LIVE, LOGGED, SOFTWARE_ROBOT, distinct, recorded_text
from trials.scores import read_scores
from trials.study import (
    DESIGN,
    LOGS,
    OUTCOMES,
    PLAN,
    RESPONSES,
    RUBRIC,
    RUNS,
    SCORES,
    SPEC,
    UNBLINDING,
    UNBLINDING_IN_REPORT,
    StudyFolder,
)

UNBLINDING_FORMAT = "navtrials.unblinding/1"
CONTROLLER_FACTOR = "Controller"

#: unblinding.json's key, in each opening, for the digest of the analysis plan in force (`AnalysisPlan.digest`); and, in
#: the first, for the scores and judgments recorded by then (`analysis.records.recorded_key`).
PLAN_KEY, BEFORE_KEY = "analysis_plan_sha256", "recorded_before"
#: unblinding.json's list of interim looks at the blinded arms (`trials report --interim REASON` without `--unblind`).
LOOKS_KEY = "interim_looks"

#: report.json's keys for the digest of the files the report was made from (`report_inputs`), and for the rubric file
#: it read from outside the study (`--rubric`), if any.
INPUTS_KEY, RUBRIC_KEY = "inputs_sha256", "rubric_file"


def report_inputs(folder: StudyFolder, rubric: Path | None = None) -> str:
    """A digest of every file a report is made from: the design, plan, results, live checks, the record of openings, the
    rubric (the study's, or `rubric` from elsewhere) and every run log, absent ones counted as absent. `trials report`
    records it and `trials status` compares it, so freshness never depends on clocks (a blinded study's files are
    stamped to the minute)."""
    named = [folder.path(name) for name in (SPEC, PLAN, DESIGN, OUTCOMES, SCORES, RESPONSES, RUBRIC, LIVE_CHECKS, UNBLINDING,
                                            UNBLINDING_IN_REPORT)]
    logs = sorted(p for where in (folder.path(RUNS), folder.path(LOGS)) if where.is_dir() for p in where.iterdir() if p.is_file()
                  and not p.name.startswith("."))
    digest = hashlib.sha256()
    for path in [*named, *([rubric] if rubric is not None else []), *logs]:
        content = path.read_bytes() if path.is_file() else None
        digest.update(f"{path.relative_to(folder.root) if path.is_relative_to(folder.root) else path}:"
                      f"{-1 if content is None else len(content)}:".encode())
        digest.update(content or b"")
    return digest.hexdigest()


def load_study(folder: StudyFolder, unblind: bool, now: str, commitment: str | None = None,
               opening: Opening | None = None) -> StudyData:
    """Read and cross-check plan, design, outcomes, scores and responses; open the key if asked,
    checked against design.json's commitment and the recorded `commitment` when given (`opening`: how complete the
    study is as it is opened, `unblinding_opening`, or as its blinded arms are looked at, `interim_look`)."""
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

    blinding = _blinding(folder, design, [f.name for f in spec.factors], unblind, now, notes, commitment, opening)
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
    opened_with = _plans_at_openings(folder, blinding.commitment) if blinding.commitment else ()
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
        analysis_plan=plan_status(folder.path(SPEC), spec, design, opened_with),
        checks=read_check_log(folder),
        registration=registration(folder, commitment),
    )


def run_origin(outcome: Outcome | None) -> str:
    """How a run was made, by its outcome row's perception: driven live (`live`), played from an external robot log
    (`log`: the toolkit did not drive that robot), else simulated."""
    perception = outcome.perception if outcome is not None else ""
    return {LIVE: LIVE_RUN, SOFTWARE_ROBOT: SOFTWARE_ROBOT_RUN, LOGGED: EXTERNAL_LOG}.get(perception, SIMULATED_RUN)


def _no_unknown_codes(found: list[str], codes: list[str], what: str) -> None:
    unknown = list(dict.fromkeys(c for c in found if c not in set(codes)))
    if unknown:
        raise StudyError(f"{what} for unknown run code(s) {', '.join(unknown)}: not in {PLAN}")


def _blinding(folder: StudyFolder, design: dict[str, Any], spec_factor_names: list[str], unblind: bool, now: str, notes: list[str],
              commitment: str | None, opening: Opening | None) -> Blinding:
    record = design.get("blinding")
    if not record:
        if unblind:
            notes.append("The study is not blinded: --unblind had nothing to open.")
        factor = CONTROLLER_FACTOR if CONTROLLER_FACTOR in spec_factor_names else None
        plan_values = {row[factor] for row in folder.read_plan()} if factor else set()
        return Blinding(False, factor, {v: v for v in plan_values})
    digest = record["commitment"]["digest"]
    history = read_unblinding(folder, digest)
    before = _recorded_before(folder, digest)
    completeness, interim = (opening.completeness, opening.interim) if opening is not None else ("", None)
    looks = _looks(folder, digest)
    if not unblind:
        if interim is not None:
            looks = (*looks, Look(now, completeness, interim))
        return Blinding(True, record["factor"], {arm: arm for arm in record["arms"]}, False, digest, history, "", completeness, interim,
                        before, looks)
    sealed, check = folder.open_sealed(commitment)
    if not history:  # opened now for the first time: everything recorded so far was recorded blind
        before = frozenset(_people_records(folder))
    return Blinding(True, record["factor"], dict(sealed.arms), True, digest, (*history, now), check, completeness, interim, before, looks)


def _looks(folder: StudyFolder, commitment: str) -> tuple[Look, ...]:
    """The interim looks at the blinded arms that unblinding.json records, oldest first."""
    looks = _unblinding_file(folder, commitment).get(LOOKS_KEY, [])
    return tuple(Look(str(x.get("utc", "")), str(x.get("completeness", "")), str(x.get("interim", ""))) for x in looks if isinstance(x, dict))


def _people_records(folder: StudyFolder) -> list[str]:
    """`recorded_key` of every human score and of every judgment by a person, sorted."""
    records = [*read_scores(folder.path(SCORES)), *(r for r in read_responses(folder.path(RESPONSES)) if r.source != SIMULATED)]
    return sorted({recorded_key(r) for r in records})


def _recorded_before(folder: StudyFolder, commitment: str) -> frozenset[str] | None:
    """What the record of the key's first opening lists as recorded by then; None when it lists nothing (never opened,
    or opened by a release that did not keep the list)."""
    openings = _unblinding_file(folder, commitment).get("openings", [])
    listed = openings[0].get(BEFORE_KEY) if openings and isinstance(openings[0], dict) else None
    return frozenset(map(str, listed)) if isinstance(listed, list) else None


def _unblinding_file(folder: StudyFolder, commitment: str) -> dict[str, Any]:
    """unblinding.json of this design (by its commitment), or {} when there is none (or it is of another design); a study
    unblinded before the record moved out of report/ has it there."""
    path = folder.path(UNBLINDING)
    if not path.exists() and folder.path(UNBLINDING_IN_REPORT).exists():
        path = folder.path(UNBLINDING_IN_REPORT)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        return {}
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise StudyError(f"{path} is damaged: {exc}") from None
    return data if isinstance(data, dict) and data.get("commitment") == commitment else {}


def _plans_at_openings(folder: StudyFolder, commitment: str) -> tuple[str | None, ...]:
    """The analysis plan's digest recorded at each earlier opening of the key (None where an opening recorded none)."""
    openings = _unblinding_file(folder, commitment).get("openings", [])
    return tuple(str(o[PLAN_KEY]) if isinstance(o, dict) and o.get(PLAN_KEY) else None for o in openings if isinstance(o, dict))


def read_unblinding(folder: StudyFolder, commitment: str) -> tuple[str, ...]:
    """Earlier verified unblindings of this design (by its commitment), oldest first."""
    return tuple(str(t) for t in _unblinding_file(folder, commitment).get("unblinded_utc", []))


@dataclass(frozen=True)
class Opening:
    """How complete a blinded study is as its key is opened, and why it is opened early (None: it is complete)."""

    completeness: str
    interim: str | None


def unblinding_opening(folder: StudyFolder, commitment: str | None, interim: str | None) -> Opening | None:
    """Check that opening the key now is deliberate: the commitment recorded outside the study is given, and every run
    has finished unless an interim reason is given. None for a study that is not blinded (nothing to open).

    Raises:
        StudyError: no `--commitment`, or runs pending or failed without `--interim REASON`, or an empty reason.
    """
    blinding = folder.read_design().get("blinding")
    if not blinding:
        return None
    if commitment is None:
        raise StudyError("--unblind needs --commitment HEX, the pre-registration digest `trials design` printed and you recorded "
                         "outside the study folder (the key's commitment for a study designed before pre-registrations): the key is "
                         "opened only against it")
    completeness, complete = _completeness(folder)
    reason = _reason(interim)
    if not complete and reason is None:
        raise StudyError(f"only {completeness}: opening the key now would be an interim look that the analysis did not plan; "
                         "finish the runs, or give --interim REASON to open it anyway (the reason is recorded and printed in the report)")
    return Opening(completeness, reason)


def interim_look(folder: StudyFolder, interim: str | None) -> Opening | None:
    """For a report that keeps the key closed: the interim look `--interim REASON` asks for at a blinded study whose runs
    are not all finished, or None (no reason given: the report then compares no arms while runs remain).

    Raises:
        StudyError: a reason given to a study that is not blinded or whose runs have all finished, or an empty reason.
    """
    if interim is None:
        return None
    if not folder.read_design().get("blinding"):
        raise StudyError("--interim: the study is not blinded, so its report compares the arms at any time; leave --interim out")
    completeness, complete = _completeness(folder)
    if complete:
        raise StudyError(f"--interim: {completeness}, so the report is not an interim look; leave --interim out")
    return Opening(completeness, _reason(interim))


def _completeness(folder: StudyFolder) -> tuple[str, bool]:
    """How many of the plan's runs have finished (and failed), in words, and whether all have finished."""
    codes = [row["run_code"] for row in folder.read_plan()]
    finished = {row.run_code for row in read_outcomes(folder.path(OUTCOMES), True)} & set(codes)
    failed = [c for c in codes if c not in finished and folder.run_failure(c).exists()]
    return f"{len(finished)} of {len(codes)} runs finished" + (f", {len(failed)} failed" if failed else ""), len(finished) == len(codes)


def _reason(interim: str | None) -> str | None:
    if interim is not None and not interim.strip():
        raise StudyError("--interim needs a reason, e.g. --interim \"safety review after a collision\"")
    return interim.strip() if interim is not None else None


def unblinding_record(folder: StudyFolder, blinding: Blinding) -> bytes:
    """unblinding.json after the report opened the key (`trials report --unblind`) or looked at the blinded arms
    (`trials report --interim`)."""
    if not blinding.revealed:
        look = blinding.looks[-1]
        earlier = _unblinding_file(folder, blinding.commitment or "")
        entry = {"utc": look.utc, "completeness": look.completeness, "interim": look.reason, "command": "trials report --interim",
                 PLAN_KEY: _plan_digest(folder)}
        data = {"unblinded_utc": [], "openings": [], **earlier, "format": UNBLINDING_FORMAT, "commitment": blinding.commitment,
                LOOKS_KEY: [*earlier.get(LOOKS_KEY, []), entry]}
        return (json.dumps(data, indent=1) + "\n").encode()
    opening = Opening(blinding.completeness, blinding.interim)
    return opened_record(folder, blinding.commitment or "", blinding.unblinded_utc[-1], opening, "trials report --unblind")


def opened_record(folder: StudyFolder, commitment: str, utc: str, opening: Opening, command: str) -> bytes:
    """unblinding.json with one more opening of the key: every time it was opened (`unblinded_utc`) and, for each
    opening recorded with them, its time, how complete the study was, any interim reason, the command that opened it and
    the digest of the analysis plan in force (`openings`); the first opening also lists the people's scores and judgments
    recorded by then (`recorded_before`), which the report counts as blind. Whatever command shows the key records it here, so
    reports and `trials status` know."""
    earlier = _unblinding_file(folder, commitment)
    entry = {"utc": utc, "completeness": opening.completeness, "interim": opening.interim, "command": command,
             PLAN_KEY: _plan_digest(folder)}
    if not earlier.get("openings"):
        entry[BEFORE_KEY] = _people_records(folder)
    data = {**earlier, "format": UNBLINDING_FORMAT, "commitment": commitment, "unblinded_utc": [*earlier.get("unblinded_utc", []), utc],
            "openings": [*earlier.get("openings", []), entry]}
    return (json.dumps(data, indent=1) + "\n").encode()


def _plan_digest(folder: StudyFolder) -> str:
    """The digest of the analysis plan in force."""
    spec_path = folder.path(SPEC)
    plan, _ = plan_in_force(spec_path, read_spec(spec_path), folder.read_design())
    return plan.digest()
