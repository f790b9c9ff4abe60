"""The study folder: the name of every file in it, and the design's files (plan.csv, design.json,
the sealed key) written and read back.

This module is the one place that names the study's files (docs/study_folder.md, docs/architecture.md). The content of
each other file has one module: study.toml `designs.spec`, rubric.toml `analysis.scoring`,
outcomes.csv `trials.outcomes`, scores.csv `trials.scores`, responses.csv `trials.responses`,
runs/<code>.mcap `robot_logs.run_log`, runs/.lock `trials.runner`, sealed/runs/ `trials.sealed_runs`,
run_events.csv `trials.run_events`, logs/ `trials.attached_logs`, console/access.json `trials.console.access`,
unblinding.json `trials.study_data`, the rest of report/ `trials.commands.report`, power/power.csv
`trials.power.campaigns`, the rest of power/ `trials.power.study_power`. Files a
new design replaces are moved to superseded/<UTC time>/ (sealed ones to
sealed/superseded/<UTC time>/; `-2`, `-3` ... after the time when that second's folder is taken), never deleted.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import os
import shutil
import tomllib
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from designs import export
from designs.blinding import SealedAllocation, canonical_bytes, verify
from designs.errors import DesignError
from designs.spec import LOG_COLUMN
from robot_logs.figure_files import FORMATS
from trials.atomic import writing
from trials.csv_table import read_rows, table_text
from trials.errors import StudyError

SPEC = "study.toml"
PLAN = "plan.csv"
DESIGN = "design.json"
CORRELATION_MAP = "correlation_map.png"
DESIGN_EVALUATION = "design_evaluation.png"
#: The design figures' SVG twins, drawn with the PNGs by `trials design --figures`.
CORRELATION_MAP_SVG = "correlation_map.svg"
DESIGN_EVALUATION_SVG = "design_evaluation.svg"
#: The design figures, PNG and SVG.
DESIGN_FIGURES = (CORRELATION_MAP, CORRELATION_MAP_SVG, DESIGN_EVALUATION, DESIGN_EVALUATION_SVG)


def evaluated_figures(stem: str) -> tuple[str, ...]:
    """The design figures of a plan brought to `trials design --evaluate` or `--compare --figures`, in DESIGN_FIGURES'
    order, named after the plan file's stem (`<stem>.correlation_map.png`): never the study's own figures' names."""
    return tuple(f"{stem}.{name}" for name in DESIGN_FIGURES)
#: The researcher's own thresholds for the report's rubric, if the study has any.
RUBRIC = "rubric.toml"
SEALED = "sealed"
ALLOCATION = f"{SEALED}/allocation.json"
#: A blinded study's spec as the researcher wrote it, naming the real levels.
SEALED_SPEC = f"{SEALED}/spec.toml"
#: A blinded study's own controllers (study.toml's `[controllers]` table), kept out of the public study.toml.
SEALED_CONTROLLERS = f"{SEALED}/controllers.toml"
#: A blinded study's controller records per run (`sealed_run`), kept out of the public logs.
SEALED_RUNS = f"{SEALED}/runs"
RUNS = "runs"
#: Held by the one `trials run` working on the study.
RUN_LOCK = f"{RUNS}/.lock"
RUN_LOG_SUFFIX = ".mcap"
#: The picture of a run beside its log (`trials log show`), in every format a figure is saved in.
RUN_FIGURE_SUFFIXES = FORMATS
#: Beside a run that failed, its one-line reason.
RUN_FAILURE_SUFFIX = ".failed.txt"
#: Live runs (`trials run --robot`): the state of the run on the robot now, for the console (public: no controller in it).
LIVE_STATE = f"{RUNS}/live.json"
#: Its appearance stops the live run at once: the console's e-stop.
LIVE_ESTOP = f"{RUNS}/estop"
#: Logs of live runs that were aborted (e-stop, stale sensors, a signal), kept with why; the run stays pending.
ABORTED_RUNS = f"{RUNS}/aborted"
OUTCOMES = "outcomes.csv"
SCORES = "scores.csv"
RESPONSES = "responses.csv"
REPORT = "report"
REPORT_MARKDOWN = f"{REPORT}/report.md"
REPORT_HTML = f"{REPORT}/report.html"
REPORT_RECORD = f"{REPORT}/report.json"
REPORT_FIGURES = f"{REPORT}/figures"
#: The blinded report as it was before the first `--unblind` replaced it.
REPORT_BLINDED = f"{REPORT}/blinded"
#: Every table of the report as CSV.
REPORT_TABLES = f"{REPORT}/tables"
#: When the sealed key of the design was opened, every time: beside the report, not in it, so that deleting or remaking
#: report/ keeps the record. Studies unblinded before 0.3 have it in report/ (`UNBLINDING_IN_REPORT`), read still.
UNBLINDING = "unblinding.json"
#: The pre-registration `trials design` writes (`trials.preregistration`).
PREREGISTRATION = "preregistration.md"
UNBLINDING_IN_REPORT = f"{REPORT}/unblinding.json"
SUPERSEDED = "superseded"
#: The experimenter's record of each run on the field day: started, finished, aborted, notes (`trials.run_events`).
RUN_EVENTS = "run_events.csv"
#: Robot logs uploaded through `trials serve`, one per run (`trials.attached_logs`).
LOGS = "logs"
#: The console's owner-only access keys: the experimenter's token and the key that signs links and cookies.
CONSOLE_ACCESS = "console/access.json"
#: `trials power`'s folder (or --out): finished closed-loop campaigns, every figure (JSON), the tables (Markdown), the plot.
POWER = "power"
POWER_CAMPAIGNS = f"{POWER}/power.csv"
POWER_RECORD = f"{POWER}/power.json"
POWER_MARKDOWN = f"{POWER}/power.md"
POWER_FIGURE = f"{POWER}/power.png"

