"""A whole `trials power` request on one study: the plans, the model-based data sets, the closed-loop
campaigns (resumed from power.csv), and the files and console lines that report them."""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from tqdm import tqdm

from analysis.plan import AnalysisPlan
from designs.diagnostics import diagnose
from designs.spec import StudySpec
from trials.analysis_plan import plan_in_force
from trials.atomic import write_files, writing
from trials.controllers import registry
from trials.errors import StudyError
from trials.power import campaigns as campaign_file
from trials.power import model_based
from trials.power.closed_loop import CampaignResult, campaign_seed
from trials.power.execution import Where, batches, check_ray, run_batches
from trials.power.figure import power_figure
from trials.power.plans import PowerPlan, plans_to_test, study_spec
from trials.power.seeds import fresh_seed
from trials.power.summary import FORMAT, PlanPower, focus_terms, plan_power, power_json, power_markdown, power_record
from trials.run_settings import override, read_run_settings
from trials.runner import RunOptions
from trials.study import POWER_CAMPAIGNS, POWER_FIGURE, POWER_MARKDOWN, POWER_RECORD, SPEC, StudyFolder


@dataclass(frozen=True)
class PowerRequest:
    """What `trials power` was asked (see its --help for each option)."""

    seed: int | None = None
    simulations: int = 400
    campaigns: int | None = None
    sizes: list[int] | None = None
    target: float = 0.8
    shares: tuple[float, float] = (0.5, 0.8)
    terms: tuple[str, ...] | None = None
    run_sd: float = 0.5
    participants: int | None = None
    controllers: tuple[str, ...] | None = None
    workers: int | None = None
    ray: str | None = None
    batch: int = 1
    #: Closed-loop run settings over the study's [run] table (None: the table's, else its defaults).
    perception: str | None = None
    timeout_s: float | None = None
    weights: str | None = None


@dataclass(frozen=True)
class PowerOutcome:
    """What was written and the console summary."""

    record: dict[str, Any]
    powers: list[PlanPower]
    lines: list[str]


def _name(out: Path, name: str) -> Path:
    return out / Path(name).name


def power_seed(out: Path, given: int | None) -> int:
    """The given seed, else the one an earlier (maybe interrupted) run recorded in OUT/power.json, else a fresh one."""
    if given is not None:
        return given
    record = _name(out, POWER_RECORD)
    if record.exists():
        try:
            return int(json.loads(record.read_text(encoding="utf-8"))["power_seed"])
        except (ValueError, KeyError, TypeError) as exc:
            raise StudyError(f"{record}: cannot read its power_seed ({exc}); give --seed or another --out") from None
        except RecursionError:
            raise StudyError(f"{record}: cannot read its power_seed (values nested too deeply to read); give --seed or another --out") from None
    return fresh_seed()


def controllers_for(plans: list[PowerPlan], asked: tuple[str, ...] | None) -> tuple[str, ...]:
    """The controllers the campaigns drive: behind a blinded plan's arms the ones asked (default the paper's two for
    two arms; as many as arms), else the plan's own Controller levels, else the default controller.

    Raises:
        StudyError: an unknown controller, or a count that does not match the arms.
    """
    plan = plans[0]
    known = registry.names()
    for name in asked or ():
        if name not in known:
            raise StudyError(f"--controllers: no controller is called {name!r} (known: {', '.join(known)})")
    if plan.blinded:
        names = asked or registry.AB_PRESET
        if len(names) != len(plan.arms):
            raise StudyError(f"--controllers: the study has {len(plan.arms)} arms ({', '.join(plan.arms)}), got {len(names)} controllers ({', '.join(names)})")
        return tuple(names)
    if asked:
        raise StudyError("--controllers goes with a blinded study; this plan names its controllers itself")
    unknown = [a for a in plan.arms if a not in known]
    if unknown:
        raise StudyError(f"the plan's Controller level {unknown[0]!r} is not a known controller ({', '.join(known)})")
    return plan.arms or (registry.DEFAULT,)


