"""From a study spec to a randomized, optionally blinded run plan with its diagnostics."""

from __future__ import annotations

import secrets
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from designs.blinding import SealedAllocation, arm_labels, seal
from designs.bound import ApproximateDesign, approximate_d_optimal
from designs.constraints import Restrictions, compile_restrictions
from designs.diagnostics import Diagnostics, diagnose
from designs.exchange import ExactDesign, candidate_set, check_runs, optimal_design
from designs.factors import CovariateFactor
from designs.model import Model
from designs.spec import StudySpec, check_search_size

#: Run-code alphabet: capitals and digits without the look-alikes 0/O, 1/I/L, 2/Z, 5/S, 8/B.
CODE_ALPHABET = "ACDEFGHJKMNPQRTUVWXY34679"
CODE_LENGTH = 5


@dataclass(frozen=True)
class PlannedRun:
    """One row of the public run sheet; `values` holds every factor, fixed ones included."""

    order: int
    code: str
    values: dict[str, float | str]
    settings: np.ndarray


@dataclass(frozen=True)
class StudyPlan:
    """A built study: the public spec (arm labels when blind), design, D-efficiency bound, diagnostics, runs."""

    spec: StudySpec
    model: Model
    design: ExactDesign
    bound: ApproximateDesign
    diagnostics: Diagnostics
    runs: tuple[PlannedRun, ...]
    sealed: SealedAllocation | None
    restrictions: Restrictions

    @property
    def seed(self) -> int:
        """The public study seed (the spec's, or the one drawn for it)."""
        assert self.spec.seed is not None
        return self.spec.seed

    @property
    def d_efficiency_vs_bound(self) -> float:
        return 100.0 * self.diagnostics.d_efficiency / self.bound.d_efficiency


@dataclass(frozen=True)
class KeptRuns:
    """The runs of a study being augmented, as (order, run code, settings), which they keep, and its sealed key."""

    runs: tuple[tuple[int, str, np.ndarray], ...]
    sealed: SealedAllocation | None


