"""The study spec (`study.toml`): factors, model, runs, seed; read, validated and written.

    [study]
    name = "qualitative"
    runs = 27
    model = "main"            # keywords main, interactions, quadratic, or terms A + B + A*B + A^2
    seed = 2019               # optional: drawn and recorded when absent
    starts = 100              # random starts of the exchange
    snr = 1.0                 # signal-to-noise ratio for the power table
    alpha = 0.05

    [anticipated]             # optional: a term's anticipated coefficient for the power (default 1)
    Controller = 0.5          # its columns get +c, -c, +c, ... as in JMP

    [[factors]]
    name = "Pedestrians"
    type = "discrete"         # continuous (low, high) | discrete (levels) | categorical (levels) | fixed (value)
    levels = [2, 4, 6]

A blinded categorical factor has `blind = true`. In the public spec that `trials design`
writes, its levels are replaced by `arms = [...]` (opaque labels); the levels themselves
live only in the sealed allocation.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, replace
from numbers import Real
from pathlib import Path
from typing import Any

import tomli_w

from designs.errors import DesignError
from designs.factors import (
    CategoricalFactor,
    ContinuousFactor,
    DesignFactor,
    DiscreteFactor,
    Factor,
    FixedFactor,
    plain,
    validate_factor,
)

FACTOR_TYPES = ("continuous", "discrete", "categorical", "fixed")
DEFAULT_STARTS = 100
#: The columns plan.csv holds before the factors, and the column in which a plan may name a robot log
#: (`trials.log_trial`); no factor may take these names.
PLAN_COLUMNS = ("order", "run_code")
LOG_COLUMN = "Log"
RESERVED_NAMES = (*PLAN_COLUMNS, LOG_COLUMN)
#: Sizes a spec may ask for: the exchange's time grows with runs x starts x candidate points, and
#: beyond these a study takes minutes to design and is almost surely a typing slip.
MAX_RUNS = 1000
MAX_STARTS = 1000
MAX_LEVELS = 20
MAX_CANDIDATES = 10_000
#: runs x starts: each start exchanges every run, so this bounds the search's time (about 10 s at the limit).
MAX_SEARCH = 100_000
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
    return spec_from_dict(data, source=path.name)


def spec_from_dict(data: dict[str, Any], source: str) -> StudySpec:
    """Validate the parsed TOML tables of a spec."""
    study = _table(data, "study", source)
    # [run] holds how the runs are made, not the design: trials.run_settings reads it.
    unknown = set(data) - {"study", "factors", "anticipated", "run"}
    if unknown:
        raise DesignError(f"{source}: unknown table {sorted(unknown)[0]!r} (expected [study], [[factors]] and optionally [anticipated] and [run])")
    raw_factors = data.get("factors")
    if not isinstance(raw_factors, list) or not raw_factors:
        raise DesignError(f"{source}: no [[factors]] given; a study needs at least one factor")
    factors = tuple(factor_from_table(raw, f"{source}: factors[{i}]") for i, raw in enumerate(raw_factors))
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
    allowed = {"name", "runs", "model", "seed", "starts", "snr", "alpha"}
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
    return StudySpec(
        name=name,
        factors=factors,
        model=_string(study, "model", where, default="main"),
        runs=_integer(study, "runs", where, minimum=1, maximum=MAX_RUNS),
        seed=_integer(study, "seed", where, minimum=0, maximum=2**63 - 1, required=False),
        starts=_integer(study, "starts", where, minimum=1, maximum=MAX_STARTS, required=False) or DEFAULT_STARTS,
        snr=snr,
        alpha=alpha,
        arms_sealed=any("arms" in raw for raw in raw_factors if isinstance(raw, dict)),
        anticipated=_anticipated(data, source),
    )


def check_search_size(spec: StudySpec) -> None:
    """DesignError when runs x starts (from the spec or the command line) exceeds MAX_SEARCH."""
    if spec.runs * spec.starts > MAX_SEARCH:
        raise DesignError(f"runs x starts = {spec.runs} x {spec.starts} exceeds {MAX_SEARCH:,}; ask for fewer runs or starts")


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
    tables: dict[str, Any] = {"study": study}
    if spec.anticipated:
        tables["anticipated"] = dict(spec.anticipated)
    return tomli_w.dumps({**tables, "factors": [factor_table(f) for f in spec.factors]})


def factor_table(factor: Factor) -> dict[str, Any]:
    """One [[factors]] table; a blind factor lists its arm labels as `arms`."""
    table: dict[str, Any] = {"name": factor.name, "type": factor.kind}
    if isinstance(factor, ContinuousFactor):
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


def factor_from_table(raw: Any, where: str) -> Factor:
    """One [[factors]] table as its factor, validated; DesignError names `where`."""
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
