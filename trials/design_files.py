"""Write a built plan into the study folder: public files and the sealed key, all at once (their
content from `trials.study`, `designs.spec` and, when asked for, the design figures)."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import tomli_w

from designs.export import design_record, plan_table
from designs.plan import StudyPlan
from designs.spec import spec_to_toml
from trials.analysis_plan import COMMITMENT as PLAN_COMMITMENT
from trials.analysis_plan import TABLE as ANALYSIS_TABLE
from trials.analysis_plan import commitment
from trials.atomic import write_files
from trials.controllers.plugins import TABLE as CONTROLLERS_TABLE
from trials.errors import StudyError
from trials.study import (
    ALLOCATION,
    DESIGN,
    DESIGN_DIGEST,
    DESIGN_FIGURES,
    PLAN,
    SEALED,
    SEALED_CONTROLLERS,
    SEALED_SPEC,
    SPEC,
    StudyFolder,
    design_digest,
    evaluated_figures,
    json_content,
    plan_content,
    plan_digest,
    private_folder,
    utc_now,
)

if TYPE_CHECKING:
    import numpy as np

    from designs.diagnostics import Diagnostics
    from designs.model import Model


def write_design(folder: StudyFolder, plan: StudyPlan, sealed_spec_text: str | None = None,
                 tables: Mapping[str, Mapping[str, Any]] | None = None, figures_dpi: int | None = None,
                 before_commit: Callable[[], object] | None = None) -> list[Path]:
    """Write study.toml, plan.csv, design.json, the design figures when `figures_dpi` is given (PNG at that
    resolution, and SVG) and the sealed key (sealed/ 0700, its files 0600).

    `sealed_spec_text` is the researcher's own spec when it names a blinded factor's levels;
    it is kept under sealed/. `tables` are the study's own tables beside the design (`[run]`:
    `trials.run_settings`; `[robot]`: `trials.robot.settings`; `[analysis]`: `trials.analysis_plan`, committed to in
    design.json; `[controllers]`: `trials.controllers.plugins`, under sealed/ when blinded), written after the design's.
    `before_commit` runs once every file is staged (`trials.atomic.write_files`). Returns the public files written.
    """
    created = utc_now()
    table = plan_table(plan)
    record = {**design_record(plan, created, ALLOCATION), "plan": plan_digest(*table)}
    if tables and tables.get(ANALYSIS_TABLE):
        record[PLAN_COMMITMENT] = commitment(dict(tables[ANALYSIS_TABLE]))
    record[DESIGN_DIGEST] = design_digest(record)
    own = {name: dict(table) for name, table in (tables or {}).items() if table}
    # A blinded study's own controllers would name its arms' levels: they are kept under sealed/ instead.
    controllers = own.pop(CONTROLLERS_TABLE, None) if plan.sealed is not None else None
    own_tables = "".join(f"\n{tomli_w.dumps({name: table})}" for name, table in own.items())
    public = {
        folder.path(SPEC): (spec_to_toml(plan.spec) + own_tables).encode(),
        folder.path(PLAN): plan_content(*table),
        folder.path(DESIGN): json_content(record),
    }
    if figures_dpi is not None:
        public.update(design_figures(folder, plan, figures_dpi))
    secret: dict[Path, bytes] = {}
    if plan.sealed is not None:
        # Exactly the committed fields: the commitment covers the key file's every field.
        secret[folder.path(ALLOCATION)] = json_content(plan.sealed.to_dict())
    if sealed_spec_text is not None:
        secret[folder.path(SEALED_SPEC)] = sealed_spec_text.encode()
    if controllers:
        secret[folder.path(SEALED_CONTROLLERS)] = tomli_w.dumps({CONTROLLERS_TABLE: controllers}).encode()
    if secret:
        private_folder(folder, folder.path(SEALED))
    write_files({**public, **secret}, private=set(secret), before_commit=before_commit)
    return list(public)


def design_figures(folder: StudyFolder, plan: StudyPlan, dpi: int) -> dict[Path, bytes]:
    """The plan's design evaluation figures under the study's own names (DESIGN_FIGURES)."""
    content = figure_content(plan.spec.name, plan.model, plan.design.settings, plan.diagnostics, dpi)
    return {folder.path(name): data for name, data in zip(DESIGN_FIGURES, content, strict=True)}


def write_evaluation_figures(folder: StudyFolder, evaluated: Sequence[EvaluatedPlan], dpi: int, force: bool) -> list[Path]:
    """Write the design figures of plans brought to `--evaluate` or `--compare` into the study folder, named after each
    plan's file (`evaluated_figures`), all at once. Refused, before anything is drawn, when two plans' files share a
    name or, without `force`, when a figure of that name is already there."""
    stems = [plan.path.stem for plan in evaluated]
    if len(set(stems)) < len(stems):
        raise StudyError(f"--figures: both plans' files are named {stems[0]}{evaluated[0].path.suffix}, so their figures "
                         "would share names; rename one")
    targets = [[folder.path(name) for name in evaluated_figures(stem)] for stem in stems]
    present = [path for paths in targets for path in paths if path.exists()]
    if present and not force:
        raise StudyError(f"{present[0]} already exists; pass --force to replace the evaluated plans' figures")
    files: dict[Path, bytes] = {}
    for plan, paths in zip(evaluated, targets, strict=True):
        content = figure_content(plan.path.name, plan.model, plan.settings, plan.diagnostics, dpi)
        files.update(zip(paths, content, strict=True))
    write_files(files)
    return list(files)


def figure_content(name: str, model: Model, settings: np.ndarray, diagnostics: Diagnostics, dpi: int) -> tuple[bytes, ...]:
    """JMP's design evaluation views of a design, in DESIGN_FIGURES' order, each as PNG (at `dpi`) and SVG: the
    correlation map, and the fraction of design space plot with the prediction variance profile."""
    # matplotlib (a third of a second) loads only when the figures are asked for.
    from analysis.figures import correlation_map_figure, design_evaluation_figure
    from designs.diagnostics import fraction_of_design_space, variance_profiles

    correlations = correlation_map_figure(diagnostics.correlation_columns, diagnostics.correlations,
                                          f"{name}: correlations of model columns")
    profiles = [(v.factor, v.x, v.variance, v.labels) for v in variance_profiles(model, settings)]
    evaluation = design_evaluation_figure(fraction_of_design_space(model, settings), profiles, f"{name}: prediction variance")
    return correlations.png(dpi), correlations.svg(), evaluation.png(dpi), evaluation.svg()


@dataclass(frozen=True)
class EvaluatedPlan:
    """A plan the researcher brought, as `trials design --evaluate` diagnosed it."""

    path: Path
    model: Model
    settings: np.ndarray
    diagnostics: Diagnostics