#: What a new design replaces: the design itself and every result of the old plan.
PUBLIC_STUDY_FILES = (SPEC, PLAN, DESIGN, PREREGISTRATION, *DESIGN_FIGURES, RUNS, OUTCOMES, SCORES, RESPONSES, REPORT, UNBLINDING, RUN_EVENTS, LOGS)
#: Its sealed part: the key, the spec naming the real levels, and the sealed records of the old plan's runs.
SEALED_STUDY_FILES = (ALLOCATION, SEALED_SPEC, SEALED_CONTROLLERS, SEALED_RUNS)


def private_folder(folder: StudyFolder, path: Path) -> None:
    """Create `path` (sealed/ or a folder in it) and each folder from sealed/ down to it, owner-only (0700)."""
    sealed = folder.path(SEALED)
    for level in [*(sealed / above for above in reversed(path.relative_to(sealed).parents)), path]:
        with writing(level):
            level.mkdir(parents=True, exist_ok=True)
            level.chmod(0o700)


def minute_ns(stamp_ns: int) -> int:
    """A time in ns since 1970 moved back to the start of its minute: how a blinded study gives every public time."""
    return stamp_ns - stamp_ns % 60_000_000_000


def to_the_minute(*paths: Path) -> None:
    """Set each path's modification time to the start of its minute, as a blinded study gives every
    public time: to the second, the times of its runs tell the controllers apart."""
    for path in paths:
        minute = minute_ns(path.stat().st_mtime_ns)
        os.utime(path, ns=(minute, minute))


def study_table(spec: Path, name: str) -> dict[str, Any] | None:
    """study.toml's `[name]` table as written; None when the file or the table is missing.

    Raises:
        StudyError: unreadable TOML, values nested too deeply for tomllib, or `name` not a table, naming the file.
    """
    try:
        data = tomllib.loads(spec.read_text(encoding="utf-8"))
    except FileNotFoundError:
        return None
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise StudyError(f"{spec}: cannot read its [{name}] table ({exc})") from None
    except RecursionError:  # tomllib parses nested arrays and inline tables recursively
        raise StudyError(f"{spec}: cannot read its [{name}] table (values nested too deeply to read)") from None
    table = data.get(name)
    if table is not None and not isinstance(table, dict):
        raise StudyError(f"{spec}: {name} must be a table ([{name}]), got {type(table).__name__}")
    return table


def utc_now(to_the_minute: bool = False) -> str:
    """The current time as ISO 8601 UTC, to the second (or to the start of its minute, as a blinded study's times are)."""
    now = datetime.now(UTC).replace(microsecond=0)
    return (now.replace(second=0) if to_the_minute else now).isoformat()


