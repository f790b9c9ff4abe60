"""The settings a study's runs are made with: the `[run]` table of study.toml, overridden by `trials run`'s
options, and recorded with every run (outcomes.csv's settings columns, the log's `run` metadata).

The table is optional; every key in it is too (the defaults are the simulator's):

    [run]
    perception = "positions"   # or "lidar"
    noise = 0.05               # positions: noise of each coordinate, standard deviation in m
    dropout = 0.05             # positions: chance a pedestrian is missed at a step
    timeout = 60               # simulated seconds before a run times out
    weights = "my-navigan.pt"  # NaviGAN-R checkpoint, beside study.toml or a shipped name (default: the shipped weights)

`designs.spec` reads the rest of study.toml and leaves this table to this module.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from robot_logs.physical import STEP_S
from trials.csv_table import cell
from trials.errors import StudyError
from trials.study import study_table

#: The study.toml table this module reads.
TABLE = "run"
PERCEPTIONS = ("positions", "lidar")
#: Upper ends of the ranges: beyond them a value is a typing slip, not a study.
MAX_NOISE_M = 10.0
MAX_TIMEOUT_S = 3600.0
#: How outcomes.csv and the log name the shipped NaviGAN-R weights.
SHIPPED_WEIGHTS = "shipped"
#: The perception recorded for a logged trial (played from a robot log, not simulated).
LOGGED = "log"
#: The perception recorded for a run driven live on a robot (`trials run --robot`), and on the software robot
#: (`trials robot-sim`, which says so on `trials.robot.live.SOFTWARE_ROBOT_TOPIC`): a rehearsal, not a real robot.
LIVE, SOFTWARE_ROBOT = "live", "software-robot"
#: Runs that were not simulated, so no simulation setting applies to them.
NOT_SIMULATED = (LOGGED, LIVE, SOFTWARE_ROBOT)


@dataclass(frozen=True)
class RunSettings:
    """How a study's runs are simulated: what the controller perceives, its noise, the timeout, NaviGAN-R's weights."""

    perception: str = "positions"
    noise_std_m: float = 0.05
    dropout: float = 0.05
    timeout_s: float = 60.0
    weights: str | None = None

    def recorded(self) -> dict[str, str]:
        """The settings as outcomes.csv's columns and the log's metadata write them."""
        return {"perception": self.perception, "noise_std_m": cell(self.noise_std_m), "dropout": cell(self.dropout),
                "timeout_s": cell(self.timeout_s), "weights": self.weights or SHIPPED_WEIGHTS}

    def describe(self) -> str:
        """One line for the console and the report, e.g. `positions, noise 0.05 m, dropout 0.05, timeout 60 s, shipped weights`."""
        noise = f", noise {self.noise_std_m:g} m, dropout {self.dropout:g}" if self.perception == "positions" else ""
        weights = "shipped weights" if self.weights is None else f"weights {self.weights}"
        return f"{self.perception}{noise}, timeout {self.timeout_s:g} s, {weights}"


#: study.toml key -> RunSettings field.
KEYS = {"perception": "perception", "noise": "noise_std_m", "dropout": "dropout", "timeout": "timeout_s", "weights": "weights"}


def read_run_settings(spec: Path) -> RunSettings:
    """The `[run]` table of a study.toml (the defaults where it or the file is missing).

    Raises:
        StudyError: malformed TOML, an unknown key, or a value out of its range, naming the file and key.
    """
    table = study_table(spec, TABLE)
    if table is None:
        return RunSettings()
    settings = settings_from_table(table, f"{spec} [{TABLE}]")
    beside = spec.parent / settings.weights if settings.weights else None
    # A checkpoint named by a relative path is the study's own, beside study.toml; else a shipped name.
    return replace(settings, weights=str(beside)) if beside is not None and beside.is_file() else settings


def run_table(spec: Path) -> dict[str, Any]:
    """The `[run]` table of a study.toml exactly as written ({} without one), after checking it, so that
    `trials design` can carry it into the study.toml it writes."""
    settings = read_run_settings(spec)
    written = {key: getattr(settings, name) for key, name in KEYS.items()}
    table = tomllib.loads(spec.read_text(encoding="utf-8")).get(TABLE, {}) if spec.exists() else {}
    return {key: written[key] for key in table}


def settings_from_table(table: Mapping[str, Any], where: str) -> RunSettings:
    """RunSettings from a `[run]` table's keys, each checked; StudyError names `where` and the key."""
    unknown = sorted(set(table) - set(KEYS))
    if unknown:
        raise StudyError(f"{where}: unknown key {unknown[0]!r} (expected {', '.join(KEYS)})")
    return override(RunSettings(), {KEYS[key]: value for key, value in table.items()}, where)


