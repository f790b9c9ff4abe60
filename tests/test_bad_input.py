"""Bad input to every command, one table row per case: the command, the input it meets, the text its
one `error:` line must hold; each must exit 2 and leave every file as it was (issue 17's cases, and
more the other tests lack). Then the re-saves that must still read, the plan digest, and a full disk.
"""

from __future__ import annotations

import csv
import errno
import hashlib
import json
import math
import os
import shutil
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from trials import atomic
from trials.cli import main
from trials.errors import DiskFullError
from trials.option_types import number
from trials.pool import Failure
from trials.run_settings import MAX_NOISE_M, settings_from_table
from trials.study import StudyFolder, design_digest

SPEC_HEAD = '[study]\nname = "bad"\nruns = 8\n\n'
SPEED = '[[factors]]\nname = "Speed"\ntype = "continuous"\nlow = 0.5\nhigh = 1.5\n'


@dataclass(frozen=True)
class Case:
    """One bad input: `prepare(tmp, study)` makes it, `args` (with {tmp} and {study}) meet it."""

    name: str
    args: tuple[str, ...]
    expected: str
    prepare: Callable[[Path, Path], None] = lambda tmp, study: None


def spec(text: str) -> Callable[[Path, Path], None]:
    """Write `text` as {tmp}/spec.toml."""
    return lambda tmp, study: (tmp / "spec.toml").write_text(text, encoding="utf-8")


def plan_bytes(change: Callable[[bytes], bytes]) -> Callable[[Path, Path], None]:
    """Rewrite the study's plan.csv through `change`."""
    def prepare(tmp: Path, study: Path) -> None:
        path = study / "plan.csv"
        path.write_bytes(change(path.read_bytes()))
    return prepare


def plan_rows(change: Callable[[list[list[str]]], list[list[str]]]) -> Callable[[Path, Path], None]:
    """Rewrite the study's plan.csv (header first) through `change`, as a careful hand edit would."""
    def prepare(tmp: Path, study: Path) -> None:
        path = study / "plan.csv"
        with path.open(newline="", encoding="utf-8") as handle:
            rows = change(list(csv.reader(handle)))
        with path.open("w", newline="", encoding="utf-8") as handle:
            csv.writer(handle, lineterminator="\n").writerows(rows)
    return prepare


def edit_cell(line: int, column: str, value: str) -> Callable[[list[list[str]]], list[list[str]]]:
    def change(rows: list[list[str]]) -> list[list[str]]:
        rows[line - 1][rows[0].index(column)] = value
        return rows
    return change


def drop_column(column: str) -> Callable[[list[list[str]]], list[list[str]]]:
    def change(rows: list[list[str]]) -> list[list[str]]:
        at = rows[0].index(column)
        return [row[:at] + row[at + 1:] for row in rows]
    return change


def write(name: str, content: str | bytes) -> Callable[[Path, Path], None]:
    """Write {tmp}/name (a folder when content is None)."""
    def prepare(tmp: Path, study: Path) -> None:
        path = tmp / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(content if isinstance(content, bytes) else content.encode())
    return prepare


def append(path: Path, text: str) -> None:
    """Add text at the end of a file, as a researcher's edit would."""
    path.write_text(path.read_text(encoding="utf-8") + text, encoding="utf-8")


def folder(name: str) -> Callable[[Path, Path], None]:
    return lambda tmp, study: (tmp / name).mkdir()


