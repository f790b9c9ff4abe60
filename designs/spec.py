"""The study spec (`study.toml`): factors, model, runs, seed; read, validated and written.

    [study]
    name = "qualitative"
    runs = 27
    model = "main"            # keywords main, interactions, quadratic, or terms A + B + A*B + A^2
    seed = 2019               # optional: drawn and recorded when absent
    starts = 100              # random starts of the exchange
    snr = 1.0                 # signal-to-noise ratio for the power table
    alpha = 0.05
    criterion = "D"           # D (det X'X), I (average prediction variance) or A (trace of (X'X)^-1)
    disallowed = ["Direction == 'Crossing' and Pedestrians == 6"]   # combinations no run may have
    constraints = ["Speed + 0.5 * Density <= 1.5"]                    # linear limits every run keeps
    blocks = 3                # optional: equal blocks in run order, a Block column and a Block model term

    [anticipated]             # optional: a term's anticipated coefficient for the power (default 1)
    Controller = 0.5          # its columns get +c, -c, +c, ... as in JMP

    [[factors]]
    name = "Pedestrians"
    type = "discrete"         # continuous (low, high) | discrete (levels) | categorical (levels) | fixed (value)
    levels = [2, 4, 6]        # | covariate (values = [...] one per run, or file = "x.csv" with a column of its name)

A blinded categorical factor has `blind = true`. In the public spec that `trials design`
writes, its levels are replaced by `arms = [...]` (opaque labels); the levels themselves
live only in the sealed allocation.
"""

from __future__ import annotations

import csv
import math
import tomllib
from dataclasses import dataclass, field, replace
from numbers import Real
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w

from designs.constraints import compile_restrictions
from designs.errors import DesignError
from designs.exchange import CRITERIA
from designs.factors import (
    BlockFactor,
    CategoricalFactor,
    ContinuousFactor,
    CovariateFactor,
    DesignFactor,
    DiscreteFactor,
    Factor,
    FixedFactor,
    plain,
    validate_factor,
)
from designs.model import Model, parse_model
from designs.questionnaire import LikertItem, questionnaire_from_tables, questionnaire_tables

FACTOR_TYPES = ("continuous", "discrete", "categorical", "fixed", "covariate")
DEFAULT_STARTS = 100
#: The columns plan.csv holds before the factors, and the column in which a plan may name a robot log
#: (`trials.log_trial`); no factor may take these names.
PLAN_COLUMNS = ("order", "run_code")
LOG_COLUMN = "Log"
BLOCK_COLUMN = "Block"
RESERVED_NAMES = (*PLAN_COLUMNS, LOG_COLUMN)
#: Sizes a spec may ask for: the exchange's time grows with runs x starts x candidate points, and
#: beyond these a study takes minutes to design and is almost surely a typing slip.
MAX_RUNS = 1000
MAX_STARTS = 1000
MAX_LEVELS = 20
MAX_CANDIDATES = 10_000
#: starts x runs x factors x p^2, the work of the coordinate exchange: at the limit (e.g. 100 starts of a
#: 6-factor quadratic in 200 runs) the search takes about half a minute.
MAX_SEARCH = 100_000_000
#: Numbers in a spec (levels, ranges, fixed values) are physical settings; larger magnitudes are refused
#: so that coding and plan.csv cells stay exact and short.
MAX_MAGNITUDE = 1e6
MAX_SNR = 100.0