def plan_content(header: Sequence[str], rows: Iterable[Sequence[str]]) -> bytes:
    """plan.csv as `StudyFolder.read_plan` reads it back."""
    return table_text(header, rows).encode()


def plan_digest(header: Sequence[str], rows: Iterable[Sequence[str]]) -> dict[str, str]:
    """design.json's `plan` field: the SHA-256 of plan.csv's design columns written out as `trials design`
    writes them. The file's cells are hashed this way, not its bytes, so a re-save that keeps every
    cell (a byte order mark, CRLF line ends, padding) still matches; any changed cell, row or column does not.
    """
    return {"file": PLAN, "sha256": hashlib.sha256(plan_content(header, rows)).hexdigest()}


#: design.json's field holding the digest of the rest of its content (`design_digest`).
DESIGN_DIGEST = "digest"


def design_digest(record: Mapping[str, Any]) -> dict[str, str]:
    """design.json's `digest` field: the SHA-256 of every other field as canonical JSON (keys sorted, no spaces, UTF-8).

    Reading design.json checks it, so a hand edit of any field (the seed, a run, a field added by a later release)
    is refused instead of silently changing what the runs do; a reformatted file (indents, key order) still matches.
    """
    content = {key: value for key, value in record.items() if key != DESIGN_DIGEST}
    return {"covers": "every other field of design.json, as JSON with sorted keys, no spaces, UTF-8",
            "sha256": hashlib.sha256(canonical_bytes(content)).hexdigest()}


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

    def run_figures(self, code: str) -> tuple[Path, ...]:
        """runs/<code>.png and .svg, the picture of a run."""
        return tuple(self.run_log(code).with_suffix(suffix) for suffix in RUN_FIGURE_SUFFIXES)

    def run_failure(self, code: str) -> Path:
        """runs/<code>.failed.txt, why the last attempt at a run failed (`trials.runner`; gone once it finishes)."""
        return self.run_log(code).with_suffix(RUN_FAILURE_SUFFIX)

    def aborted_log(self, code: str, stamp: str) -> Path:
        """runs/aborted/<code>-<stamp>.mcap, the log of a live run aborted at `stamp` (a UTC time without colons)."""
        return self.path(ABORTED_RUNS) / f"{code}-{stamp}{RUN_LOG_SUFFIX}"

    def aborted_sealed_run(self, code: str, stamp: str) -> Path:
        """sealed/runs/aborted/<code>-<stamp>.json.gz, the sealed record of that aborted blinded run."""
        return self.path(SEALED_RUNS) / "aborted" / f"{code}-{stamp}.json.gz"

    def sealed_run(self, code: str) -> Path:
        """sealed/runs/<code>.json.gz, a blinded run's controller output (`trials.sealed_runs`)."""
        return self.path(SEALED_RUNS) / f"{code}.json.gz"

    def older_sealed_run(self, code: str) -> Path:
        """sealed/runs/<code>.json, a blinded run's record as earlier releases wrote it (plain JSON)."""
        return self.path(SEALED_RUNS) / f"{code}.json"

    def sealed_failure(self, code: str) -> Path:
        """sealed/runs/<code>.error.txt.gz, what went wrong in a blinded run (it may name the controller)."""
        return self.path(SEALED_RUNS) / f"{code}.error.txt.gz"

    def has_plan(self) -> bool:
        return self.path(PLAN).exists() or self.path(DESIGN).exists()

    def require_plan(self) -> None:
        """Raise StudyError unless a design has been made here."""
        if not self.path(PLAN).exists() or not self.path(DESIGN).exists():
            raise StudyError(f"no plan in {self.root.resolve()} ({PLAN} and {DESIGN}): run `trials design` first")

    def read_design(self) -> dict[str, Any]:
        """design.json as a dict, with the fields every reader relies on checked."""
        self.require_plan()
        path = self.path(DESIGN)
        try:
            record = json.loads(path.read_text(encoding="utf-8"))
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise StudyError(f"{path} is damaged: {exc}") from None
        except RecursionError:  # json decodes nested arrays and objects recursively
            raise StudyError(f"{path} is damaged: values nested too deeply to read") from None
        if not isinstance(record, dict) or record.get("format") != export.FORMAT:
            raise StudyError(f"{path} is not a design record (its format field must be {export.FORMAT!r}); `trials design --force` makes a new plan")
        for key, kind in (("seed", int), ("factors", list), ("design", list)):
            if not isinstance(record.get(key), kind) or isinstance(record.get(key), bool):
                raise StudyError(f"{path}: field {key!r} is missing or not a {kind.__name__}; `trials design --force` makes a new plan")
        recorded = record.get(DESIGN_DIGEST)  # absent from design.json of earlier releases (`trials status` says so)
        if recorded is not None and (not isinstance(recorded, dict) or recorded.get("sha256") != design_digest(record)["sha256"]):
            raise StudyError(f"{path} was edited after `trials design` wrote it (its content no longer matches its digest): "
                             "put back the file as it was, or make a new plan with `trials design --force`")
        return record

    def read_plan(self) -> list[dict[str, str]]:
        """plan.csv as one dict per run, in run order, checked against design.json (`check_plan`)."""
        design = self.read_design()
        path = self.path(PLAN)
        header, rows = read_rows(path, same_width=True)
        check_plan(path, header, rows, design, self.path(DESIGN))
        return [dict(zip(header, cells)) for _, cells in rows]

    def read_sealed(self) -> SealedAllocation:
        """The sealed key, checked against the commitment in design.json."""
        return self.open_sealed()[0]

    def open_sealed(self, recorded: str | None = None) -> tuple[SealedAllocation, str]:
        """The sealed key, checked against design.json's commitment and what the researcher `recorded` outside the study
        (when given): the pre-registration's digest for a study that has one (`trials.preregistration.check_recorded`),
        else the key's commitment; with the sentence saying which check was made."""
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
        except RecursionError:
            raise StudyError(f"the sealed key {path} is damaged: values nested too deeply to read") from None
        registered = self.path(PREREGISTRATION).exists()
        try:
            sealed = SealedAllocation.from_dict(data, str(path))
            commitment = blinding["commitment"]
            check = verify(data, sealed, commitment["algorithm"], commitment["digest"], None if registered else recorded)
        except DesignError as exc:
            raise StudyError(f"{exc} ({path})") from None
        except (KeyError, TypeError):
            raise StudyError(f"{self.path(DESIGN)}: blinding.commitment lacks its algorithm or digest") from None
        if registered and recorded is not None:
            from trials.preregistration import check_recorded  # it reads the study through this class

            check = check_recorded(self, recorded)
        return sealed, check

    def keep_blinded_report(self) -> Path | None:
        """Move the blinded report (report.md, .html, .json, figures/, tables/) to report/blinded/ before an
        unblinded one is written; an earlier report/blinded/ moves to superseded/<UTC time>/.
        Returns report/blinded/ if a report moved."""
        names = [name for name in (REPORT_MARKDOWN, REPORT_HTML, REPORT_RECORD, REPORT_FIGURES, REPORT_TABLES) if self.path(name).exists()]
        if not names:
            return None
        self.supersede((REPORT_BLINDED,))
        target = self.path(REPORT_BLINDED)
        target.mkdir(parents=True)
        for name in names:
            shutil.move(str(self.path(name)), str(target / Path(name).name))
        return target

    def aside_stamp(self) -> str:
        """A new name for superseded/<name>/ and sealed/superseded/<name>/: the UTC time to the second without colons,
        then `-2`, `-3` ... while that name is taken. The public folder is made here, exclusively, so two moves in
        the same second (or two processes at once) never share a folder and never overwrite each other's files."""
        time = utc_now().replace(":", "")
        with writing(self.path(SUPERSEDED)):
            self.path(SUPERSEDED).mkdir(parents=True, exist_ok=True)
        for stamp in itertools.chain([time], (f"{time}-{count}" for count in itertools.count(2))):
            with writing(self.path(SUPERSEDED) / stamp):
                try:
                    (self.path(SUPERSEDED) / stamp).mkdir()
                except FileExistsError:
                    continue
            if not (self.path(SEALED) / SUPERSEDED / stamp).exists():
                return stamp
            (self.path(SUPERSEDED) / stamp).rmdir()  # ours, empty: a sealed folder of that name exists without it
        raise AssertionError("the names above never run out")

    def copy_aside(self, names: tuple[str, ...]) -> Path:
        """Copy existing entries (files) into a new superseded/<UTC time>/ (`aside_stamp`), leaving them in place;
        returns that folder."""
        target = self.path(SUPERSEDED) / self.aside_stamp()
        try:
            for name in names:
                if self.path(name).exists():
                    shutil.copy2(self.path(name), target / Path(name).name)
        except BaseException:
            shutil.rmtree(target, ignore_errors=True)  # no half-made copy is left to pass for the old files
            raise
        return target

    def supersede(self, names: tuple[str, ...], sealed_names: tuple[str, ...] = ()) -> Path | None:
        """Move existing entries aside into a new superseded/<UTC time>/ (sealed ones into sealed/superseded/<UTC
        time>/, `aside_stamp`); returns the public folder if anything public moved."""
        public = [name for name in names if self.path(name).exists()]
        secret = [name for name in sealed_names if self.path(name).exists()]
        if not public and not secret:
            return None
        stamp = self.aside_stamp()
        if secret:
            private_folder(self, self.path(SEALED) / SUPERSEDED / stamp)
        for name, base in [(n, self.path(SUPERSEDED) / stamp) for n in public] + [
            (n, self.path(SEALED) / SUPERSEDED / stamp) for n in secret
        ]:
            target = base / Path(name).name
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.move(str(self.path(name)), str(target))
        if not public:
            (self.path(SUPERSEDED) / stamp).rmdir()
            return None
        return self.path(SUPERSEDED) / stamp


