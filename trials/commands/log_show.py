"""`trials log show RUN`: a finished run's summary from its MCAP (by run code or path), and a PNG of its trajectories."""

from __future__ import annotations

import argparse

from trials import option_types as types


def register(group: argparse._SubParsersAction) -> None:
    parser = group.add_parser(
        "show",
        help="summarise a trial run from its MCAP log and draw its trajectories",
        description="Print a run's settings, seed, events and metrics, recomputed from runs/<code>.mcap, and "
        "write runs/<code>.png and .svg (the robot's and the pedestrians' paths seen from above, marked every 2 s) beside it. A blinded "
        "run's log holds no controller output; --unblind adds it from the sealed record. It also names the Foxglove "
        "layout shipped for run logs (the scene, the robot's velocity in a plot, the events).",
    )
    parser.add_argument("run", metavar="RUN", help="a run code of the study, or the path of a run's .mcap")
    parser.add_argument("--study", type=types.folder, default=types.folder("."), metavar="DIR", help="the study folder (default: current folder)")
    parser.add_argument("--unblind", action="store_true",
                        help="blinded study: open the sealed key (checked against design.json's commitment) and show "
                        "the run's controller and its plans from sealed/runs/")
    parser.add_argument("--commitment", metavar="HEX",
                        help="with --unblind (required): the pre-registration digest recorded when the study was designed")
    parser.add_argument("--interim", metavar="REASON",
                        help="with --unblind: open the key although runs are pending or failed, for this reason (recorded)")
    types.add_dpi(parser)
    parser.set_defaults(handler=show)


def show(args: argparse.Namespace) -> int:
    from robot_logs.run_log import LAYOUT, read_run
    from trials.atomic import write_files
    from trials.commands.log import study_log
    from trials.errors import StudyError
    from trials.metrics import measure
    from trials.outcomes import outcome_cells
    from trials.run_figure import log_figure, run_settings
    from trials.sealed_runs import unsealed_lines
    from trials.study import UNBLINDING, StudyFolder, utc_now
    from trials.study_data import opened_record, unblinding_opening

    if (args.commitment is not None or args.interim is not None) and not args.unblind:
        raise StudyError("--commitment and --interim go with the key's opening: give them with --unblind")
    path = study_log(args.run, args.study)
    run = read_run(path)
    meta = dict(run.metadata)
    code = meta.pop("run_code", path.stem)
    status = run.status or "unfinished"
    outcome = measure(status, run.time, run.pose, run.velocity, run.pedestrians)
    logged = "log" in meta  # a logged trial, played from a robot log
    settings = run_settings(meta)
    lines = [f"{path}: run {code} of study {meta.get('study', '?')}", f"settings: {settings}",
             f"seed {meta.get('seed', '?')}, perception {meta.get('perception', '?')}"
             + (f" (noise {meta['noise_std_m']} m, dropout {meta['dropout']}, range {meta['range_m']} m)" if "noise_std_m" in meta else "")]
    if "controller" in meta:
        lines.append(f"controller: {meta['controller']}" + (f" ({meta['weights']})" if "weights" in meta else ""))
    if logged:
        lines.append(f"played from {meta['log']} ({meta['log_format']}) from {meta['log_offset_s']} s, frame {meta['log_frame']}, "
                     f"goal ({meta['goal_x']}, {meta['goal_y']}); odometry: {meta['odometry']}"
                     + (f"; static map: {meta['static_map']}" if "static_map" in meta else ""))
    lines.append("events: " + "; ".join(f"{t:.1f} s {name} ({detail})" for t, name, detail in run.events))
    blinded = "controller" not in meta
    plans = f"{run.plans} plans" if not blinded else "its plans sealed"
    lines.append(f"{status} after {outcome.duration_s:.1f} s {'of the log' if logged else 'simulated'}; "
                 f"{len(run.ids)} {'tracked people' if logged else 'pedestrians'}, {plans}")
    replay = run.replay
    if args.unblind:
        if not blinded:
            raise StudyError(f"--unblind: run {code}'s log is not blinded, it names its controller already")
        folder = StudyFolder(args.study)
        opening = unblinding_opening(folder, args.commitment, args.interim)
        unsealed = unsealed_lines(folder, code, args.commitment)
        if opening is not None:  # opening the key is an unblinding, recorded as `trials report --unblind` records it
            write_files({folder.path(UNBLINDING): opened_record(folder, folder.read_design()["blinding"]["commitment"]["digest"],
                                                                utc_now(), opening, f"trials log show {code} --unblind")})
        lines += unsealed.lines
        replay = unsealed.replay
    if replay:
        figures = {k: v or "-" for k, v in replay.items()}
        lines.append(f"plans against the log: {figures['plan_deviation_mean_m']} m from the recorded path on average "
                     f"(at most {figures['plan_deviation_max_m']} m), closest predicted {figures['plan_min_clearance_m']} m")
    lines.extend(f"  {name:<30} {value or '-'}" for name, value in outcome_cells(outcome).items() if name != "duration_s")
    pictures = log_figure(run, code).files(path.with_suffix(""), args.dpi)
    write_files(pictures)
    lines.append(f"trajectories: {', '.join(str(picture) for picture in pictures)}")
    lines.append(f"Foxglove: open {path} with the layout {LAYOUT} (scene, robot velocity, events)")
    print("\n".join(lines))
    return 0
