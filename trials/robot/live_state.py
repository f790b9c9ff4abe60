"""`runs/live.json`: the state of the live run in progress (or the last one), written by the worker that drives it and
read by `trials status` and the console. Public: the run code, the state and its detail, never the controller; its time,
and the modification times of the file and of runs/, are to the minute, since to the second they would time a run's end
and so tell the arms of a blinded study apart."""

from __future__ import annotations

import json

from trials.atomic import write_text
from trials.study import LIVE_STATE, StudyFolder, to_the_minute, utc_now


def write_state(folder: StudyFolder, code: str, state: str, detail: str) -> None:
    """runs/live.json: the live run's code, state and detail, and the minute it entered that state (UTC)."""
    path = folder.path(LIVE_STATE)
    write_text(path, json.dumps({"run_code": code, "state": state, "detail": detail, "since_utc": utc_now(to_the_minute=True)}) + "\n")
    to_the_minute(path, path.parent)


def read_state(folder: StudyFolder) -> dict[str, str] | None:
    """The live run's state as the worker last wrote it, or None (no live run yet, or an unreadable file)."""
    try:
        data = json.loads(folder.path(LIVE_STATE).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return {k: str(v) for k, v in data.items()} if isinstance(data, dict) else None