def override(settings: RunSettings, values: Mapping[str, Any], where: str) -> RunSettings:
    """The settings with the given fields (None: keep) replaced, each checked; StudyError names `where`."""
    given = {name: value for name, value in values.items() if value is not None}
    for name, value in given.items():
        _check(name, value, where)
    # + 0.0 makes -0.0 0.0: numpy refuses a noise of -0.0 ("scale < 0") in every run
    return replace(settings, **{name: float(v) + 0.0 if name in NUMBERS else v for name, v in given.items()})


#: Numeric fields and their ranges (closed, but dropout's upper end is open).
NUMBERS = {"noise_std_m": (0.0, MAX_NOISE_M), "dropout": (0.0, 1.0), "timeout_s": (STEP_S, MAX_TIMEOUT_S)}


def _check(name: str, value: Any, where: str) -> None:
    key = next(k for k, f in KEYS.items() if f == name)
    if name == "perception":
        if value not in PERCEPTIONS:
            raise StudyError(f"{where}: {key} must be one of {', '.join(PERCEPTIONS)}, got {value!r}")
    elif name == "weights":
        if not isinstance(value, str) or not value.strip():
            raise StudyError(f"{where}: {key} must be a checkpoint file name, got {value!r}")
    else:
        low, high = NUMBERS[name]
        number = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
        if not (number and low <= value <= high and not (name == "dropout" and value >= high)):
            ends = f"[{low:g}, {high:g}{')' if name == 'dropout' else ']'}"
            raise StudyError(f"{where}: {key} must be a number in {ends}, got {value!r}")


def setting_names() -> tuple[str, ...]:
    """The recorded settings' names, as outcomes.csv's columns."""
    return tuple(RunSettings().recorded())


def differences(recorded: Mapping[str, str | None], settings: RunSettings) -> list[str]:
    """Where a simulated run's recorded settings (outcomes.csv cells; empty for a run recorded before
    the columns existed) differ from `settings`, as `name recorded -> new` phrases; a logged trial
    (perception `log`) or a live run (`live`) was not simulated, and differs from nothing."""
    if recorded.get("perception") in NOT_SIMULATED:
        return []
    wanted = settings.recorded()
    return [f"{name} {recorded[name]} -> {wanted[name]}" for name in wanted
            if recorded.get(name) not in (None, "") and recorded[name] != wanted[name]]


def distinct(rows: Iterable[Mapping[str, str | None]]) -> dict[tuple[str, ...], int]:
    """How many rows were made with each combination of recorded settings (rows with none recorded left out)."""
    counts: dict[tuple[str, ...], int] = {}
    for row in (r for r in rows if r.get("perception") not in NOT_SIMULATED):
        key = tuple(str(row.get(name) or "") for name in setting_names())
        if any(key[1:]):
            counts[key] = counts.get(key, 0) + 1
    return counts




def recorded_text(key: tuple[str, ...]) -> str:
    """A combination of recorded settings (a key of `distinct`) as `perception positions, noise_std_m 0.050, ...`."""
    return ", ".join(f"{name} {value or '-'}" for name, value in zip(setting_names(), key))
