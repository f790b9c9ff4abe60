"""Write a built plan into the study folder: public files and the sealed key, all at once."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

from analysis.figures import correlation_map_png
from designs.export import design_record, plan_table
from designs.plan import StudyPlan
from designs.spec import spec_to_toml
from trials.atomic import write_files
from trials.study import ALLOCATION, CORRELATION_MAP, DESIGN, PLAN, SEALED_SPEC, SPEC, StudyFolder, utc_now


def write_design(folder: StudyFolder, plan: StudyPlan, sealed_spec_text: str | None = None) -> list[Path]:
    """Write study.toml, plan.csv, design.json, correlation_map.png and the sealed key.

    `sealed_spec_text` is the researcher's own spec when it names a blinded factor's levels;
    it is kept under sealed/. Returns the public files written.
    """
    created = utc_now()
    header, rows = plan_table(plan)
    table = io.StringIO()
    writer = csv.writer(table, lineterminator="\n")
    writer.writerow(header)
    writer.writerows(rows)
    d = plan.diagnostics
    # The figure first: it does not need the cvxpy bound, which may still be solving.
    figure = correlation_map_png(d.correlation_columns, d.correlations, f"{plan.spec.name}: correlations of model columns")
    public = {
        folder.path(SPEC): spec_to_toml(plan.spec).encode(),
        folder.path(PLAN): table.getvalue().encode(),
        folder.path(DESIGN): (json.dumps(design_record(plan, created, ALLOCATION), indent=1) + "\n").encode(),
        folder.path(CORRELATION_MAP): figure,
    }
    secret: dict[Path, bytes] = {}
    if plan.sealed is not None:
        key = {**plan.sealed.to_dict(), "created": created}
        secret[folder.path(ALLOCATION)] = (json.dumps(key, indent=1) + "\n").encode()
    if sealed_spec_text is not None:
        secret[folder.path(SEALED_SPEC)] = sealed_spec_text.encode()
    write_files({**public, **secret})
    return list(public)
