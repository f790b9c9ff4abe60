"""`trials report`: score the finished runs, tabulate and fit the results, write report/ (Markdown and HTML)."""

from __future__ import annotations

import argparse
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "report",
        help="score the runs and write report/ (report.md, report.html, figures)",
        description=(
            "Score every finished run with the rubric (human scores override it), tabulate the score "
            "distribution and the A/B table (Table II) with Wilson intervals and Fisher's exact tests, fit "
            "the design's model to the judgments (primary: logistic GEE clustered by run) and outcome metrics, and write report/report.md, a "
            "self-contained report/report.html, report/report.json and report/figures/. A blinded study is "
            "reported by arm label unless --unblind is given."
        ),
    )
    parser.add_argument("--study", type=Path, default=Path("."), metavar="DIR", help="the study folder (default: current folder)")
    parser.add_argument(
        "--unblind",
        action="store_true",
        help="open the sealed key (checked against design.json's commitment) and name the controllers; "
        "the time is recorded in report/unblinding.json",
    )
    parser.add_argument("--rubric", type=Path, metavar="FILE", help="rubric thresholds: a TOML file with a [rubric] table "
                        "(default: the study's rubric.toml if any, else the documented defaults)")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    import json

    from analysis.report import build_report
    from analysis.scoring import Rubric, read_rubric
    from trials.atomic import write_files
    from trials.errors import StudyError
    from trials.study import (
        OUTCOMES,
        REPORT,
        REPORT_FIGURES,
        REPORT_HTML,
        REPORT_MARKDOWN,
        REPORT_RECORD,
        REPORT_TABLES,
        RUBRIC,
        UNBLINDING,
        StudyFolder,
        utc_now,
    )
    from trials.study_data import load_study, unblinding_record

    folder = StudyFolder(args.study)
    now = utc_now()
    data = load_study(folder, args.unblind, now)
    if not data.finished:
        raise StudyError(f"no finished runs in {folder.path(OUTCOMES)} yet: nothing to report (run `trials run` first)")
    rubric_file = args.rubric or (folder.path(RUBRIC) if folder.path(RUBRIC).exists() else None)
    rubric = read_rubric(rubric_file) if rubric_file is not None else Rubric()
    source = f"from {rubric_file}" if rubric_file is not None else "the documented defaults"
    report = build_report(data, rubric, source, now)

    out, figures, tables = folder.path(REPORT), folder.path(REPORT_FIGURES), folder.path(REPORT_TABLES)
    files = {
        folder.path(REPORT_MARKDOWN): report.markdown().encode(),
        folder.path(REPORT_HTML): report.html().encode(),
        folder.path(REPORT_RECORD): (json.dumps(report.record, indent=1) + "\n").encode(),
        **{figures / f"{figure.name}.png": figure.image.png for figure in report.figures},
        **{figures / f"{figure.name}.svg": figure.image.svg for figure in report.figures},
        **{tables / f"{name}.csv": text.encode() for name, text in report.tables().items()},
    }
    if data.blinding.revealed:
        files[folder.path(UNBLINDING)] = unblinding_record(data.blinding)
    write_files(files)
    for stale in [*figures.glob("*.png"), *figures.glob("*.svg"), *tables.glob("*.csv")]:
        if stale not in files:
            stale.unlink()
    print("\n".join(report.summary))
    print(f"Wrote report.md, report.html, report.json, {len(report.figures)} figures (PNG and SVG) and {len(report.tables())} tables (CSV) in {out.resolve()}")
    return 0
