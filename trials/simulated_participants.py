"""Simulated judgments of finished runs, appended to responses.csv (source `simulated`, with their seed).

The model is `analysis.participants`; the runner calls `simulate_run` after each finished
simulated run, `trials respond --simulate` calls `simulate_runs` for every run still unjudged.
"""

from __future__ import annotations

from collections.abc import Iterable

from analysis.participants import ParticipantModel, judge_run
from analysis.records import SIMULATED, Response
from analysis.run_log import RunLog
from robot_logs.errors import LogError
from robot_logs.run_log import read_run
from trials.responses import append_responses, read_responses
from trials.study import RESPONSES, StudyFolder, utc_now


def simulate_runs(
    folder: StudyFolder, codes: Iterable[str], seed: int, participants: int | None = None,
    model: ParticipantModel = ParticipantModel(), recorded_utc: str | None = None,
) -> tuple[list[Response], list[str]]:
    """Judge each run that has no judgments yet from its log; returns the judgments appended and the
    runs skipped because their log cannot be read (with the reason). `recorded_utc` defaults to now."""
    judged = {r.run_code for r in read_responses(folder.path(RESPONSES))}
    now = recorded_utc or utc_now()
    responses: list[Response] = []
    skipped: list[str] = []
    for code in codes:
        if code in judged:
            continue
        try:
            log = RunLog.of(read_run(folder.run_log(code)))
        except LogError as exc:
            skipped.append(f"{code} ({exc})")
            continue
        for judgment in judge_run(log, code, seed, participants, model):
            responses.append(Response(code, judgment.participant, judgment.compliant, SIMULATED, now, seed))
    if responses:
        append_responses(folder, responses)
    return responses, skipped


def simulate_run(
    folder: StudyFolder, run_code: str, seed: int, participants: int | None = None, recorded_utc: str | None = None
) -> list[Response]:
    """Append the simulated judgments of one finished run (none if it has judgments already).

    The runner passes the run's `finished_utc` as `recorded_utc`, so that a blinded study's
    responses carry no finer timing than its outcomes do.

    Raises:
        LogError: the run's log runs/<code>.mcap is missing or unreadable.
    """
    responses, skipped = simulate_runs(folder, [run_code], seed, participants, recorded_utc=recorded_utc)
    if skipped:
        raise LogError(f"cannot simulate judgments of run {skipped[0]}")
    return responses
