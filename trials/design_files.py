"""Write a built plan into the study folder: public files and the sealed key, all at once (their
content from `trials.study`, `designs.spec` and, when asked for, the design figures)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import tomli_w

from designs.export import design_record, plan_table
from designs.plan import StudyPlan
from designs.spec import spec_to_toml
from trials.atomic import write_files
from trials.run_settings import TABLE
from trials.study import (
    ALLOCATION,
    CORRELATION_MAP,
    CORRELATION_MAP_SVG,
    DESIGN,
    DESIGN_EVALUATION,
    DESIGN_EVALUATION_SVG,
    PLAN,
    SEALED,
    SEALED_SPEC,
    SPEC,
    StudyFolder,
    json_content,
    plan_content,
    plan_digest,
    private_folder,
    utc_now,
)


def write_design(folder: StudyFolder, plan: StudyPlan, sealed_spec_text: str | None = None,
                 run: Mapping[str, Any] | None = None, figures_dpi: int | None = None) -> list[Path]:
    """Write study.toml, plan.csv, design.json, the design figures when `figures_dpi` is given (PNG at that
    resolution, and SVG) and the sealed key (sealed/ 0700, its files 0600).

    `sealed_spec_text` is the researcher's own spec when it names a blinded factor's levels;
    it is kept under sealed/. `run` is the spec's `[run]` table (`trials.run_settings`), written
    after the design's tables. Returns the public files written.
    """
    created = utc_now()
    table = plan_table(plan)
    record = {**design_record(plan, created, ALLOCATION), "plan": plan_digest(*table)}
    public = {
        folder.path(SPEC): (spec_to_toml(plan.spec) + (f"\n{tomli_w.dumps({TABLE: dict(run)})}" if run else "")).encode(),
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
    if secret:
        private_folder(folder, folder.path(SEALED))
    write_files({**public, **secret}, private=set(secret))
    return list(public)


def design_figures(folder: StudyFolder, plan: StudyPlan, dpi: int) -> dict[Path, bytes]:
    """JMP's design evaluation views of the plan, each as PNG (at `dpi`) and SVG: the correlation map, and the
    fraction of design space plot with the prediction variance profile."""
    # matplotlib (a third of a second) loads only when the figures are asked for.
    from analysis.figures import correlation_map_figure, design_evaluation_figure
    from designs.diagnostics import fraction_of_design_space, variance_profiles

    d = plan.diagnostics
    correlations = correlation_map_figure(d.correlation_columns, d.correlations, f"{plan.spec.name}: correlations of model columns")
    profiles = [(v.factor, v.x, v.variance, v.labels) for v in variance_profiles(plan.model, plan.design.settings)]
    evaluation = design_evaluation_figure(fraction_of_design_space(plan.model, plan.design.settings), profiles,
                                          f"{plan.spec.name}: prediction variance")
    return {folder.path(CORRELATION_MAP): correlations.png(dpi), folder.path(CORRELATION_MAP_SVG): correlations.svg(),
            folder.path(DESIGN_EVALUATION): evaluation.png(dpi), folder.path(DESIGN_EVALUATION_SVG): evaluation.svg()}