CASES = [
    # trials design: where the spec and study are
    Case("study is a file", ("design", "--study", "{tmp}/afile"), "argument --study: {tmp}/afile is a file, not a folder",
         write("afile", "x")),
    Case("spec is a folder", ("design", "--spec", "{tmp}/adir", "--study", "{tmp}/new"), "argument --spec: {tmp}/adir is a folder, not a file",
         folder("adir")),
    Case("no spec file", ("design", "--spec", "{tmp}/none.toml", "--study", "{tmp}/new"), "argument --spec: no file {tmp}/none.toml"),
    Case("existing plan", ("design", "--study", "{study}"), "already has a plan; pass --force to replace it"),
    # trials design: options
    Case("negative seed", ("design", "--seed", "-1", "--study", "{tmp}/new"),
         "argument --seed: expected a whole number from 0 to 9007199254740991, got '-1'"),
    Case("negative allocation seed", ("design", "--ab", "--allocation-seed", "-3", "--study", "{tmp}/new"),
         "argument --allocation-seed: expected a whole number from 0"),
    Case("snr nan", ("design", "--snr", "nan", "--study", "{tmp}/new"), "argument --snr: expected a finite number in (0, 100], got 'nan'"),
    Case("snr inf", ("design", "--snr", "inf", "--study", "{tmp}/new"), "argument --snr: expected a finite number in (0, 100], got 'inf'"),
    Case("snr negative", ("design", "--snr", "-1", "--study", "{tmp}/new"), "argument --snr: expected a finite number in (0, 100], got '-1'"),
    Case("runs far too many", ("design", "--runs", "100000", "--study", "{tmp}/new"),
         "argument --runs: expected a whole number from 1 to 1000, got '100000'"),
    Case("search too large", ("design", "--runs", "1000", "--starts", "1000", "--model", "main + interactions", "--study", "{tmp}/new"),
         "starts x runs x factors x p^2 = 1000 x 1000 x 3 x 10^2 = 300,000,000 exceeds 100,000,000"),
    Case("starts zero", ("design", "--starts", "0", "--study", "{tmp}/new"), "argument --starts: expected a whole number from 1 to 1000, got '0'"),
    Case("runs too few from the spec", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "runs = 2 is too few: the model has p = 3 parameters", spec('[study]\nruns = 2\n\n' + SPEED.replace("Speed", "A") + SPEED.replace("Speed", "B"))),
    # trials design: the spec
    Case("runs far too many in the spec", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "spec.toml: [study]: runs must be a whole number from 1 to 1000, got 100000", spec('[study]\nruns = 100000\n\n' + SPEED)),
    Case("negative seed in the spec", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "spec.toml: [study]: seed must be a whole number from 0", spec(SPEC_HEAD.replace("runs", "seed = -4\nruns") + SPEED)),
    Case("alpha above one", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "spec.toml: [study]: alpha must be a number between 0 and 1, got 1.5", spec(SPEC_HEAD + "alpha = 1.5\n" + SPEED)),
    Case("snr zero in the spec", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "spec.toml: [study]: snr must be a number above 0 and at most 100, got 0", spec(SPEC_HEAD + "snr = 0\n" + SPEED)),
    Case("high infinite", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "spec.toml: factors[0] (Speed): high must be a finite number of magnitude at most 1e+06, got inf",
         spec(SPEC_HEAD + SPEED.replace("1.5", "inf"))),
    Case("high huge", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "factors[0] (Speed): high must be a finite number of magnitude at most 1e+06, got 1e+308",
         spec(SPEC_HEAD + SPEED.replace("1.5", "1e308"))),
    Case("low nan", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "factors[0] (Speed): low must be a finite number", spec(SPEC_HEAD + SPEED.replace("0.5", "nan"))),
    Case("discrete level infinite", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "factors[0] (N): level must be a finite number", spec(SPEC_HEAD + '[[factors]]\nname = "N"\ntype = "discrete"\nlevels = [1, 2, inf]\n')),
    Case("fixed value huge", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "factors[1] (Gap): value must be a finite number", spec(SPEC_HEAD + SPEED + '[[factors]]\nname = "Gap"\ntype = "fixed"\nvalue = 1e9\n')),
    Case("factor named order", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "factors[0] (order): 'order' is a plan.csv column of its own", spec(SPEC_HEAD + SPEED.replace("Speed", "order"))),
    Case("factor named run_code", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "factors[0] (run_code): 'run_code' is a plan.csv column of its own", spec(SPEC_HEAD + SPEED.replace("Speed", "run_code"))),
    Case("factor named Log", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "factors[0] (Log): 'Log' is a plan.csv column of its own",
         spec(SPEC_HEAD + '[[factors]]\nname = "Log"\ntype = "categorical"\nlevels = ["a.bag", "b.bag"]\n')),
    Case("mixed level types", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "factors[0] (Mode): level True is not a string",
         spec(SPEC_HEAD + '[[factors]]\nname = "Mode"\ntype = "categorical"\nlevels = ["fast", true]\n')),
    Case("unicode factor name", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "factor names must be ASCII letters, digits and _ (no spaces), got 'Geschwindigkeit_über'",
         spec(SPEC_HEAD + SPEED.replace("Speed", "Geschwindigkeit_über"))),
    Case("newline in the study name", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "name must be one line of printable text, got 'two\\nlines'", spec(SPEC_HEAD.replace('"bad"', '"two\\nlines"') + SPEED)),
    Case("too many levels", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "factors[0] (N): 21 levels; at most 20", spec(SPEC_HEAD + '[[factors]]\nname = "N"\ntype = "discrete"\nlevels = ' + str(list(range(21))) + "\n")),
    Case("too many candidate points", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "the factors span 19683 candidate points; at most 10000",
         spec(SPEC_HEAD + "".join(SPEED.replace("Speed", f"F{i}") for i in range(9)))),
    Case("unknown field", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "factors[0] (Speed): unknown field 'steps'", spec(SPEC_HEAD + SPEED + "steps = 3\n")),
    Case("spec not UTF-8", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "malformed spec.toml: not UTF-8 text", write("spec.toml", b"[study]\nname = \"\xff\"\n")),
    Case("every factor fixed", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "spec.toml: every factor is fixed; a design needs at least one varying factor",
         spec(SPEC_HEAD + '[[factors]]\nname = "A"\ntype = "fixed"\nvalue = 1\n')),
    Case("unknown table", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "spec.toml: unknown table 'extra' (expected [study], [[factors]] and optionally [anticipated], [[questionnaire]], [run], [robot], "
         "[analysis] and [controllers])",
         spec(SPEC_HEAD + "[extra]\n" + SPEED)),
    Case("arms without blind", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "factors[0] (A): arms are only for a blind factor; use levels",
         spec(SPEC_HEAD + '[[factors]]\nname = "A"\ntype = "categorical"\narms = ["x", "y"]\n')),
    Case("two factors of one name", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "spec.toml: two factors are named 'Speed'", spec(SPEC_HEAD + SPEED + SPEED)),
    Case("two blind factors", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "spec.toml: only one factor can be blind, got ['A', 'B']",
         spec(SPEC_HEAD + "".join(f'[[factors]]\nname = "{n}"\ntype = "categorical"\nlevels = ["x", "y"]\nblind = true\n' for n in "AB"))),
    # trials run: options
    Case("timeout infinite", ("run", "--timeout", "inf", "--study", "{study}"), "argument --timeout: expected a finite number in [0.4, 3600], got 'inf'"),
    Case("timeout below a step", ("run", "--timeout", "1e-9", "--study", "{study}"), "argument --timeout: expected a finite number in [0.4, 3600], got '1e-9'"),
    Case("noise nan", ("run", "--noise", "nan", "--study", "{study}"), "argument --noise: expected a finite number in [0, 10], got 'nan'"),
    Case("workers zero", ("run", "--workers", "0", "--study", "{study}"), "argument --workers: expected a whole number from 1 to 256, got '0'"),
    Case("duration zero", ("run", "--duration", "0", "--study", "{study}"), "argument --duration: expected a finite number in (0, inf), got '0'"),
    Case("study is a file (run)", ("run", "--study", "{tmp}/afile"), "argument --study: {tmp}/afile is a file, not a folder", write("afile", "x")),
    Case("newline in a run code", ("run", "--only", "AB\nCD", "--study", "{study}"), "run AB\\nCD is not in"),
    # the [run] table of study.toml (trials/run_settings.py)
    Case("run table unknown key", ("run", "--study", "{study}"),
         "study.toml [run]: unknown key 'speed' (expected perception, noise, dropout, timeout, weights)",
         lambda tmp, study: append(study / "study.toml", "\n[run]\nspeed = 2\n")),
    Case("run table noise too large", ("run", "--study", "{study}"), "study.toml [run]: noise must be a number in [0, 10], got 11",
         lambda tmp, study: append(study / "study.toml", "\n[run]\nnoise = 11\n")),
    Case("run table dropout of one", ("status", "--study", "{study}"), "study.toml [run]: dropout must be a number in [0, 1), got 1",
         lambda tmp, study: append(study / "study.toml", "\n[run]\ndropout = 1\n")),
    Case("run table unknown perception", ("run", "--study", "{study}"), "study.toml [run]: perception must be one of positions, lidar, got 'sonar'",
         lambda tmp, study: append(study / "study.toml", '\n[run]\nperception = "sonar"\n')),
    # usage errors point to the --help of the command typed; seeds stay exact as doubles
    Case("unknown option of design", ("design", "--bogus", "--study", "{tmp}/new"), "unrecognized arguments: --bogus (see `trials design --help`)"),
    Case("unknown option of log inspect", ("log", "inspect", "x.mcap", "--bogus"), "unrecognized arguments: --bogus (see `trials log inspect --help`)"),
    Case("seed of 2^53", ("design", "--seed", "9007199254740992", "--study", "{tmp}/new"),
         "argument --seed: expected a whole number from 0 to 9007199254740991, got '9007199254740992'"),
    # trials status and run codes for log inspect
    Case("status of no study", ("status", "--study", "{tmp}/new"), "no plan in"),
    Case("log inspect of an unknown run", ("log", "inspect", "ZZZZZ", "--study", "{study}"), "no log of run ZZZZZ in"),
    # trials run: plan.csv damaged or edited
    Case("plan not UTF-8", ("run", "--study", "{study}"), "plan.csv is not UTF-8 text (invalid start byte at byte 20)",
         plan_bytes(lambda b: b[:20] + b"\xff" + b[21:])),
    Case("plan is binary", ("run", "--study", "{study}"), "plan.csv holds binary data (a NUL byte at byte 0), not CSV text",
         plan_bytes(lambda b: bytes(range(256)))),
    Case("plan empty", ("run", "--study", "{study}"), "plan.csv is empty: it has no header line", plan_bytes(lambda b: b"")),
    Case("plan separated by ;", ("run", "--study", "{study}"), "plan.csv is separated by ';', not ','",
         plan_bytes(lambda b: b.replace(b",", b";"))),
    Case("plan short row", ("run", "--study", "{study}"), "plan.csv line 3: 5 cells, but the header has 6",
         plan_bytes(lambda b: b"\n".join(line.rsplit(b",", 1)[0] if i == 2 else line for i, line in enumerate(b.split(b"\n"))))),
    Case("plan factor column deleted", ("run", "--study", "{study}"), "plan.csv: column 'Direction' is missing", plan_rows(drop_column("Direction"))),
    Case("plan column added", ("run", "--study", "{study}"), "plan.csv: column 'Weather' is not in the design",
         plan_rows(lambda rows: [row + (["Weather"] if i == 0 else ["rain"]) for i, row in enumerate(rows)])),
    Case("plan run code duplicated", ("run", "--study", "{study}"), "plan.csv line 3: run 'NGAC3' appears again (first on line 2)",
         plan_rows(edit_cell(3, "run_code", "NGAC3"))),
    Case("plan extra row", ("run", "--study", "{study}"), "plan.csv line 20: run 'QQQQQ' is not in the design's 18 runs",
         plan_rows(lambda rows: [*rows, ["19", "QQQQQ", *rows[1][2:]]])),
    Case("plan row deleted", ("run", "--study", "{study}"), "plan.csv: run NGAC3 of the design is missing (17 of 18 rows)",
         plan_rows(lambda rows: [rows[0], *rows[2:]])),
    Case("plan rows swapped", ("run", "--study", "{study}"), "plan.csv line 2: run N3W3X is out of plan order (run NGAC3 comes here)",
         plan_rows(lambda rows: [rows[0], rows[2], rows[1], *rows[3:]])),
    Case("plan setting edited", ("run", "--study", "{study}"),
         "plan.csv line 4 (run 6PKG7): Pedestrians is '3', but the design has '6'", plan_rows(edit_cell(4, "Pedestrians", "3"))),
    Case("plan edited (score)", ("score", "NGAC3", "2", "--study", "{study}"),
         "plan.csv line 2 (run NGAC3): Direction is 'Parallel', but the design has 'Crossing'",
         plan_rows(edit_cell(2, "Direction", "Parallel"))),
    Case("design.json emptied", ("report", "--study", "{study}"), "design.json is not a design record (its format field must be 'navtrials.design/1')",
         lambda tmp, study: (study / "design.json").write_text("{}")),
    Case("design.json seed edited", ("run", "--study", "{study}"),
         "design.json was edited after `trials design` wrote it (its content no longer matches its digest)",
         lambda tmp, study: _edit_design(study, lambda d: d.update(seed=d["seed"] + 1), redigest=False)),
    Case("design.json efficiency edited (report)", ("report", "--study", "{study}"), "design.json was edited after `trials design`",
         lambda tmp, study: _edit_design(study, lambda d: d["diagnostics"].update(d_efficiency=100.0), redigest=False)),
    Case("design.json field added (status)", ("status", "--study", "{study}"), "design.json was edited after `trials design`",
         lambda tmp, study: _edit_design(study, lambda d: d.update(note="checked"), redigest=False)),
    Case("design.json digest not a record", ("status", "--study", "{study}"), "design.json was edited after `trials design`",
         lambda tmp, study: _edit_design(study, lambda d: d.update(digest="0" * 64), redigest=False)),
    Case("design.json seed gone", ("run", "--study", "{study}"), "design.json: field 'seed' is missing or not a int",
         lambda tmp, study: _edit_design(study, lambda d: d.pop("seed"))),
    Case("plan digest differs", ("run", "--study", "{study}"), "design.json: its plan digest does not match its own runs",
         lambda tmp, study: _edit_design(study, lambda d: d["plan"].update(sha256="0" * 64))),
    Case("design settings edited", ("run", "--study", "{study}"), "plan.csv line 2 (run NGAC3): Pedestrians is '2', but the design has '6'",
         lambda tmp, study: _edit_design(study, lambda d: d["design"][0]["settings"].__setitem__(0, 1.0))),
    Case("outcomes not UTF-8", ("run", "--study", "{study}"), "outcomes.csv is not UTF-8 text (invalid start byte at byte 0)",
         lambda tmp, study: (study / "outcomes.csv").write_bytes(b"\xff\xfe")),
    Case("log show of an unfinished run", ("log", "show", "NGAC3", "--study", "{study}"), "no log of run NGAC3 in"),
    # trials score / respond
    Case("recorded_utc not a time", ("score", "--import", "{tmp}/sheet.csv", "--study", "{study}"),
         "line 2 of sheet.csv: recorded_utc must be an ISO 8601 time such as 2026-05-01T14:03:00+00:00, got 'yesterday'",
         write("sheet.csv", "run_code,score,recorded_utc\nNGAC3,3,yesterday\n")),
    Case("recorded_utc without offset", ("respond", "--import", "{tmp}/sheet.csv", "--study", "{study}"),
         "line 2 of sheet.csv: recorded_utc must give its UTC offset (e.g. +00:00), got '2026-01-01T10:00:00'",
         write("sheet.csv", "run_code,participant,compliant,recorded_utc\nNGAC3,P1,yes,2026-01-01T10:00:00\n")),
    Case("respond seed negative", ("respond", "--simulate", "--seed", "-1", "--study", "{study}"), "argument --seed: expected a whole number from 0"),
    # values a parser can only refuse by running out of stack, a number no float holds, spaces a CSV reader strips, a folder
    # that cannot be made (issue 43)
    Case("spec nested 5,000 arrays deep", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "error: malformed spec.toml: values nested too deeply to read", spec(SPEC_HEAD + "deep = " + "[" * 5000 + "]" * 5000 + "\n" + SPEED)),
    Case("spec nested 3,000 inline tables deep", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "error: malformed spec.toml: values nested too deeply to read", spec(SPEC_HEAD + "deep = " + "{a = " * 3000 + "1" + "}" * 3000 + "\n" + SPEED)),
    Case("study.toml nested deep (status)", ("status", "--study", "{study}"),
         "study.toml: cannot read its [run] table (values nested too deeply to read)", lambda tmp, study: append(study / "study.toml", NESTED_TABLE)),
    Case("study.toml nested deep (run)", ("run", "--study", "{study}"),
         "study.toml: cannot read its [run] table (values nested too deeply to read)", lambda tmp, study: append(study / "study.toml", NESTED_TABLE)),
    Case("study.toml nested deep (design)", ("design", "--force", "--study", "{study}"),
         "error: malformed study.toml: values nested too deeply to read", lambda tmp, study: append(study / "study.toml", NESTED_TABLE)),
    Case("design.json nested 100,000 deep (status)", ("status", "--study", "{study}"),
         "design.json is damaged: values nested too deeply to read", lambda tmp, study: _nest_design(study)),
    Case("design.json nested 100,000 deep (run)", ("run", "--study", "{study}"),
         "design.json is damaged: values nested too deeply to read", lambda tmp, study: _nest_design(study)),
    Case("a 400-digit number in a disallowed expression", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "the number 10000000000000000000... (401 characters) is too large: numbers must be finite, below about 1.8e308 in magnitude",
         spec(SPEC_HEAD + f'disallowed = ["Speed > 1{"0" * 400}"]\n' + SPEED)),
    Case("1e999 in a constraint", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "constraints[0] 'Speed < 1e999': the number 1e999 is too large", spec(SPEC_HEAD + 'constraints = ["Speed < 1e999"]\n' + SPEED)),
    Case("a level with a leading space", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "spec.toml: factors[1] (Direction): level ' Crossing' begins or ends with a space; write 'Crossing'",
         spec(SPEC_HEAD + SPEED + '[[factors]]\nname = "Direction"\ntype = "categorical"\nlevels = [" Crossing", "Parallel"]\n')),
    Case("a level with a trailing space", ("design", "--spec", "{tmp}/spec.toml", "--study", "{tmp}/new"),
         "level 'Parallel ' begins or ends with a space; write 'Parallel'",
         spec(SPEC_HEAD + SPEED + '[[factors]]\nname = "Direction"\ntype = "categorical"\nlevels = ["Crossing", "Parallel "]\n')),
    Case("power out under /proc", ("power", "--out", "/proc/navtrials-power", "--study", "{study}"),
         "error: cannot write /proc/navtrials-power: No such file or directory"),
    # trials evaluate / train / playback
    Case("evaluate seed negative", ("evaluate", "--baseline", "constant-velocity", "--split", "eth", "--seed", "-1"),
         "argument --seed: expected a whole number from 0"),
    Case("evaluate json in a missing folder", ("evaluate", "--baseline", "constant-velocity", "--split", "eth", "--json", "{tmp}/no/such/x.json"),
         "argument --json: {tmp}/no/such/x.json: the folder {tmp}/no/such does not exist"),
    Case("evaluate garbage checkpoint", ("evaluate", "--checkpoint", "{tmp}/bad.pt", "--json", "{tmp}/x.json"),
         "bad.pt is not a readable checkpoint: a weights-only load stops at: Unsupported operand", write("bad.pt", b"garbage" * 8)),
    Case("train recipe infinite", ("train", "--recipe", "{tmp}/r.toml", "--split", "eth", "--out", "{tmp}/m.pt"),
         "train.encounters: expected a number >= 0, got Infinity", write("r.toml", 'model = "navigan-r"\n[train]\nencounters = inf\n')),
    Case("train threads zero", ("train", "--recipe", "navigan", "--split", "eth", "--threads", "0"),
         "argument --threads: expected a whole number from 1 to 256"),
    Case("train out in a missing folder", ("train", "--recipe", "navigan", "--split", "eth", "--out", "{tmp}/no/m.pt"),
         "argument --out: {tmp}/no/m.pt: the folder {tmp}/no does not exist"),
    Case("playback out is a file", ("playback", "--out", "{tmp}/afile"), "argument --out: {tmp}/afile is a file, not a folder", write("afile", "x")),
    Case("playback gamma above one", ("playback", "--gamma", "2"), "argument --gamma: expected a finite number in (0, 1], got '2'"),
]