def build_plan(spec: StudySpec, allocation_seed: int | None = None,
               progress: Callable[[int, int], None] | None = None, kept: KeptRuns | None = None,
               threads: int = 1) -> StudyPlan:
    """Design, bound, diagnose and randomize a study; seal its blind factor if it has one.

    `progress(done, starts)` follows the exchange's starts, searched on `threads` threads. With `kept`
    (augmenting; `spec` is the study's public spec, `spec.runs` the new total) the kept runs stay first and
    unchanged, the new ones are searched around them and randomized after them, and the sealed key stays as it is;
    a blinded study's new runs are split evenly between its arms first (`balanced_arms`), as its plan splits them. A new
    blinded plan keeps its arms balanced within each block (no two arms' counts more than one apart): when the search's
    best design is not, it searches again with the arms split so.

    The public seed (drawn when the spec has none) drives the exchange starts, the run order, the run codes
    and an augmentation's arm labels (public already in plan.csv); the blind allocation uses its own secret seed.
    """
    seed = spec.seed if spec.seed is not None else secrets.randbits(31)
    spec = replace(spec, seed=seed)
    sealed = kept.sealed if kept is not None else None
    blind = spec.blind_factor
    if blind is not None and kept is None:
        sealed = seal(blind.name, blind.levels, allocation_seed)
        spec = spec.with_factor(replace(blind, levels=arm_labels(len(blind.levels))))
    model = spec.build_model()
    check_search_size(spec, model.p)
    check_runs(model, spec.runs)
    restrictions = compile_restrictions(spec.disallowed, spec.constraints, model.factors, "study.toml [study]")
    bound = approximate_d_optimal(model.matrix(candidate_set(model, restrictions)))
    design_seed, order_seed, code_seed, arm_seed = np.random.SeedSequence(seed).spawn(4)
    old = tuple(PlannedRun(order, code, _values(spec, model, settings), settings)
                for order, code, settings in (kept.runs if kept is not None else ()))
    per_run = spec.per_run()
    if blind is not None and old:
        arm = [f.name for f in model.factors].index(blind.name)
        new_arms = balanced_arms(np.array([run.settings[arm] for run in old]), spec.runs - len(old), len(blind.levels),
                                 np.random.default_rng(arm_seed))
        per_run[arm] = np.concatenate([np.zeros(len(old)), new_arms])
    def search(fixed: dict[int, np.ndarray]) -> ExactDesign:
        return optimal_design(model, spec.runs, seed=int(design_seed.generate_state(1)[0]), starts=spec.starts,
                              criterion=spec.criterion, restrictions=restrictions, progress=progress,
                              kept=np.array([run.settings for run in old]).reshape(len(old), len(model.factors)),
                              per_run=fixed, threads=threads)

    design = search(per_run)
    if blind is not None and not old:
        arm = [f.name for f in model.factors].index(blind.name)
        size = spec.runs // spec.blocks
        blocks = design.settings[:, arm].reshape(spec.blocks, size)
        if any(np.ptp(np.bincount(b.astype(int), minlength=len(blind.levels))) > 1 for b in blocks):
            # The best design found favours an arm within a block: search again with the arms split evenly in each.
            rng = np.random.default_rng(arm_seed)
            per_run[arm] = np.concatenate([balanced_arms(np.zeros(0), size, len(blind.levels), rng) for _ in range(spec.blocks)])
            design = search(per_run)
    diagnostics = diagnose(model, design.settings, alpha=spec.alpha, snr=spec.snr, anticipated=spec.anticipated)
    order = len(old) + _run_order(spec, spec.runs - len(old), np.random.default_rng(order_seed))
    codes = run_codes(spec.runs - len(old), np.random.default_rng(code_seed), taken={run.code for run in old})
    runs = old + tuple(
        PlannedRun(len(old) + position + 1, codes[position], _values(spec, model, design.settings[row]), design.settings[row])
        for position, row in enumerate(order)
    )
    return StudyPlan(spec, model, design, bound, diagnostics, runs, sealed, restrictions)


def balanced_arms(kept: np.ndarray, count: int, arms: int, rng: np.random.Generator) -> np.ndarray:
    """The arm (0 .. arms-1) of each of `count` new runs of a blinded study whose runs so far have arms `kept`.

    Each arm gets count // arms of them; the remainder goes to the arms with the fewest runs so far, ties
    drawn at random, so no arm is favoured by the exchange's search (which may give it every new run).
    """
    share, extra = divmod(count, arms)
    held = np.bincount(kept.astype(int), minlength=arms)
    favoured = np.lexsort((rng.permutation(arms), held))[:extra]
    counts = np.full(arms, share) + np.isin(np.arange(arms), favoured)
    return rng.permutation(np.repeat(np.arange(arms, dtype=float), counts))


def _run_order(spec: StudySpec, count: int, rng: np.random.Generator) -> np.ndarray:
    """The design rows in run order: at random, within each block when blocked; as given when a
    covariate ties each row to a run."""
    if any(isinstance(f, CovariateFactor) for f in spec.factors):
        return np.arange(count)
    size = count // spec.blocks
    return np.concatenate([b * size + rng.permutation(size) for b in range(spec.blocks)])


def run_codes(count: int, rng: np.random.Generator, taken: set[str] | None = None) -> list[str]:
    """`count` distinct random codes, unrelated to run order or arm, none of them in `taken`."""
    codes: list[str] = []
    taken = taken or set()
    while len(codes) < count:
        code = "".join(rng.choice(list(CODE_ALPHABET), size=CODE_LENGTH))
        if code not in codes and code not in taken:
            codes.append(code)
    return codes


def _values(spec: StudySpec, model: Model, settings: np.ndarray) -> dict[str, float | str]:
    design_values = {f.name: f.decode(s) for f, s in zip(model.factors, settings)}
    return {f.name: design_values[f.name] if f.name in design_values else f.value for f in spec.factors}
