"""The participants' questionnaire items a study may add to study.toml beside the compliance question:
Likert items, each a name (its column in responses.csv), the question and the number of points.

    [[questionnaire]]
    name = "comfort"
    question = "How comfortable did you feel near the robot?"
    scale = 5                 # answers 1 .. scale
    low = "very uncomfortable" # optional words for 1 and for scale
    high = "very comfortable"
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

from designs.errors import DesignError

#: The fewest and most points an item's scale may have.
SCALE_RANGE = (2, 11)
MAX_ITEMS = 20
#: An item's name is a responses.csv column: lower-case ASCII letters, digits and _.
NAME = re.compile(r"[a-z][a-z0-9_]{0,39}")
FIELDS = {"name", "question", "scale", "low", "high"}


@dataclass(frozen=True)
class LikertItem:
    """One questionnaire item: answered with a whole number from 1 (`low`) to `scale` (`high`)."""

    name: str
    question: str
    scale: int
    low: str = ""
    high: str = ""


def questionnaire_from_tables(raw: Any, source: str) -> tuple[LikertItem, ...]:
    """The [[questionnaire]] tables of a spec as items, validated; DesignError names the table and field."""
    if raw is None:
        return ()
    if not isinstance(raw, list) or len(raw) > MAX_ITEMS:
        raise DesignError(f"{source}: [[questionnaire]] must be a list of at most {MAX_ITEMS} tables with name, question and scale")
    items = []
    for i, table in enumerate(raw):
        where = f"{source}: questionnaire[{i}]"
        if not isinstance(table, dict):
            raise DesignError(f"{where}: expected a table with name, question and scale")
        unknown = sorted(set(table) - FIELDS)
        if unknown:
            raise DesignError(f"{where}: unknown field {unknown[0]!r} (expected {', '.join(sorted(FIELDS))})")
        name, scale = table.get("name"), table.get("scale")
        if not isinstance(name, str) or not NAME.fullmatch(name):
            raise DesignError(f"{where}: name must be lower-case letters, digits and _ starting with a letter (a column name), got {name!r}")
        texts = {key: table.get(key, "" if key != "question" else None) for key in ("question", "low", "high")}
        for key, text in texts.items():
            if not isinstance(text, str) or not text.isprintable() or (key == "question" and not text.strip()):
                raise DesignError(f"{where} ({name}): {key} must be one line of text, got {text!r}")
        if isinstance(scale, bool) or not isinstance(scale, int) or not SCALE_RANGE[0] <= scale <= SCALE_RANGE[1]:
            raise DesignError(f"{where} ({name}): scale must be a whole number of points from {SCALE_RANGE[0]} to {SCALE_RANGE[1]}, got {scale!r}")
        if name in {item.name for item in items}:
            raise DesignError(f"{where}: two questionnaire items are named {name!r}")
        items.append(LikertItem(name, texts["question"], scale, texts["low"], texts["high"]))
    return tuple(items)


def questionnaire_tables(items: tuple[LikertItem, ...]) -> list[dict[str, Any]]:
    """The items as [[questionnaire]] tables (empty anchors left out)."""
    return [{key: value for key, value in vars(item).items() if value != ""} for item in items]
