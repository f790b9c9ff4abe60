"""`trials design`: build a D-optimal, randomized (and blinded) plan into the study folder."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from designs.exchange import CRITERIA
from designs.spec import MAX_RUNS, MAX_SNR, MAX_STARTS
from trials import option_types as types
from trials.option_types import MAX_THREADS
from trials.progress import add_quiet

if TYPE_CHECKING:
    from designs.spec import StudySpec
    from trials.study import StudyFolder


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "design",
        help="make a D-optimal, randomized, optionally blinded run plan",
        description=(
            "Build the study's plan: the paper's 27-run qualitative plan by default, the 18-run "
            "blinded A/B plan with --ab, or any study from a study.toml. Writes study.toml, "
            "plan.csv, design.json (and sealed/ when blinded); with --figures also the design evaluation figures."
        ),
    )
    source = parser.add_mutually_exclusive_group()
    source.add_argument("--ab", action="store_true", help="the paper's blinded A/B plan (NaviGAN-R vs the lattice planner)")
    source.add_argument("--arms", type=types.listed(str, "controller names"), metavar="NAME,NAME,...",
                        help="the A/B plan's design with these controllers as its blinded arms, two or more (`trials controllers` "
                             "lists them; 18 runs for 2 or 3 arms, 6 a controller beyond)")
    source.add_argument("--spec", type=types.input_file, metavar="FILE",
                        help="a study.toml to build (default: the study folder's own, else the qualitative plan)")
    check = parser.add_mutually_exclusive_group()
    check.add_argument("--evaluate", type=types.input_file, metavar="PLAN.csv",
                       help="print the full diagnostics of a plan you have (its factor columns, under the spec's coding "
                            "and model); writes nothing unless --figures")
    check.add_argument("--compare", type=types.input_file, nargs=2, metavar=("A.csv", "B.csv"),
                       help="print two plans' diagnostics side by side; writes nothing unless --figures")
    check.add_argument("--augment", type=types.whole(1, MAX_RUNS), metavar="N",
                       help="add N runs to the study's plan, keeping its runs and results (the old design files are "
                            "copied to superseded/)")
    parser.add_argument("--runs", type=types.whole(1, MAX_RUNS), help=f"number of runs, at most {MAX_RUNS} (presets: 27, or 18 with --ab)")
    parser.add_argument("--model", help="model terms, e.g. 'main + interactions' or 'A + B + A*B + A^2'")
    parser.add_argument("--criterion", choices=CRITERIA,
                        help="D: largest det(X'X) (default); I: smallest average prediction variance; A: smallest trace((X'X)^-1)")
    parser.add_argument("--seed", type=types.seed, help="seed of the design search, run order and run codes (default: drawn and recorded)")
    parser.add_argument("--starts", type=types.whole(1, MAX_STARTS), help=f"random starts of the exchange algorithm (default 100, at most {MAX_STARTS})")
    parser.add_argument("--threads", type=types.whole(1, MAX_THREADS), metavar="N",
                        help="starts searched side by side (default: the CPUs this process may use; the design is the same whatever N)")
    parser.add_argument("--snr", type=types.number(0, MAX_SNR, above=True), help="signal-to-noise ratio for the power table (default 1)")
    parser.add_argument("--allocation-seed", type=types.seed, help="seed of the blind allocation (default: a fresh secret one, sealed)")
    parser.add_argument("--study", type=types.folder, default=types.folder("."), metavar="DIR", help="the study folder (default: current folder)")
    parser.add_argument("--force", action="store_true", help="replace an existing plan; the old files move to superseded/")
    parser.add_argument("--robot", metavar="URI",
                        help="drive the runs live on this robot (ros1://HOST:PORT or ros2://DOMAIN): writes a [robot] table with "
                        "the defaults (topics, frames, limits; docs/live_runs.md) into study.toml, for `trials run --robot` and the console")
    parser.add_argument("--figures", action="store_true",
                        help="also draw the design evaluation figures, correlation_map and design_evaluation, as PNG and SVG "
                             "(with --evaluate or --compare: each plan's, named PLAN.correlation_map.png and so on, in --study)")
    parser.add_argument("--power", type=types.whole(0, 100_000), metavar="N",
                        help="the power of the planned primary test from N simulated data sets per plan size, at the plan's size and "
                             "at 2 to 4 times it until 0.8, for the runs needed (model-based, as `trials power`; default: 200 data "
                             "sets at the plan's size only; 0: none)")
    types.add_dpi(parser)
    add_quiet(parser)
    parser.add_argument("--json", action="store_true", help="print the files written and design.json's record as one JSON object")
    parser.set_defaults(handler=run)


def usable_cpus() -> int:
    """The CPUs this process may use: the starts' threads unless --threads says otherwise."""
    affinity = getattr(os, "sched_getaffinity", None)
    return len(affinity(0)) if affinity is not None else os.cpu_count() or 1