@dataclass(frozen=True)
class StudySpec:
    """A study as the researcher specifies it.

    `arms_sealed` says that the blinded factor's levels are already arm labels (a public
    spec written by `trials design`), so its real levels must come from the sealed key.
    """

    name: str
    factors: tuple[Factor, ...]
    model: str
    runs: int
    seed: int | None = None
    starts: int = DEFAULT_STARTS
    snr: float = 1.0
    alpha: float = 0.05
    arms_sealed: bool = False
    #: Anticipated coefficient per model term for the power table; terms not named get 1.
    anticipated: dict[str, float] = field(default_factory=dict)
    #: Likert items participants answer after each run beside the compliance question ([[questionnaire]]).
    questionnaire: tuple[LikertItem, ...] = ()
    criterion: str = "D"
    disallowed: tuple[str, ...] = ()
    constraints: tuple[str, ...] = ()

    @property
    def blocks(self) -> int:
        """The number of blocks (1: none); the block factor is the last of `factors`."""
        block = next((f for f in self.factors if isinstance(f, BlockFactor)), None)
        return len(block.levels) if block is not None else 1

    @property
    def full_model(self) -> str:
        """The model expression the design is built on: `model`, with the block effect when the study is blocked."""
        return self.model + (f" + {BLOCK_COLUMN}" if self.blocks > 1 else "")

    def build_model(self) -> Model:
        """The design's model (`full_model`) over the design factors."""
        return parse_model(self.full_model, self.design_factors, tuple(f.name for f in self.fixed_factors))

    def per_run(self) -> dict[int, np.ndarray]:
        """Design-factor index -> the coded setting of each run, for the factors the runs fix (block, covariates)."""
        size = self.runs // self.blocks
        fixed: dict[int, np.ndarray] = {}
        for i, factor in enumerate(self.design_factors):
            if isinstance(factor, BlockFactor):
                fixed[i] = np.arange(self.runs, dtype=float) // size
            elif isinstance(factor, CovariateFactor):
                if len(factor.values) != self.runs:
                    raise DesignError(f"covariate {factor.name} has {len(factor.values)} values for {self.runs} runs; "
                                      "give one value per run")
                fixed[i] = np.array([factor.encode(v) for v in factor.values])
        return fixed

    @property
    def design_factors(self) -> tuple[DesignFactor, ...]:
        return tuple(f for f in self.factors if not isinstance(f, FixedFactor))

    @property
    def fixed_factors(self) -> tuple[FixedFactor, ...]:
        return tuple(f for f in self.factors if isinstance(f, FixedFactor))

    @property
    def blind_factor(self) -> CategoricalFactor | None:
        return next((f for f in self.factors if isinstance(f, CategoricalFactor) and f.blind), None)

    def with_factor(self, factor: Factor) -> StudySpec:
        """The same spec with the factor of the same name replaced."""
        return replace(self, factors=tuple(factor if f.name == factor.name else f for f in self.factors))


