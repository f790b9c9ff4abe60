"""Training recipes: TOML files that name a model and the settings that train it.

The shipped recipes are the `NAME.toml` files beside this module; a user's own file is read the
same way. A recipe sets only what differs from the defaults of `navigan.config.ModelConfig` and
`TrainConfig` (the paper's), which are written there and nowhere else:

    model = "navigan-r"     # a key of navigan.config.MODELS
    [network]               # ModelConfig fields: sizes, pair_pool
    [train]                 # TrainConfig fields but split
    [closed_loop]           # ClosedLoopConfig fields: the tuning `trials train --closed-loop` adds
    [evasion]               # EvasionConfig fields: the networks `trials train --evasion` adds

The split, the output file, the device and the data folder belong to the command, not the recipe.
"""

from __future__ import annotations

import json
import math
import tomllib
import types
from collections.abc import Callable
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, Union, get_args, get_origin, get_type_hints

from navigan.config import MODELS, ClosedLoopConfig, EvasionConfig, ModelConfig, TrainConfig
from navigan.errors import NaviganError
from robot_logs.physical import T_PRED

#: Where the shipped recipes live.
RECIPES_DIR = Path(__file__).resolve().parent

#: The tables of a recipe file and the config each one fills (the model's name is a top-level key).
TABLES: dict[str, type] = {"network": ModelConfig, "train": TrainConfig, "closed_loop": ClosedLoopConfig,
                           "evasion": EvasionConfig}

#: Config fields a recipe may not set: the model is named at the top, the split by the command.
NOT_IN_TABLES = frozenset({"model", "split"})


def _positive(value: float) -> bool:
    return math.isfinite(value) and value > 0


def _at_least_zero(value: float) -> bool:
    return math.isfinite(value) and value >= 0


_WHOLE_POSITIVE = (_positive, "a positive whole number")
_AT_LEAST_ZERO = (_at_least_zero, "a number >= 0")

#: Settings whose values have bounds, with what a value must be (other settings need only the field's type).
LIMITS: dict[str, tuple[Callable[[Any], bool], str]] = {
    **{name: _WHOLE_POSITIVE for name in ("hidden", "embed", "goal", "pool", "noise", "mlp", "epochs", "patience", "batch",
                                          "rounds", "width", "shortfall_batches")},
    **{name: _AT_LEAST_ZERO for name in ("w_l2", "w_fde", "w_adversarial", "w_resistance", "encounters", "force_size",
                                         "w_first", "w_rest", "w_hinge")},
    "seed": (_at_least_zero, "a whole number >= 0"),
    "lr": (_positive, "a positive number"),
    "clip": (_positive, "a positive number"),
    "d_safe": (_positive, "a positive distance in metres"),
    "margin": (_positive, "a positive distance in metres"),
    "encounter_crowd": (lambda v: 0 <= v <= 1, "a fraction in [0, 1]"),
    "resist_steps": (lambda v: 1 <= v <= T_PRED, f"a whole number of way-points from 1 to {T_PRED}"),
}

#: How a value of each field type is described when it has the wrong type.
KINDS: dict[type, str] = {int: "a whole number", float: "a number", bool: "true or false", str: "a string"}


def _kind(config: type, name: str) -> type:
    """The type a config field holds when set (int for `int | None`)."""
    hint = get_type_hints(config)[name]
    if get_origin(hint) in (Union, types.UnionType):
        hint = next(arg for arg in get_args(hint) if arg is not type(None))
    return hint


def _typed(kind: type, value: Any) -> Any:
    """`value` as a `kind` (a whole number stands for a float), or None if it is not one."""
    if isinstance(value, bool) != (kind is bool):
        return None
    if kind is float and isinstance(value, int):
        return float(value)
    return value if isinstance(value, kind) else None


def problem(config: type, name: str, value: Any) -> str | None:
    """What setting `name` of `config` must be, if `value` is not that; None if it fits."""
    kind = _kind(config, name)
    test, expected = LIMITS.get(name, (lambda _: True, KINDS[kind]))
    typed = _typed(kind, value)
    return expected if typed is None or not test(typed) else None


def _shown(value: Any) -> str:
    """A value as TOML would spell it (near enough for an error message)."""
    return json.dumps(value, default=str)


