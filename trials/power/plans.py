"""The plans whose power is estimated: the study's own plan.csv, or a D-optimal plan of another size
designed from the study's spec; each with the facts the analyses need (model rows, pedestrians, arms)."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from designs.constraints import compile_restrictions
from designs.exchange import check_runs, optimal_design
from designs.factors import CategoricalFactor, DesignFactor
from designs.model import Model
from designs.spec import StudySpec, read_spec
from trials.errors import StudyError
from trials.power.seeds import derived
from trials.scenario import CONTROLLER, PEDESTRIANS
from trials.study import SPEC, StudyFolder


@dataclass(frozen=True)
class PowerPlan:
    """One plan to test: its runs as plan rows (factor values as plan.csv spells them, with run codes),
    their coded settings, and the model the report fits to them."""

    runs: int
    source: str
    model: Model
    rows: tuple[dict[str, str], ...]
    settings: np.ndarray
    #: The public levels of the Controller factor (arm labels when blinded), empty without one.
    arms: tuple[str, ...]
    blinded: bool

    @property
    def codes(self) -> list[str]:
        return [row["run_code"] for row in self.rows]

    def pedestrians(self) -> list[int]:
        """Each run's number of pedestrians (0 when the plan has no Pedestrians factor)."""
        return [int(float(row[PEDESTRIANS])) if PEDESTRIANS in row else 0 for row in self.rows]

    def arm_of_runs(self) -> list[str]:
        """Each run's Controller level (arm label when blinded; '' without a Controller factor)."""
        return [row.get(CONTROLLER, "") for row in self.rows]


def study_spec(folder: StudyFolder) -> tuple[StudySpec, Model]:
    """The study's public spec and model (a blinded factor's levels are its arm labels).

    Raises:
        StudyError: the folder has no plan.
    """
    folder.require_plan()
    spec = read_spec(folder.path(SPEC))
    return spec, spec.build_model()


def _controller(spec: StudySpec) -> tuple[tuple[str, ...], bool]:
    factor = next((f for f in spec.design_factors if f.name == CONTROLLER), None)
    if not isinstance(factor, CategoricalFactor):
        return (), False
    return factor.levels, spec.blind_factor is not None and spec.blind_factor.name == CONTROLLER


def _encode(factor: DesignFactor, value: str) -> float:
    return factor.encode(value) if isinstance(factor, CategoricalFactor) else factor.encode(float(value))


def own_plan(folder: StudyFolder) -> PowerPlan:
    """The study's plan.csv as it stands (checked against design.json).

    Raises:
        StudyError: no plan, or a plan that does not match its design.
    """
    spec, model = study_spec(folder)
    rows = tuple({k: v for k, v in row.items() if k != "order"} for row in folder.read_plan())
    settings = np.array([[_encode(f, row[f.name]) for f in model.factors] for row in rows], dtype=float).reshape(len(rows), len(model.factors))
    arms, blinded = _controller(spec)
    return PowerPlan(len(rows), "the study's plan.csv", model, rows, settings, arms, blinded)


def designed_plan(folder: StudyFolder, runs: int, power_seed: int) -> PowerPlan:
    """An optimal plan of `runs` runs for the study's spec: its model, criterion, restrictions and blocks (the
    exchange seeded from the power seed).

    Raises:
        StudyError: no plan; DesignError: too few runs for the model.
    """
    spec = replace(study_spec(folder)[0], runs=runs)
    model = spec.build_model()
    check_runs(model, runs)
    seed = derived(power_seed, "design", runs)
    restrictions = compile_restrictions(spec.disallowed, spec.constraints, model.factors, "study.toml [study]")
    design = optimal_design(model, runs, seed=seed, starts=spec.starts, criterion=spec.criterion, restrictions=restrictions,
                            per_run=spec.per_run())
    fixed = {f.name: _cell(f.value) for f in spec.fixed_factors}
    rows = tuple(
        {"run_code": f"P{index + 1:03d}", **{f.name: _cell(f.decode(s)) for f, s in zip(model.factors, setting)}, **fixed}
        for index, setting in enumerate(design.settings)
    )
    arms, blinded = _controller(spec)
    source = f"{spec.criterion}-optimal, {runs} runs (exchange seed {seed})"
    return PowerPlan(runs, source, model, rows, np.asarray(design.settings, dtype=float), arms, blinded)


def _cell(value: float | str) -> str:
    """A factor value as plan.csv spells it (whole numbers without a decimal point)."""
    if isinstance(value, str):
        return value
    return str(int(value)) if float(value).is_integer() else f"{value:g}"


def plans_to_test(folder: StudyFolder, sizes: list[int] | None, power_seed: int) -> list[PowerPlan]:
    """The study's own plan, or one D-optimal plan per size in `sizes` (a size equal to the study's runs
    uses its own plan)."""
    own = own_plan(folder)
    if not sizes:
        return [own]
    if len(set(sizes)) != len(sizes):
        raise StudyError(f"--runs: each size once, got {','.join(map(str, sizes))}")
    return [own if runs == own.runs else designed_plan(folder, runs, power_seed) for runs in sorted(sizes)]
