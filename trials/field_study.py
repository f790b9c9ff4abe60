"""Whether a study is a field study: its runs happen on the robot (driven live, or played from the robot's own logs),
so simulated runs and simulated judgments must not mix into its data unless asked for by name (`--allow-simulated`)."""

from __future__ import annotations

from trials.outcomes import read_outcomes
from trials.robot.settings import read_robot_settings
from trials.run_settings import LOGGED, NOT_SIMULATED, SOFTWARE_ROBOT
from trials.study import OUTCOMES, SPEC, StudyFolder

#: The flag that lets `trials run` simulate, and `trials respond --simulate` judge, in a field study.
ALLOW_SIMULATED = "--allow-simulated"


def field_reason(folder: StudyFolder, blind: bool) -> str | None:
    """Why `folder` is a field study (its [robot] table, or its first run driven live or played from a log), else None."""
    robot = read_robot_settings(folder.path(SPEC))
    if robot is not None:
        return f"{folder.path(SPEC)} has a [robot] table (runs are driven live on {robot.uri})"
    field_run = next((row for row in read_outcomes(folder.path(OUTCOMES), blind) if row.perception in NOT_SIMULATED), None)
    if field_run is not None:
        how = {LOGGED: "played from a robot log", SOFTWARE_ROBOT: "driven live on the software robot"}.get(field_run.perception, "driven live")
        return f"its run {field_run.run_code} was {how}"
    return None


def refuse_simulation(folder: StudyFolder, blind: bool, what: str) -> None:
    """StudyError when `folder` is a field study: `what` (e.g. "simulate runs") would mix simulation into its data.

    Raises:
        StudyError: the study is a field study, naming why and the flag that allows it anyway.
    """
    from trials.errors import StudyError

    reason = field_reason(folder, blind)
    if reason is not None:
        raise StudyError(f"{folder.root} is a field study ({reason}): refusing to {what}; pass {ALLOW_SIMULATED} to mix "
                         "simulation into its data anyway (the report says which runs were simulated)")