@dataclass(frozen=True)
class TrainingRecipe:
    """A recipe as read: where it came from and the settings it names.

    Attributes:
        name: a shipped recipe's name, or the file as the user gave it.
        file: the file read.
        text: the file's text, kept in checkpoints so a training can be redone from one alone.
        model: a key of navigan.config.MODELS.
        network: the ModelConfig fields it sets.
        train: the TrainConfig fields it sets.
        closed_loop: the ClosedLoopConfig fields it sets.
        evasion: the EvasionConfig fields it sets.
    """

    name: str
    file: Path
    text: str
    model: str
    network: dict[str, Any]
    train: dict[str, Any]
    closed_loop: dict[str, Any]
    evasion: dict[str, Any]

    def configs(self, split: str, **overrides: Any) -> tuple[ModelConfig, TrainConfig]:
        """The model and training configs on `split`; `overrides` replace training settings (None: the recipe's)."""
        settings = self.train | {name: value for name, value in overrides.items() if value is not None}
        return ModelConfig(self.model, **self.network), TrainConfig(split, **settings)

    def tuning(self, seed: int | None = None) -> ClosedLoopConfig:
        """The closed-loop tuning's settings; `seed` replaces the recipe's (None: the recipe's)."""
        return ClosedLoopConfig(**(self.closed_loop | ({} if seed is None else {"seed": seed})))

    def evasion_training(self, seed: int | None = None) -> EvasionConfig:
        """The evasion networks' training settings; `seed` replaces the recipe's (None: the recipe's)."""
        return EvasionConfig(**(self.evasion | ({} if seed is None else {"seed": seed})))

    def record(self) -> dict[str, str]:
        """What a checkpoint keeps of the recipe (its configs hold the settings as resolved)."""
        return {"name": self.name, "file": str(self.file), "text": self.text}


def shipped() -> list[str]:
    """The names of the shipped recipes."""
    return sorted(path.stem for path in RECIPES_DIR.glob("*.toml"))


def load(name_or_file: str) -> TrainingRecipe:
    """A shipped recipe by name, or a recipe file (a path, or any name ending in .toml).

    Raises:
        NaviganError: unknown name, missing or unreadable file, or a setting that is not one,
            has the wrong type or is out of range (one line naming the file and the key).
    """
    if name_or_file.endswith(".toml") or len(Path(name_or_file).parts) > 1:
        file = Path(name_or_file)
        if not file.is_file():
            raise NaviganError(f"no recipe file {file}")
    else:
        file = RECIPES_DIR / f"{name_or_file}.toml"
        if not file.is_file():
            raise NaviganError(
                f"unknown recipe {name_or_file!r}: shipped recipes are {', '.join(shipped())} (or give a .toml file)"
            )
    text = file.read_text(encoding="utf-8")
    try:
        values = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise NaviganError(f"{file}: not valid TOML: {exc}") from None
    model, tables = _settings(values, str(file))
    return TrainingRecipe(name_or_file, file, text, model, tables["network"], tables["train"], tables["closed_loop"],
                          tables["evasion"])


def _settings(values: dict[str, Any], where: str) -> tuple[str, dict[str, dict[str, Any]]]:
    """The model name and each table's checked settings of a parsed recipe file.

    Raises:
        NaviganError: see `load`.
    """
    allowed = ["model", *TABLES]
    for key in values:
        if key not in allowed:
            raise NaviganError(f"{where}: unknown key {key}: expected one of {', '.join(allowed)}")
    model = values.get("model")
    if model not in MODELS:
        got = "nothing" if model is None else _shown(model)
        raise NaviganError(f"{where}: model: expected one of {', '.join(MODELS)}, got {got}")
    tables = {}
    for table, config in TABLES.items():
        given = values.get(table, {})
        if not isinstance(given, dict):
            raise NaviganError(f"{where}: {table}: expected a table of {config.__name__} settings, got {_shown(given)}")
        names = [f.name for f in fields(config) if f.name not in NOT_IN_TABLES]
        settings = {}
        for name, value in given.items():
            if name not in names:
                raise NaviganError(f"{where}: unknown key {table}.{name}: expected one of {', '.join(names)}")
            expected = problem(config, name, value)
            if expected is not None:
                raise NaviganError(f"{where}: {table}.{name}: expected {expected}, got {_shown(value)}")
            settings[name] = _typed(_kind(config, name), value)
        tables[table] = settings
    return model, tables