def settings_digest(seed: int, plans: list[PowerPlan], controllers: tuple[str, ...], options: RunOptions, participants: int | None) -> str:
    """A short digest of everything that shapes a campaign, so power.csv never mixes campaigns of other settings."""
    shape = {"seed": seed, "plans": [[list(r.items()) for r in p.rows] for p in plans], "controllers": controllers,
             "options": [asdict(options.settings), asdict(options.noise)], "participants": participants}
    return hashlib.sha256(json.dumps(shape, sort_keys=True, default=str).encode()).hexdigest()[:12]


def _model_based(plans: list[PowerPlan], spec: StudySpec, anticipated: model_based.Anticipated, seed: int, simulations: int,
                 analysis: AnalysisPlan) -> list[list[Any]]:
    verdicts = []
    with tqdm(total=simulations * len(plans), unit="data set", desc="model-based", disable=None, leave=False) as bar:
        for plan in plans:
            beta = model_based.coefficients(plan, spec, anticipated)
            mine = []
            for index in range(simulations):
                mine.append(model_based.simulate(plan, beta, anticipated, model_based.simulation_seed(seed, plan, index), analysis))
                bar.update()
            verdicts.append(mine)
    return verdicts


def _closed_loop(plans: list[PowerPlan], controllers: tuple[str, ...], options: RunOptions, request: PowerRequest,
                 settings: dict[str, Any], out: Path, where: Where) -> list[list[CampaignResult]]:
    """Run the campaigns power.csv does not hold yet; every campaign of every plan, in campaign order."""
    path = _name(out, POWER_CAMPAIGNS)
    columns = campaign_file.header(plans, controllers)
    seed = settings["power_seed"]
    digest = settings["closed_loop"]["settings_digest"]
    assert request.campaigns is not None
    done = {(r.runs, r.campaign): r for r in campaign_file.read_campaigns(path, columns, digest)}
    # Recorded before the first campaign, so an interrupted run resumes with the same power seed.
    write_files({_name(out, POWER_RECORD): power_json({"format": FORMAT, **settings, "status": "running"}).encode()})
    pending = [(i, c, campaign_seed(seed, plan, c)) for i, plan in enumerate(plans)
               for c in range(request.campaigns) if (plan.runs, c) not in done]
    total = request.campaigns * len(plans)
    with tqdm(total=total, initial=total - len(pending), unit="campaign", desc="closed-loop", disable=None) as bar:
        def keep(results: list[CampaignResult]) -> None:
            campaign_file.append_campaigns(path, columns, results, digest)
            done.update({(r.runs, r.campaign): r for r in results})
            bar.update(len(results))

        setup = (plans, controllers, options, request.participants)
        run_batches(batches(pending, request.batch), setup, where, keep)
    return [[done[(plan.runs, c)] for c in range(request.campaigns)] for plan in plans]


