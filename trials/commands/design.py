"""`trials design`: build a D-optimal, randomized (and blinded) plan into the study folder."""

from __future__ import annotations

import argparse

from designs.spec import MAX_RUNS, MAX_SNR, MAX_STARTS
from trials import option_types as types
from trials.progress import add_quiet


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "design",
        help="make a D-optimal, randomized, optionally blinded run plan",
        description=(
            "Build the study's plan: the paper's 27-run qualitative plan by default, the 18-run "
            "blinded A/B plan with --ab, or any study from a study.toml. Writes study.toml, "
            "plan.csv, design.json, correlation_map.png (and sealed/ when blinded)."
        ),
    )
    source = parser.add_mutually_exclusive_group()
    source.add_argument("--ab", action="store_true", help="the paper's blinded A/B plan (NaviGAN-R vs the lattice planner)")
    source.add_argument("--spec", type=types.input_file, metavar="FILE",
                        help="a study.toml to build (default: the study folder's own, else the qualitative plan)")
    parser.add_argument("--runs", type=types.whole(1, MAX_RUNS), help=f"number of runs, at most {MAX_RUNS} (presets: 27, or 18 with --ab)")
    parser.add_argument("--model", help="model terms, e.g. 'main + interactions' or 'A + B + A*B + A^2'")
    parser.add_argument("--seed", type=types.seed, help="seed of the design search, run order and run codes (default: drawn and recorded)")
    parser.add_argument("--starts", type=types.whole(1, MAX_STARTS), help=f"random starts of the exchange algorithm (default 100, at most {MAX_STARTS})")
    parser.add_argument("--snr", type=types.number(0, MAX_SNR, above=True), help="signal-to-noise ratio for the power table (default 1)")
    parser.add_argument("--allocation-seed", type=types.seed, help="seed of the blind allocation (default: a fresh secret one, sealed)")
    parser.add_argument("--study", type=types.folder, default=types.folder("."), metavar="DIR", help="the study folder (default: current folder)")
    parser.add_argument("--force", action="store_true", help="replace an existing plan; the old files move to superseded/")
    add_quiet(parser)
    parser.add_argument("--json", action="store_true", help="print the files written and design.json's record as one JSON object")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from designs import presets
    from designs.export import summary_lines
    from designs.plan import build_plan
    from designs.spec import read_spec
    from trials.controllers import registry
    from trials.errors import StudyError
    from trials.progress import Progress
    from trials.run_settings import run_table
    from trials.study import (
        ALLOCATION,
        DESIGN,
        PUBLIC_STUDY_FILES,
        SEALED_SPEC,
        SPEC,
        StudyFolder,
    )

    folder = StudyFolder(args.study)
    own_spec = folder.path(SPEC)
    spec_path = args.spec or (own_spec if own_spec.exists() and not args.ab else None)
    if spec_path is not None:
        spec = read_spec(spec_path)
    else:
        spec = presets.ab(registry.NAMES) if args.ab else presets.qualitative()
    overrides = {"runs": args.runs, "model": args.model, "seed": args.seed, "starts": args.starts, "snr": args.snr}
    spec = replace(spec, **{k: v for k, v in overrides.items() if v is not None})

    replaces_own_spec = own_spec.exists() and (spec_path is None or spec_path.resolve() != own_spec.resolve())
    if (folder.has_plan() or replaces_own_spec) and not args.force:
        what = "a plan" if folder.has_plan() else f"a different {SPEC}"
        raise StudyError(f"{folder.root.resolve()} already has {what}; pass --force to replace it (the old files move to superseded/)")
    if spec.arms_sealed:
        sealed = folder.read_sealed()
        blind = spec.blind_factor
        assert blind is not None
        spec = spec.with_factor(replace(blind, levels=tuple(sealed.arms[arm] for arm in blind.levels)))

    run = run_table(spec_path) if spec_path is not None else {}
    Progress("start", "design", args.quiet or args.json).loading(
        f"Searching for a D-optimal design of {spec.runs} runs ({spec.starts} exchange starts) and its cvxpy bound")
    plan = build_plan(spec, allocation_seed=args.allocation_seed)  # every bad input fails here, before any write
    # Imported only now (matplotlib loads) so that it overlaps the background cvxpy solve.
    from trials.design_files import write_design

    names_real_levels = spec_path == own_spec and spec.blind_factor is not None and not read_spec(own_spec).arms_sealed
    original = own_spec.read_text(encoding="utf-8") if names_real_levels else None
    moved = folder.supersede(PUBLIC_STUDY_FILES, (ALLOCATION, SEALED_SPEC)) if args.force else None
    written = write_design(folder, plan, original, run)

    if args.json:
        import json

        print(json.dumps({"study": str(folder.root.resolve()), "files": [str(p) for p in written],
                          "commitment": plan.sealed.commitment() if plan.sealed is not None else None,
                          "superseded": str(moved) if moved is not None else None,
                          "design": json.loads(folder.path(DESIGN).read_text(encoding="utf-8"))}))
        return 0
    print("\n".join(summary_lines(plan)))
    print(f"Wrote {', '.join(p.name for p in written)} in {folder.root.resolve()}")
    if plan.sealed is not None:
        print("The allocation key is in sealed/, readable by you only (folder 0700, files 0600): keep it closed until "
              "the study is unblinded (trials report --unblind).")
    if moved is not None:
        print(f"The previous plan and its results moved to {moved}")
    return 0