def _threads(args: argparse.Namespace) -> int:
    return args.threads or usable_cpus()


def _progress(done: int, starts: int) -> None:
    """One line on a terminal that follows the exchange's starts."""
    print(f"\rdesign search: start {done} of {starts}", end="", file=sys.stderr, flush=True)


def _evaluate(spec: StudySpec, paths: list[Path], folder: StudyFolder, args: argparse.Namespace) -> int:
    """Diagnose plans the researcher brings under the spec's factors, coding and model and print them; with
    --figures, draw each plan's design figures into the study folder under its file's name."""
    from designs.diagnostics import diagnose
    from designs.errors import DesignError
    from designs.evaluate import settings_from_rows
    from designs.export import comparison_lines, diagnostics_lines
    from trials.csv_table import read_rows
    from trials.design_files import EvaluatedPlan, write_evaluation_figures

    model = spec.build_model()
    evaluated = []
    for path in paths:
        header, rows = read_rows(path, same_width=True)
        settings = settings_from_rows(model.factors, header, rows, path.name)
        if len(settings) < model.p:
            raise DesignError(f"{path.name}: {len(settings)} runs cannot estimate the model's p = {model.p} parameters")
        diagnostics = diagnose(model, settings, alpha=spec.alpha, snr=spec.snr, anticipated=spec.anticipated)
        evaluated.append(EvaluatedPlan(path, model, settings, diagnostics))
    written = write_evaluation_figures(folder, evaluated, args.dpi, args.force) if args.figures else []
    results = [plan.diagnostics for plan in evaluated]
    if len(results) == 1:
        print(f"{paths[0].name}: {results[0].n} runs, model {spec.model!r} with p = {results[0].p} parameters")
        print("\n".join(diagnostics_lines(results[0])))
    else:
        print(f"Model {spec.model!r}")
        print("\n".join(comparison_lines([p.name for p in paths], results)))
    if written:
        print(f"Wrote {', '.join(p.name for p in written)} in {folder.root.resolve()}")
    return 0


def _tables_only(spec: Path) -> bool:
    """Whether a study.toml holds no [study] table (a damaged one is left to the spec reader to report)."""
    from trials.errors import StudyError
    from trials.study import study_table

    try:
        return study_table(spec, "study") is None
    except StudyError:
        return False


def _arms(asked: tuple[str, ...], known: tuple[str, ...]) -> tuple[str, ...]:
    """`--arms`' controllers: two or more, each known, none twice."""
    from trials.errors import StudyError

    if len(asked) < 2:
        raise StudyError(f"--arms: name two or more controllers, got {len(asked)}")
    twice = next((name for i, name in enumerate(asked) if name in asked[:i]), None)
    if twice is not None:
        raise StudyError(f"--arms: {twice!r} is named twice")
    unknown = next((name for name in asked if name not in known), None)
    if unknown is not None:
        raise StudyError(f"--arms: no controller is called {unknown!r} (known: {', '.join(known)})")
    return asked


