"""The study folder: where each file lives, reading the plan back, and the sealed key.

Layout (see docs/architecture.md): study.toml, plan.csv, design.json, correlation_map.png,
sealed/allocation.json, runs/<code>.mcap, outcomes.csv, scores.csv, responses.csv, report/.
Files a new design replaces are moved to superseded/<UTC time>/ (sealed ones to
sealed/superseded/<UTC time>/), never deleted.
"""

from __future__ import annotations

import csv
import json
import shutil
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from designs.blinding import SealedAllocation, verify
from designs.errors import DesignError
from trials.errors import StudyError

SPEC = "study.toml"
PLAN = "plan.csv"
DESIGN = "design.json"
CORRELATION_MAP = "correlation_map.png"
SEALED = "sealed"
ALLOCATION = "sealed/allocation.json"
RUNS = "runs"
OUTCOMES = "outcomes.csv"
SCORES = "scores.csv"
RESPONSES = "responses.csv"
REPORT = "report"
SUPERSEDED = "superseded"

#: What a new design replaces: the design itself and every result of the old plan.
PUBLIC_STUDY_FILES = (SPEC, PLAN, DESIGN, CORRELATION_MAP, RUNS, OUTCOMES, SCORES, RESPONSES, REPORT)


def utc_now() -> str:
    """The current time as ISO 8601 UTC, to the second."""
    return datetime.now(UTC).replace(microsecond=0).isoformat()


@dataclass(frozen=True)
class StudyFolder:
    """One study's folder (the current directory unless --study says otherwise)."""

    root: Path

    def path(self, name: str) -> Path:
        return self.root / name

    def has_plan(self) -> bool:
        return self.path(PLAN).exists() or self.path(DESIGN).exists()

    def require_plan(self) -> None:
        """Raise StudyError unless a design has been made here."""
        if not self.path(PLAN).exists() or not self.path(DESIGN).exists():
            raise StudyError(f"no plan in {self.root.resolve()} (plan.csv and design.json): run `trials design` first")

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
