"""The study folder: the name of every file in it, and the design's files (plan.csv, design.json,
the sealed key) written and read back.

This module is the one place that names the study's files (docs/study_folder.md, docs/architecture.md). The content of
each other file has one module: study.toml `designs.spec`, rubric.toml `analysis.scoring`,
outcomes.csv `trials.outcomes`, scores.csv `trials.scores`, responses.csv `trials.responses`,
runs/<code>.mcap `robot_logs.run_log`, runs/.lock and sealed/runs/ `trials.runner`,
report/unblinding.json `trials.study_data`, the rest of report/ `trials.commands.report`. Files a
new design replaces are moved to superseded/<UTC time>/ (sealed ones to
sealed/superseded/<UTC time>/), never deleted.
"""

from __future__ import annotations

import csv
import json
import shutil
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from designs.blinding import SealedAllocation, verify
from designs.errors import DesignError
from trials.csv_table import table_text
from trials.errors import StudyError

SPEC = "study.toml"
PLAN = "plan.csv"
DESIGN = "design.json"
CORRELATION_MAP = "correlation_map.png"
#: The researcher's own thresholds for the report's rubric, if the study has any.
RUBRIC = "rubric.toml"
SEALED = "sealed"
ALLOCATION = f"{SEALED}/allocation.json"
#: A blinded study's spec as the researcher wrote it, naming the real levels.
SEALED_SPEC = f"{SEALED}/spec.toml"
#: A blinded study's controller records per run (`sealed_run`), kept out of the public logs.
SEALED_RUNS = f"{SEALED}/runs"
RUNS = "runs"
#: Held by the one `trials run` working on the study.
RUN_LOCK = f"{RUNS}/.lock"
RUN_LOG_SUFFIX = ".mcap"
#: The picture of a run beside its log (`trials log show`).
RUN_FIGURE_SUFFIX = ".png"
OUTCOMES = "outcomes.csv"
SCORES = "scores.csv"
RESPONSES = "responses.csv"
REPORT = "report"
REPORT_MARKDOWN = f"{REPORT}/report.md"
REPORT_HTML = f"{REPORT}/report.html"
REPORT_RECORD = f"{REPORT}/report.json"
REPORT_FIGURES = f"{REPORT}/figures"
#: Every table of the report as CSV.
REPORT_TABLES = f"{REPORT}/tables"
#: When the sealed key of the design was opened, every time.
UNBLINDING = f"{REPORT}/unblinding.json"
SUPERSEDED = "superseded"

#: What a new design replaces: the design itself and every result of the old plan.
PUBLIC_STUDY_FILES = (SPEC, PLAN, DESIGN, CORRELATION_MAP, RUNS, OUTCOMES, SCORES, RESPONSES, REPORT)


def utc_now() -> str:
    """The current time as ISO 8601 UTC, to the second."""
    return datetime.now(UTC).replace(microsecond=0).isoformat()


def plan_content(header: Sequence[str], rows: Iterable[Sequence[str]]) -> bytes:
    """plan.csv as `StudyFolder.read_plan` reads it back."""
    return table_text(header, rows).encode()


def json_content(record: Mapping[str, Any]) -> bytes:
    """design.json or the sealed key as `StudyFolder.read_design` and `read_sealed` read them back."""
    return (json.dumps(record, indent=1) + "\n").encode()


@dataclass(frozen=True)
class StudyFolder:
    """One study's folder (the current directory unless --study says otherwise)."""

    root: Path

    def path(self, name: str) -> Path:
        return self.root / name

    def run_log(self, code: str) -> Path:
        """runs/<code>.mcap, the log of a run."""
        return self.path(RUNS) / f"{code}{RUN_LOG_SUFFIX}"

    def run_figure(self, code: str) -> Path:
        """runs/<code>.png, the picture of a run."""
        return self.run_log(code).with_suffix(RUN_FIGURE_SUFFIX)

    def sealed_run(self, code: str) -> Path:
        """sealed/runs/<code>.json, a blinded run's controller records."""
        return self.path(SEALED_RUNS) / f"{code}.json"

    def sealed_failure(self, code: str) -> Path:
        """sealed/runs/<code>.error.txt, what went wrong in a blinded run (it may name the controller)."""
        return self.path(SEALED_RUNS) / f"{code}.error.txt"

    def has_plan(self) -> bool:
        return self.path(PLAN).exists() or self.path(DESIGN).exists()

    def require_plan(self) -> None:
        """Raise StudyError unless a design has been made here."""
        if not self.path(PLAN).exists() or not self.path(DESIGN).exists():
            raise StudyError(f"no plan in {self.root.resolve()} ({PLAN} and {DESIGN}): run `trials design` first")

    def read_design(self) -> dict[str, Any]:
        """design.json as a dict."""
        self.require_plan()
        try:
            return json.loads(self.path(DESIGN).read_text(encoding="utf-8"))
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise StudyError(f"{self.path(DESIGN)} is damaged: {exc}") from None

    def read_plan(self) -> list[dict[str, str]]:
        """plan.csv as one dict per run, in run order."""
        self.require_plan()
        with self.path(PLAN).open(newline="", encoding="utf-8") as handle:
            return list(csv.DictReader(handle))

    def read_sealed(self) -> SealedAllocation:
        """The sealed key, checked against the commitment in design.json."""
        blinding = self.read_design().get("blinding")
        if not blinding:
            raise StudyError(f"the study in {self.root} is not blinded: it has no sealed key")
        path = self.path(ALLOCATION)
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise StudyError(f"the sealed key {path} is missing") from None
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise StudyError(f"the sealed key {path} is damaged: {exc}") from None
        try:
            sealed = SealedAllocation.from_dict(data, str(path))
            verify(sealed, blinding["commitment"]["digest"])
        except DesignError as exc:
            raise StudyError(f"{exc} ({path})") from None
        return sealed

    def supersede(self, names: tuple[str, ...], sealed_names: tuple[str, ...] = ()) -> Path | None:
        """Move existing entries aside into superseded/<UTC time>/; returns that folder if any moved."""
        stamp = utc_now().replace(":", "")
        public = [name for name in names if self.path(name).exists()]
        secret = [name for name in sealed_names if self.path(name).exists()]
        for name, base in [(n, self.path(SUPERSEDED) / stamp) for n in public] + [
            (n, self.path(SEALED) / SUPERSEDED / stamp) for n in secret
        ]:
            target = base / Path(name).name
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.move(str(self.path(name)), str(target))
        return self.path(SUPERSEDED) / stamp if public else None