def _augment(folder: StudyFolder, args: argparse.Namespace) -> int:
    """Add runs to a study's plan around the runs it has; its results and sealed key stay as they are."""
    from dataclasses import replace

    import numpy as np

    from designs.export import summary_lines
    from designs.plan import KeptRuns, build_plan
    from designs.spec import MAX_RUNS, read_spec
    from trials.analysis_plan import analysis_table
    from trials.controllers.plugins import read_table
    from trials.design_files import write_design
    from trials.errors import StudyError
    from trials.preregistration import register, registered_lines
    from trials.robot.settings import robot_table
    from trials.run_settings import run_table
    from trials.study import DESIGN, DESIGN_FIGURES, PLAN, PREREGISTRATION, SPEC

    folder.require_plan()
    spec = read_spec(folder.path(SPEC))
    if spec.blocks > 1 or any(f.kind == "covariate" for f in spec.factors):
        raise StudyError(f"{folder.path(SPEC)}: a study with blocks or covariates cannot be augmented (its runs' "
                         "blocks and covariate values are fixed by the spec); make a new plan with trials design --force")
    record = folder.read_design()
    try:
        kept = tuple((int(run["order"]), str(run["run_code"]), np.array(run["settings"], dtype=float)) for run in record["design"])
    except (KeyError, TypeError, ValueError) as exc:
        raise StudyError(f"{folder.path(DESIGN)}: its runs are damaged ({type(exc).__name__}: {exc})") from None
    total = len(kept) + args.augment
    if total > MAX_RUNS:
        raise StudyError(f"--augment {args.augment}: the study would have {total} runs; at most {MAX_RUNS}")
    overrides = {"seed": args.seed, "starts": args.starts, "snr": args.snr, "criterion": args.criterion}
    spec = replace(spec, runs=total, **{k: v for k, v in overrides.items() if v is not None})
    if args.seed is None:
        spec = replace(spec, seed=None)  # a fresh seed for the new runs, recorded
    sealed = folder.read_sealed() if spec.blind_factor is not None else None
    plan = build_plan(spec, kept=KeptRuns(kept, sealed), progress=_progress if sys.stderr.isatty() and not args.quiet else None,
                      threads=_threads(args))
    tables = {"run": run_table(folder.path(SPEC)), "robot": robot_table(folder.path(SPEC), args.robot),  # they stay with the study
              "controllers": read_table(folder.path(SPEC)), "analysis": analysis_table(folder.path(SPEC), plan.spec, plan.seed)}
    copies: list[Path] = []  # the previous design files, copied aside once the new ones are staged
    written = write_design(folder, plan, None, tables, args.dpi if args.figures else None,
                           lambda: copies.append(folder.copy_aside((SPEC, PLAN, DESIGN, PREREGISTRATION, *DESIGN_FIGURES))))
    registered = register(folder, None)
    if not args.figures:
        for name in DESIGN_FIGURES:  # they show the old plan; their copies are in superseded/
            folder.path(name).unlink(missing_ok=True)
    print("\n".join(summary_lines(plan)))
    print(f"Kept the {len(kept)} planned runs and their results; added {args.augment}. "
          f"Wrote {', '.join(p.name for p in written)}, {PREREGISTRATION}; the previous design files are in {copies[0]}")
    print(registered_lines(registered, sealed is not None))
    return 0


