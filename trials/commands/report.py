"""`trials report`: score the finished runs, tabulate and fit the results, write report/ (Markdown and HTML)."""

from __future__ import annotations

import argparse
from pathlib import Path

from trials import option_types as types
from trials.progress import add_quiet


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "report",
        help="score the runs and write report/ (report.md, report.html, figures)",
        description=(
            "Score every finished run with the rubric (human scores override it), tabulate the score "
            "distribution and the A/B table (Table II) with Wilson intervals and Fisher's exact tests, fit "
            "the design's model to the judgments (primary: logistic GEE clustered by run) and outcome metrics, and write report/report.md, a "
            "self-contained report/report.html, report/report.json and report/figures/. A blinded study is "
            "reported by arm label unless --unblind is given; before every run has finished its report pools the arms "
            "unless --interim REASON is given."
        ),
    )
    parser.add_argument("--study", type=types.folder, default=types.folder("."), metavar="DIR", help="the study folder (default: current folder)")
    parser.add_argument(
        "--unblind",
        action="store_true",
        help="open the sealed key (checked against design.json's commitment) and name the controllers; "
        "the time is recorded in unblinding.json, and the blinded report is kept in report/blinded/",
    )
    parser.add_argument(
        "--commitment",
        metavar="HEX",
        help="the pre-registration digest `trials design` printed, as recorded outside the study folder: with --unblind (required "
        "to unblind a blinded study) a study or key that does not match it is refused; without, the report says whether it matches",
    )
    parser.add_argument(
        "--interim",
        metavar="REASON",
        help="an interim look, for this reason, while runs are pending or failed: a blinded report then compares the arms "
        "by label (without it, it pools them), and with --unblind the key is opened; the reason, the time and how many runs "
        "had finished are recorded in unblinding.json and printed in the report",
    )
    parser.add_argument("--rubric", type=Path, metavar="FILE", help="rubric thresholds: a TOML file with a [rubric] table "
                        "(default: the study's rubric.toml if any, else the documented defaults)")
    types.add_dpi(parser)
    add_quiet(parser)
    parser.add_argument("--json", action="store_true", help="print the files written and the report's record (report.json) as one JSON object")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    import json

    from analysis.report import build_report
    from analysis.scoring import Rubric, read_rubric
    from trials.atomic import write_files
    from trials.errors import StudyError
    from trials.progress import Progress
    from trials.study import (
        OUTCOMES,
        PREREGISTRATION,
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
    from trials.study_data import INPUTS_KEY, RUBRIC_KEY, interim_look, load_study, report_inputs, unblinding_opening, unblinding_record

    folder = StudyFolder(args.study)
    if args.commitment is not None and not args.unblind and not folder.path(PREREGISTRATION).exists():
        raise StudyError("--commitment checks the key when it is opened: give it with --unblind (this study has no pre-registration "
                         "to check it against)")
    opening = unblinding_opening(folder, args.commitment, args.interim) if args.unblind else interim_look(folder, args.interim)
    now = utc_now()
    Progress("figure", "report", args.quiet or args.json).loading(
        f"Reading the study in {folder.root} and fitting its model{' (opening the sealed key)' if args.unblind else ''}")
    # Before reading, so a change made while the report is built shows as stale.
    inputs = report_inputs(folder, args.rubric)
    data = load_study(folder, args.unblind, now, args.commitment, opening)
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
        folder.path(REPORT_RECORD): (json.dumps({**report.record, INPUTS_KEY: inputs,
                                                  RUBRIC_KEY: str(args.rubric.resolve()) if args.rubric else None}, indent=1) + "\n").encode(),
        **{path: data for figure in report.figures for path, data in figure.image.files(figures / figure.name, args.dpi).items()},
        **{tables / f"{name}.csv": text.encode() for name, text in report.tables().items()},
    }
    kept = None
    if data.blinding.revealed or data.blinding.looking:
        files[folder.path(UNBLINDING)] = unblinding_record(folder, data.blinding)
    if data.blinding.revealed and not _unblinded(folder.path(REPORT_RECORD)):
        kept = folder.keep_blinded_report()
    write_files(files)
    for stale in [*figures.glob("*.png"), *figures.glob("*.svg"), *tables.glob("*.csv")]:
        if stale not in files:
            stale.unlink()
    if args.json:
        print(json.dumps({"report": str(out.resolve()), "files": sorted(str(p) for p in files),
                          "blinded_report_kept": str(kept) if kept else None, "record": report.record}))
        return 0
    print("\n".join(report.summary))
    print(f"Wrote report.md, report.html, report.json, {len(report.figures)} figures (PNG and SVG) and {len(report.tables())} tables (CSV) in {out.resolve()}")
    if data.blinding.revealed:
        print(data.blinding.check)
    if kept is not None:
        print(f"The blinded report is kept in {kept.resolve()}")
    return 0


def _unblinded(record: Path) -> bool:
    """Whether report/report.json is of an unblinded report (one that a new unblinded report may replace)."""
    import json

    try:
        return json.loads(record.read_text(encoding="utf-8"))["blinding"]["controllers_named"] is True
    except (OSError, ValueError, KeyError, TypeError):
        return False  # missing or unreadable: whatever is there is kept