def estimate_power(folder: StudyFolder, out: Path, request: PowerRequest) -> PowerOutcome:
    """Estimate the power, write OUT/ (power.json, power.md, power.png, and power.csv with campaigns), and summarise.

    Raises:
        StudyError: no plan, a bad option for this study, Ray missing or unreachable; DesignError: too few runs for the model.
    """
    spec, _ = study_spec(folder)
    analysis, _ = plan_in_force(folder.path(SPEC), spec, folder.read_design())
    seed = power_seed(out, request.seed)
    plans = plans_to_test(folder, request.sizes, seed)
    anticipated = model_based.Anticipated(request.shares[0], request.shares[1], request.run_sd, request.participants, request.terms)
    for plan in plans:
        model_based.coefficients(plan, spec, anticipated)  # checks --terms before any work
    given = {"perception": request.perception, "timeout_s": request.timeout_s, "weights": request.weights}
    options = RunOptions(override(read_run_settings(folder.path(SPEC)), given, "trials power"))
    where = Where(request.workers or 1, request.ray)
    if request.ray is not None:
        if not request.campaigns:
            raise StudyError("--ray runs closed-loop campaigns: give --campaigns K too")
        check_ray(request.ray)
    controllers = controllers_for(plans, request.controllers) if request.campaigns else ()
    with writing(out):  # a folder that cannot be made (under /proc, a read-only disk) is one line naming it
        out.mkdir(parents=True, exist_ok=True)
    settings: dict[str, Any] = {
        "power_seed": seed, "study": spec.name, "alpha": spec.alpha, "planned_test": analysis.describe_test(),
        "model_based": {"simulations": request.simulations, "assumed": anticipated.describe(), "shares": list(request.shares),
                        "run_sd": request.run_sd, "participants": request.participants, "terms": list(request.terms) if request.terms else None,
                        "snr": spec.snr, "anticipated": dict(spec.anticipated)},
    }
    if request.campaigns:
        settings["closed_loop"] = {"campaigns": request.campaigns, "controllers": list(controllers), **asdict(options.settings),
                                   "participants": request.participants,
                                   "settings_digest": settings_digest(seed, plans, controllers, options, request.participants)}
    model_verdicts = _model_based(plans, spec, anticipated, seed, request.simulations, analysis)
    campaigns = _closed_loop(plans, controllers, options, request, settings, out, where) if request.campaigns else [[] for _ in plans]
    powers = []
    for plan, verdicts, results in zip(plans, model_verdicts, campaigns):
        analytic = {t.term: t.power for t in diagnose(plan.model, plan.settings, alpha=spec.alpha, snr=spec.snr, anticipated=spec.anticipated).term_power}
        powers.append(plan_power(plan, analytic, verdicts, results, spec.alpha, analysis.alpha))
    terms = focus_terms(plans[0])
    record = power_record(powers, settings, request.target, terms)
    figure = _name(out, POWER_FIGURE)
    write_files({_name(out, POWER_RECORD): power_json(record).encode(),
                 _name(out, POWER_MARKDOWN): power_markdown(record, powers, spec.name, figure.name).encode()})
    power_figure(powers, request.target, figure)
    return PowerOutcome(record, powers, summary_lines(record, powers, out, where if request.campaigns else None))


def summary_lines(record: dict[str, Any], powers: list[PlanPower], out: Path, where: Where | None) -> list[str]:
    """The console summary: the seed, each plan's power on the focus terms, the smallest plan reaching the target."""
    terms = record["target_terms"]
    lines = [f"Power seed {record['power_seed']}; alpha {record['alpha']:g}; model-based: {record['model_based']['assumed']}."]
    if where is not None:
        lines.append(f"Closed-loop campaigns ran on {where.describe()}.")
    for p in powers:
        parts = [f"{t} model-based {p.judgments[t].text()}" + (f", closed-loop {p.closed_terms[t].text()}" if p.campaigns else "") for t in terms]
        rows = [f">= {k}: {e.text()}" for k, e in p.rows.items()]
        lines.append(f"{p.runs} runs: " + "; ".join(parts) + (f"; Table II rows (model-based) {', '.join(rows)}" if rows else ""))
    lines += [f"{p.runs} runs: planned primary test ({record['planned_test']}) model-based {p.planned.text()}"
              for p in powers if p.planned is not None]
    found = record["smallest_runs"]
    lines.append(f"Smallest plan reaching {record['target']:g} on the planned primary test: model-based {found['planned'] or 'none tried'}.")
    lines.append(f"Smallest plan reaching {record['target']:g} on {', '.join(terms)}: model-based {found['model_based'] or 'none tried'}"
                 + (f", closed-loop {found['closed_loop'] or 'none tried'}" if found["closed_loop"] is not None or where is not None else "") + ".")
    lines.append(f"Wrote {', '.join(Path(n).name for n in (POWER_RECORD, POWER_MARKDOWN, POWER_FIGURE) + ((POWER_CAMPAIGNS,) if where else ()))} in {out}")
    return lines