def run(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from designs import presets
    from designs.export import summary_lines
    from designs.plan import build_plan
    from designs.spec import read_spec
    from trials.analysis_plan import analysis_table
    from trials.controllers import registry
    from trials.controllers.plugins import read_table
    from trials.errors import StudyError
    from trials.progress import Progress
    from trials.robot.settings import robot_table
    from trials.run_settings import run_table
    from trials.study import (
        DESIGN,
        PREREGISTRATION,
        PUBLIC_STUDY_FILES,
        SEALED_STUDY_FILES,
        SPEC,
        StudyFolder,
    )

    folder = StudyFolder(args.study)
    if args.augment:
        return _augment(folder, args)
    own_spec = folder.path(SPEC)
    # A study.toml of the study's own tables only ([controllers], [run], [robot], [analysis]) is read for them, not replaced.
    tables_only = own_spec.exists() and _tables_only(own_spec)
    spec_path = args.spec or (own_spec if own_spec.exists() and not (args.ab or args.arms or tables_only) else None)
    tables_from = spec_path or (own_spec if tables_only else None)
    spec = read_spec(spec_path) if spec_path is not None else None  # its errors first: they name the line
    controllers = read_table(tables_from) if tables_from is not None else {}
    if spec is None and args.arms:
        spec = presets.ab(_arms(tuple(args.arms), registry.names(controllers)), runs=max(18, 6 * len(args.arms)))
    elif spec is None:
        spec = presets.ab(registry.AB_PRESET) if args.ab else presets.qualitative()
    overrides = {"runs": args.runs, "model": args.model, "seed": args.seed, "starts": args.starts, "snr": args.snr,
                 "criterion": args.criterion}
    spec = replace(spec, **{k: v for k, v in overrides.items() if v is not None})

    if args.evaluate or args.compare:
        return _evaluate(spec, args.compare or [args.evaluate], folder, args)

    replaces_own_spec = own_spec.exists() and not tables_only and (spec_path is None or spec_path.resolve() != own_spec.resolve())
    if (folder.has_plan() or replaces_own_spec) and not args.force:
        what = "a plan" if folder.has_plan() else f"a different {SPEC}"
        raise StudyError(f"{folder.root.resolve()} already has {what}; pass --force to replace it (the old files move to superseded/)")
    if spec.arms_sealed:
        sealed = folder.read_sealed()
        blind = spec.blind_factor
        assert blind is not None
        spec = spec.with_factor(replace(blind, levels=tuple(sealed.arms[arm] for arm in blind.levels)))

    tables = {"run": run_table(tables_from) if tables_from is not None else {}, "robot": robot_table(tables_from, args.robot),
              "controllers": controllers}
    analysis_table(tables_from, spec, 0)  # a bad [analysis] table fails before the search; its default seed is the design's
    quiet = args.quiet or args.json
    Progress("start", "design", quiet).loading(f"Searching for a {spec.criterion}-optimal design of {spec.runs} runs ({spec.starts} exchange starts)")
    follow = sys.stderr.isatty() and not quiet
    # every bad input fails here
    plan = build_plan(spec, allocation_seed=args.allocation_seed, progress=_progress if follow else None, threads=_threads(args))
    if follow:
        print(file=sys.stderr)
    tables["analysis"] = analysis_table(tables_from, plan.spec, plan.seed)
    from trials.design_files import write_design

    names_real_levels = spec_path == own_spec and spec.blind_factor is not None and not read_spec(own_spec).arms_sealed
    original = own_spec.read_text(encoding="utf-8") if names_real_levels else None
    aside: list[Path | None] = [None]  # where --force moved the old files: only once the new ones are staged

    def move_aside() -> None:
        aside[0] = folder.supersede(PUBLIC_STUDY_FILES, SEALED_STUDY_FILES)

    written = write_design(folder, plan, original, tables, args.dpi if args.figures else None, move_aside if args.force else None)
    moved = aside[0]

    planned = None
    if args.power != 0:
        from trials.power.planned import SIMULATIONS, planned_test_power

        Progress("start", "design", quiet).loading("Simulating the power of the planned primary test")
        planned = planned_test_power(folder, plan.seed, args.power or SIMULATIONS, search=args.power is not None)
    from trials.preregistration import register, registered_lines

    registered = register(folder, planned)
    if args.json:
        import json

        print(json.dumps({"study": str(folder.root.resolve()), "files": [str(p) for p in written],
                          "planned_power": planned.record() if planned is not None else None,
                          "commitment": plan.sealed.commitment() if plan.sealed is not None else None,
                          "preregistration": {"file": str(folder.path(PREREGISTRATION)), "sha256": registered},
                          "superseded": str(moved) if moved is not None else None,
                          "design": json.loads(folder.path(DESIGN).read_text(encoding="utf-8"))}))
        return 0
    print("\n".join(summary_lines(plan)))
    if planned is not None:
        print("\n".join(planned.lines()))
    print(f"Wrote {', '.join(p.name for p in written)}, {PREREGISTRATION} in {folder.root.resolve()}")
    print(registered_lines(registered, plan.sealed is not None))
    if plan.sealed is not None:
        print("The allocation key is in sealed/, readable by you only (folder 0700, files 0600): keep it closed until "
              "the study is unblinded (trials report --unblind).")
    if moved is not None:
        print(f"The previous plan and its results moved to {moved}")
    return 0