def read_spec(path: Path) -> StudySpec:
    """Parse and validate a study.toml; DesignError names the file, line or field."""
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise DesignError(f"no study spec at {path}") from None
    except UnicodeDecodeError as exc:
        raise DesignError(f"malformed {path.name}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except OSError as exc:
        raise DesignError(f"cannot read the study spec {path}: {exc.strerror}") from None
    except tomllib.TOMLDecodeError as exc:
        raise DesignError(f"malformed {path.name}: {exc}") from None
    except RecursionError:  # tomllib parses nested arrays and inline tables recursively
        raise DesignError(f"malformed {path.name}: values nested too deeply to read") from None
    return spec_from_dict(data, source=path.name, folder=path.parent)


def spec_from_dict(data: dict[str, Any], source: str, folder: Path | None = None) -> StudySpec:
    """Validate the parsed TOML tables of a spec; `folder` is where a covariate's `file` is found."""
    study = _table(data, "study", source)
    # [run] and [robot] hold how the runs are made, [analysis] how the results are analysed, not the design:
    # trials.run_settings, trials.robot.settings and trials.analysis_plan read them.
    unknown = set(data) - {"study", "factors", "anticipated", "questionnaire", "run", "robot", "analysis", "controllers"}
    if unknown:
        raise DesignError(f"{source}: unknown table {sorted(unknown)[0]!r} (expected [study], [[factors]] and optionally "
                          "[anticipated], [[questionnaire]], [run], [robot], [analysis] and [controllers])")
    raw_factors = data.get("factors")
    if not isinstance(raw_factors, list) or not raw_factors:
        raise DesignError(f"{source}: no [[factors]] given; a study needs at least one factor")
    factors = tuple(factor_from_table(raw, f"{source}: factors[{i}]", folder) for i, raw in enumerate(raw_factors))
    names = [f.name for f in factors]
    for name in names:
        if names.count(name) > 1:
            raise DesignError(f"{source}: two factors are named {name!r}")
    blind = [f for f in factors if isinstance(f, CategoricalFactor) and f.blind]
    if len(blind) > 1:
        raise DesignError(f"{source}: only one factor can be blind, got {[f.name for f in blind]}")
    if not any(not isinstance(f, FixedFactor) for f in factors):
        raise DesignError(f"{source}: every factor is fixed; a design needs at least one varying factor")
    candidates = math.prod(len(f.candidate_settings) for f in factors if not isinstance(f, FixedFactor))
    if candidates > MAX_CANDIDATES:
        raise DesignError(f"{source}: the factors span {candidates} candidate points; at most {MAX_CANDIDATES} "
                          "(fewer factors or levels)")
    allowed = {"name", "runs", "model", "seed", "starts", "snr", "alpha", "criterion", "disallowed", "constraints", "blocks"}
    where = f"{source}: [study]"
    _no_unknown_keys(study, allowed, where)
    name = _string(study, "name", where, default="study")
    if not name.isprintable():
        raise DesignError(f"{where}: name must be one line of printable text, got {name!r}")
    snr = _number(study, "snr", where, default=1.0)
    if not 0 < snr <= MAX_SNR:
        raise DesignError(f"{where}: snr must be a number above 0 and at most {MAX_SNR:g}, got {snr:g}")
    alpha = _number(study, "alpha", where, default=0.05)
    if not 0 < alpha < 1:
        raise DesignError(f"{where}: alpha must be a number between 0 and 1, got {alpha:g}")
    criterion = _string(study, "criterion", where, default="D")
    if criterion not in CRITERIA:
        raise DesignError(f"{where}: criterion must be one of {', '.join(CRITERIA)}, got {criterion!r}")
    disallowed, constraints = _expressions(study, "disallowed", where), _expressions(study, "constraints", where)
    design_factors = tuple(f for f in factors if not isinstance(f, FixedFactor))
    compile_restrictions(disallowed, constraints, design_factors, where, blind[0].name if blind else None)
    runs = _integer(study, "runs", where, minimum=1, maximum=MAX_RUNS)
    assert runs is not None
    blocks = _integer(study, "blocks", where, minimum=1, maximum=runs, required=False) or 1
    if runs % blocks:
        raise DesignError(f"{where}: blocks = {blocks} must divide runs = {runs} (equal blocks)")
    if BLOCK_COLUMN in names:
        raise DesignError(f"{source}: a factor is named {BLOCK_COLUMN!r}, the column of the blocks; rename it")
    return StudySpec(
        name=name,
        factors=factors + ((BlockFactor.of(blocks),) if blocks > 1 else ()),
        model=_string(study, "model", where, default="main"),
        runs=runs,
        seed=_integer(study, "seed", where, minimum=0, maximum=2**63 - 1, required=False),
        starts=_integer(study, "starts", where, minimum=1, maximum=MAX_STARTS, required=False) or DEFAULT_STARTS,
        snr=snr,
        alpha=alpha,
        arms_sealed=any("arms" in raw for raw in raw_factors if isinstance(raw, dict)),
        anticipated=_anticipated(data, source),
        questionnaire=questionnaire_from_tables(data.get("questionnaire"), source),
        criterion=criterion,
        disallowed=disallowed,
        constraints=constraints,
    )


def _expressions(study: dict[str, Any], key: str, where: str) -> tuple[str, ...]:
    """An optional list of expression strings (checked by `designs.constraints`)."""
    value = study.get(key, [])
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise DesignError(f"{where}: {key} must be a list of strings (expressions over factor names), got {value!r}")
    return tuple(value)


def check_search_size(spec: StudySpec, p: int) -> None:
    """DesignError when starts x runs x factors x p^2 (p the model's parameters) exceeds MAX_SEARCH."""
    work = spec.starts * spec.runs * len(spec.design_factors) * p * p
    if work > MAX_SEARCH:
        raise DesignError(f"starts x runs x factors x p^2 = {spec.starts} x {spec.runs} x {len(spec.design_factors)} x {p}^2 "
                          f"= {work:,} exceeds {MAX_SEARCH:,} (about half a minute of search); ask for fewer starts, runs or terms")


def _anticipated(data: dict[str, Any], source: str) -> dict[str, float]:
    """The optional [anticipated] table: model term -> its anticipated coefficient (a number)."""
    table = data.get("anticipated", {})
    if not isinstance(table, dict):
        raise DesignError(f"{source}: [anticipated] must be a table of term = coefficient, got {table!r}")
    return {term: _number(table, term, f"{source}: [anticipated]") for term in table}


def spec_to_toml(spec: StudySpec) -> str:
    """The spec as TOML; a blinded factor lists only its arm labels (`arms`)."""
    study: dict[str, Any] = {"name": spec.name, "runs": spec.runs, "model": spec.model}
    if spec.seed is not None:
        study["seed"] = spec.seed
    study.update(starts=spec.starts, snr=spec.snr, alpha=spec.alpha)
    if spec.criterion != "D":
        study["criterion"] = spec.criterion
    if spec.disallowed:
        study["disallowed"] = list(spec.disallowed)
    if spec.constraints:
        study["constraints"] = list(spec.constraints)
    if spec.blocks > 1:
        study["blocks"] = spec.blocks
    tables: dict[str, Any] = {"study": study}
    if spec.anticipated:
        tables["anticipated"] = dict(spec.anticipated)
    if spec.questionnaire:
        tables["questionnaire"] = questionnaire_tables(spec.questionnaire)
    factors = [factor_table(f) for f in spec.factors if not isinstance(f, BlockFactor)]
    return tomli_w.dumps({**tables, "factors": factors})


def factor_table(factor: Factor) -> dict[str, Any]:
    """One [[factors]] table; a blind factor lists its arm labels as `arms`."""
    table: dict[str, Any] = {"name": factor.name, "type": factor.kind}
    if isinstance(factor, CovariateFactor):
        table["values"] = [plain(v) for v in factor.values]
    elif isinstance(factor, ContinuousFactor):
        table.update(low=plain(factor.low), high=plain(factor.high))
    elif isinstance(factor, DiscreteFactor):
        table["levels"] = [plain(v) for v in factor.levels]
    elif isinstance(factor, CategoricalFactor):
        table.update({"blind": True, "arms": list(factor.levels)} if factor.blind else {"levels": list(factor.levels)})
    else:
        table["value"] = plain(factor.value)
    if getattr(factor, "units", ""):
        table["units"] = factor.units
    return table


def factor_from_table(raw: Any, where: str, folder: Path | None = None) -> Factor:
    """One [[factors]] table as its factor, validated; DesignError names `where`. A covariate's `file` is
    read from `folder`."""
    if not isinstance(raw, dict):
        raise DesignError(f"{where}: expected a table with name and type")
    name = _string(raw, "name", where)
    where = f"{where} ({name})"
    if not (name.isascii() and name.isidentifier()):
        raise DesignError(f"{where}: factor names must be ASCII letters, digits and _ (no spaces), got {name!r}")
    if name.casefold() in {n.casefold() for n in RESERVED_NAMES}:
        raise DesignError(f"{where}: {name!r} is a plan.csv column of its own; a factor cannot be named "
                          f"{', '.join(RESERVED_NAMES)}")
    kind = _string(raw, "type", where)
    if kind not in FACTOR_TYPES:
        raise DesignError(f"{where}: unknown factor type {kind!r} (expected {', '.join(FACTOR_TYPES)})")
    units = _string(raw, "units", where, default="")
    common = {"name", "type", "units"}
    factor: Factor
    if kind == "continuous":
        _no_unknown_keys(raw, common | {"low", "high"}, where)
        factor = ContinuousFactor(name, _number(raw, "low", where), _number(raw, "high", where), units)
    elif kind == "covariate":
        _no_unknown_keys(raw, common | {"values", "file"}, where)
        values = _covariate_values(raw, name, where, folder)
        if min(values) == max(values):
            raise DesignError(f"{where}: a covariate needs at least two different values, got {values[0]:g} for every run")
        factor = CovariateFactor(name, min(values), max(values), units, values)
    elif kind == "discrete":
        _no_unknown_keys(raw, common | {"levels"}, where)
        levels = _levels(raw, where)
        for level in levels:
            if not isinstance(level, Real) or isinstance(level, bool):
                raise DesignError(f"{where}: level {level!r} is not a number; a discrete numeric factor needs numeric levels")
        factor = DiscreteFactor(name, tuple(_finite(float(v), "level", where) for v in levels), units)
    elif kind == "categorical":
        _no_unknown_keys(raw, common | {"levels", "blind", "arms"}, where)
        blind = raw.get("blind", False)
        if not isinstance(blind, bool):
            raise DesignError(f"{where}: blind must be true or false, got {blind!r}")
        key = "arms" if "arms" in raw else "levels"
        if key == "arms" and not blind:
            raise DesignError(f"{where}: arms are only for a blind factor; use levels")
        levels = _levels(raw, where, key)
        for level in levels:
            if not isinstance(level, str):
                raise DesignError(f"{where}: level {level!r} is not a string; a categorical factor's levels are names "
                                  "(quote numbers: \"2\")")
            if not level.isprintable():
                raise DesignError(f"{where}: level {level!r} must be one line of printable text")
            if level.strip() and level != level.strip():  # every study CSV is read with its cells stripped: the plan would no longer match
                raise DesignError(f"{where}: level {level!r} begins or ends with a space; write {level.strip()!r}")
        factor = CategoricalFactor(name, tuple(levels), blind)
    else:
        _no_unknown_keys(raw, common | {"value"}, where)
        if "value" not in raw:
            raise DesignError(f"{where}: a fixed factor needs a value")
        value = raw["value"]
        if isinstance(value, bool) or not isinstance(value, (Real, str)):
            raise DesignError(f"{where}: value must be a number or a string, got {value!r}")
        if isinstance(value, str) and not value.isprintable():
            raise DesignError(f"{where}: value {value!r} must be one line of printable text")
        factor = FixedFactor(name, _finite(float(value), "value", where) if isinstance(value, Real) else value, units)
    validate_factor(factor, where)
    return factor


def _covariate_values(raw: dict[str, Any], name: str, where: str, folder: Path | None) -> tuple[float, ...]:
    """A covariate's values, one per run: `values = [...]`, or the column named after it in the CSV `file`."""
    if ("values" in raw) == ("file" in raw):
        raise DesignError(f"{where}: a covariate needs either values = [...] (one per run) or file = \"name.csv\"")
    if "values" in raw:
        cells: list[Any] = raw["values"] if isinstance(raw["values"], list) else [raw["values"]]
        places = [f"values[{i}]" for i in range(len(cells))]
    else:
        path = (folder or Path(".")) / _string(raw, "file", where)
        try:
            with path.open(newline="", encoding="utf-8-sig") as handle:
                rows = list(csv.DictReader(handle))
        except (OSError, UnicodeDecodeError, csv.Error) as exc:
            raise DesignError(f"{where}: cannot read the covariate file {path}: {exc}") from None
        if not rows or name not in rows[0]:
            raise DesignError(f"{where}: {path} has no column {name!r} (a header row naming it, then one value per run)")
        cells = [row[name] for row in rows]
        places = [f"{path.name} line {i + 2}" for i in range(len(rows))]
    values = []
    for cell, place in zip(cells, places):
        try:
            number = float(cell) if not isinstance(cell, bool) else math.nan
        except (TypeError, ValueError):
            number = math.nan
        values.append(_finite(number, f"covariate value ({place}: {cell!r})", where))
    if not values:
        raise DesignError(f"{where}: a covariate needs one value per run, got none")
    return tuple(values)


def _table(data: dict[str, Any], key: str, source: str) -> dict[str, Any]:
    value = data.get(key)
    if not isinstance(value, dict):
        raise DesignError(f"{source}: missing [{key}] table")
    return value


def _no_unknown_keys(raw: dict[str, Any], allowed: set[str], where: str) -> None:
    unknown = sorted(set(raw) - allowed)
    if unknown:
        raise DesignError(f"{where}: unknown field {unknown[0]!r} (expected {', '.join(sorted(allowed))})")


def _levels(raw: dict[str, Any], where: str, key: str = "levels") -> list[Any]:
    levels = raw.get(key)
    if not isinstance(levels, list):
        raise DesignError(f"{where}: {key} must be a list, got {levels!r}")
    if len(levels) > MAX_LEVELS:
        raise DesignError(f"{where}: {len(levels)} {key}; at most {MAX_LEVELS}")
    return levels


def _string(raw: dict[str, Any], key: str, where: str, default: str | None = None) -> str:
    value = raw.get(key, default)
    if not isinstance(value, str) or (default is None and not value.strip()):
        raise DesignError(f"{where}: {key} must be a non-empty string, got {value!r}")
    return value


def _number(raw: dict[str, Any], key: str, where: str, default: float | None = None) -> float:
    value = raw.get(key, default)
    if isinstance(value, bool) or not isinstance(value, Real):
        raise DesignError(f"{where}: {key} must be a number, got {value!r}")
    return _finite(float(value), key, where)


def _finite(value: float, key: str, where: str) -> float:
    """A spec's number, refused when it is inf, nan or beyond MAX_MAGNITUDE."""
    if not (math.isfinite(value) and abs(value) <= MAX_MAGNITUDE):
        raise DesignError(f"{where}: {key} must be a finite number of magnitude at most {MAX_MAGNITUDE:g}, got {value!r}")
    return value


def _integer(raw: dict[str, Any], key: str, where: str, minimum: int, maximum: int, required: bool = True) -> int | None:
    value = raw.get(key)
    if value is None and not required:
        return None
    if isinstance(value, bool) or not isinstance(value, int) or not minimum <= value <= maximum:
        raise DesignError(f"{where}: {key} must be a whole number from {minimum} to {maximum}, got {value!r}")
    return value