def check_plan(path: Path, header: list[str], rows: list[tuple[int, list[str]]], design: dict[str, Any], design_path: Path) -> None:
    """StudyError unless plan.csv holds exactly the runs design.json planned: the same columns (and an
    optional `Log` column), the same run codes once each in the same order, the same settings, and,
    where design.json records one, the same digest. `trials design --force` is the way to change a plan."""
    try:
        expected_header, expected_rows = export.plan_from_record(design, str(design_path))
    except DesignError as exc:
        raise StudyError(str(exc)) from None
    remedy = "plan.csv must stay as `trials design` wrote it (`trials design --force` makes a new plan)"
    for name in header:
        if header.count(name) > 1:
            raise StudyError(f"{path}: column {name!r} appears {header.count(name)} times")
        if name not in expected_header and name != LOG_COLUMN:
            raise StudyError(f"{path}: column {name!r} is not in the design (its columns are {','.join(expected_header)})")
    missing = [name for name in expected_header if name not in header]
    if missing:
        raise StudyError(f"{path}: column {missing[0]!r} is missing (the design's columns are {','.join(expected_header)}); {remedy}")
    planned = {cells[1]: cells for cells in expected_rows}
    code_at = header.index("run_code")
    seen: dict[str, int] = {}
    for line, cells in rows:
        code = cells[code_at]
        if code in seen:
            raise StudyError(f"{path} line {line}: run {code!r} appears again (first on line {seen[code]}); {remedy}")
        seen[code] = line
        if code not in planned:
            raise StudyError(f"{path} line {line}: run {code!r} is not in the design's {len(planned)} runs; {remedy}")
        for name, value in zip(expected_header, planned[code]):
            cell = cells[header.index(name)]
            if cell != value:
                raise StudyError(f"{path} line {line} (run {code}): {name} is {cell!r}, but the design has {value!r}; {remedy}")
    absent = [cells[1] for cells in expected_rows if cells[1] not in seen]
    if absent:
        raise StudyError(f"{path}: run {absent[0]} of the design is missing ({len(rows)} of {len(expected_rows)} rows); {remedy}")
    for (line, cells), expected in zip(rows, expected_rows):
        if cells[code_at] != expected[1]:
            raise StudyError(f"{path} line {line}: run {cells[code_at]} is out of plan order (run {expected[1]} comes here); {remedy}")
    recorded = design.get("plan")
    if recorded is not None and recorded != plan_digest(expected_header, expected_rows):
        raise StudyError(f"{design_path}: its plan digest does not match its own runs (was design.json edited?); "
                         "`trials design --force` makes a new plan")