def _edit_design(study: Path, change: Callable[[dict], object], redigest: bool = True) -> None:
    """Rewrite design.json through `change`; with `redigest` its own digest is made again, so the edit meets the
    checks behind the digest's."""
    path = study / "design.json"
    record = json.loads(path.read_text())
    change(record)
    if redigest:
        record["digest"] = design_digest(record)
    path.write_text(json.dumps(record))


#: A table whose one value is nested 5,000 arrays deep, appended to a study.toml.
NESTED_TABLE = "\n[deep]\nx = " + "[" * 5000 + "]" * 5000 + "\n"


def _nest_design(study: Path) -> None:
    """Give design.json a field nested 100,000 arrays deep."""
    path = study / "design.json"
    path.write_text(path.read_text().replace("{", '{"deep": ' + "[" * 100_000 + "]" * 100_000 + ", ", 1))


def _snapshot(root: Path) -> dict[str, str]:
    """Every file and folder under root, files by content."""
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir"
            for p in sorted(root.rglob("*"))}


@pytest.fixture(scope="module")
def template(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The 18-run blinded A/B plan with seed 1 (its first run NGAC3, 2 pedestrians Crossing)."""
    root = tmp_path_factory.mktemp("template") / "study"
    assert main(["design", "--ab", "--seed", "1", "--study", str(root)]) == 0
    return root


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_bad_input_is_one_line_exit_2_and_writes_nothing(case: Case, template: Path, tmp_path: Path,
                                                         capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    study = Path(shutil.copytree(template, tmp_path / "study"))
    case.prepare(tmp_path, study)
    monkeypatch.chdir(tmp_path)  # a command's default output lands here, inside the snapshot
    before = _snapshot(tmp_path)
    capsys.readouterr()
    args = [a.format(tmp=tmp_path, study=study) for a in case.args]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1, err
    assert case.expected.format(tmp=tmp_path, study=study) in err, err
    assert "Traceback" not in err
    assert _snapshot(tmp_path) == before


def test_a_noise_of_minus_zero_is_zero() -> None:
    """`--noise -0` and `[run] noise = -0.0` were taken as they were written, and numpy refused every run (scale < 0)."""
    for noise in (number(0, MAX_NOISE_M)("-0"), settings_from_table({"noise": -0.0}, "study.toml [run]").noise_std_m):
        assert noise == 0.0 and math.copysign(1.0, noise) == 1.0
        assert np.random.default_rng(0).normal(0.0, noise, 2).tolist() == [0.0, 0.0]  # as a run draws its position noise


@pytest.mark.slow  # one simulated run in a worker process
def test_a_run_with_a_noise_of_minus_zero_finishes(template: Path, tmp_path: Path) -> None:
    study = Path(shutil.copytree(template, tmp_path / "study"))
    append(study / "study.toml", "\n[run]\nnoise = -0.0\n")
    assert main(["run", "--only", "NGAC3", "--workers", "1", "--study", str(study)]) == 0
    with (study / "outcomes.csv").open(newline="", encoding="utf-8") as handle:
        (row,) = csv.DictReader(handle)
    assert row["run_code"] == "NGAC3" and row["noise_std_m"] == "0.000"


def test_spreadsheet_resaves_read_as_the_plan(template: Path, tmp_path: Path) -> None:
    """A byte order mark, CRLF line ends, padded cells and a trailing blank line change no run."""
    study = Path(shutil.copytree(template, tmp_path / "study"))
    original = StudyFolder(study).read_plan()
    lines = (study / "plan.csv").read_text().splitlines()
    padded = [",".join(f" {cell} " for cell in line.split(",")) for line in lines]
    (study / "plan.csv").write_bytes(b"\xef\xbb\xbf" + "\r\n".join(padded).encode() + b"\r\n\r\n")
    again = StudyFolder(study).read_plan()
    assert again == original and list(again[0]) == ["order", "run_code", "Pedestrians", "Direction", "Controller", "CrossingDistance"]
    assert again[0]["run_code"] == "NGAC3" and again[0]["Pedestrians"] == "2"


def test_a_log_column_may_be_added(template: Path, tmp_path: Path) -> None:
    study = Path(shutil.copytree(template, tmp_path / "study"))
    plan_rows(lambda rows: [row + (["Log"] if i == 0 else [""]) for i, row in enumerate(rows)])(tmp_path, study)
    plan = StudyFolder(study).read_plan()
    assert len(plan) == 18 and plan[0]["Log"] == ""


def test_design_json_records_the_plan_digest_and_old_records_without_it_still_check(template: Path, tmp_path: Path) -> None:
    study = Path(shutil.copytree(template, tmp_path / "study"))
    record = json.loads((study / "design.json").read_text())
    table = list(csv.reader((study / "plan.csv").read_text().splitlines()))
    assert record["plan"] == {"file": "plan.csv", "sha256": hashlib.sha256((study / "plan.csv").read_bytes()).hexdigest()}
    assert len(table) == 19
    _edit_design(study, lambda d: d.pop("plan"))  # a design.json written before the digest
    assert len(StudyFolder(study).read_plan()) == 18
    plan_rows(edit_cell(5, "Direction", "Parallel" if table[4][3] != "Parallel" else "Crossing"))(tmp_path, study)
    with pytest.raises(ValueError, match=r"plan.csv line 5 \(run \w+\): Direction is"):
        StudyFolder(study).read_plan()


def test_design_json_is_checked_by_its_own_digest_and_old_records_without_it_still_read(template: Path, tmp_path: Path,
                                                                                        capsys: pytest.CaptureFixture[str]) -> None:
    study = Path(shutil.copytree(template, tmp_path / "study"))
    path = study / "design.json"
    record = json.loads(path.read_text())
    content = {key: value for key, value in record.items() if key != "digest"}
    canonical = json.dumps(content, sort_keys=True, separators=(",", ":"), ensure_ascii=False).encode()
    assert record["digest"]["sha256"] == hashlib.sha256(canonical).hexdigest()
    path.write_text(json.dumps(dict(reversed(record.items())), indent=4))  # laid out anew, not edited
    assert StudyFolder(study).read_design() == record
    assert main(["status", "--study", str(study)]) == 0
    assert "digest" not in capsys.readouterr().out
    _edit_design(study, lambda d: d.pop("digest"), redigest=False)  # a design.json written before the digest
    _edit_design(study, lambda d: d.update(seed=d["seed"] + 1), redigest=False)
    assert StudyFolder(study).read_design()["seed"] == record["seed"] + 1
    assert main(["status", "--study", str(study)]) == 0
    assert "note: design.json has no digest of its own content" in capsys.readouterr().out


def test_design_with_unicode_levels_prints_no_glyph_warnings(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "spec.toml").write_text(SPEC_HEAD + '[[factors]]\nname = "Gait"\ntype = "categorical"\nlevels = ["歩く", "走る"]\n',
                                        encoding="utf-8")
    assert main(["design", "--spec", str(tmp_path / "spec.toml"), "--study", str(tmp_path / "s"), "--seed", "3"]) == 0
    assert capfd.readouterr().err == ""
    assert StudyFolder(tmp_path / "s").read_plan()[0]["Gait"] in ("歩く", "走る")


def _no_space(*args: object) -> None:
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def test_a_full_disk_names_the_file_and_keeps_the_old_one(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    target = tmp_path / "outcomes.csv"
    target.write_text("old\n")
    monkeypatch.setattr(atomic.os, "fsync", _no_space)
    with pytest.raises(DiskFullError, match=f"no space left on the device to write {target}; free some"):
        atomic.write_files({target: b"new\n", tmp_path / "a.csv": b"new\n"})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["outcomes.csv"] and target.read_text() == "old\n"


def test_a_full_disk_in_a_worker_is_a_disk_full_error_naming_the_log(template: Path, tmp_path: Path,
                                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """Raised from a run (the MCAP write), it is not a failed run but a stop; nothing goes to sealed/runs/."""
    from trials.runner import RunTask, TrialWorker

    study = Path(shutil.copytree(template, tmp_path / "study"))
    worker = TrialWorker.__new__(TrialWorker)
    worker.folder, worker.blind = StudyFolder(study), True
    monkeypatch.setattr(TrialWorker, "_run", lambda self, task: _no_space())
    with pytest.raises(DiskFullError, match=r"to write .*/runs/NGAC3\.mcap"):
        worker(RunTask("NGAC3", {}, 1))
    assert not (study / "sealed" / "runs").exists()


@pytest.mark.slow
def test_a_full_disk_stops_trials_run_at_once(template: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    """The parent cannot write outcomes.csv after the first run: one line naming it, exit 2, no second
    run, no partial file; the finished log without a row runs again next time."""
    study = Path(shutil.copytree(template, tmp_path / "study"))
    codes = [row["run_code"] for row in StudyFolder(study).read_plan()[:3]]
    monkeypatch.setattr(atomic.os, "fsync", _no_space)  # the parent's writes only: workers are spawned
    capsys.readouterr()
    assert main(["run", "--study", str(study), "--only", *codes, "--no-responses"]) == 2
    captured = capsys.readouterr()
    assert captured.err.count("\n") == 1 and captured.err.startswith(f"error: no space left on the device to write {study / 'outcomes.csv'}")
    assert "failed" not in captured.err and not (study / "outcomes.csv").exists()
    assert [p.name for p in (study / "runs").iterdir() if p.name != ".lock"] == [f"{codes[0]}.mcap"]
    assert not list(study.glob(".*.tmp")) and not list(study.rglob("*.partial"))


class _FullDiskPool:
    """Stands in for the worker pool: every worker answers that the disk is full."""

    def __init__(self, *args: object, **options: object) -> None:
        return None

    def __enter__(self) -> _FullDiskPool:
        return self

    def __exit__(self, *exc: object) -> None:
        return None

    def ready(self) -> None:
        return None

    def run(self, tasks: Iterator[tuple[str, object]]) -> Iterator[tuple[str, Failure]]:
        for code, _ in tasks:
            yield code, Failure("DiskFullError", f"no space left on the device to write runs/{code}.mcap; free some", "", True)


def test_a_worker_out_of_space_stops_the_run_without_a_line_per_run(template: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                                      capsys: pytest.CaptureFixture[str]) -> None:
    study = Path(shutil.copytree(template, tmp_path / "study"))
    monkeypatch.setattr("trials.runner.WorkerPool", _FullDiskPool)
    capsys.readouterr()
    assert main(["run", "--study", str(study), "--no-responses"]) == 2
    err = capsys.readouterr().err
    assert err == "error: no space left on the device to write runs/NGAC3.mcap; free some\n"
    assert not (study / "outcomes.csv").exists()
