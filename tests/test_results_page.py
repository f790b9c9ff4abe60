"""docs/results.md stays true: scripts/results.py recomputes its cheap, deterministic sections and finds them
unchanged; its Table I section counts the paper's cells inside our intervals and names one cause a line."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "results.py"
LABELS = ("Goal", "L2", "L2-dagger", "NG", "NG-dagger", "R", "R-dagger", "human")


@pytest.fixture(scope="module")
def results():
    spec = importlib.util.spec_from_file_location("results_page", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def scope_cells(outside: set[tuple[str, str]]) -> dict[tuple[str, str], dict[str, str]]:
    """One scope's rows: every interval 0.400-0.600 around the paper's 0.500, but 0.000-0.100 for the
    (metric, column) cells in `outside`."""
    cells: dict[tuple[str, str], dict[str, str]] = {}
    for metric in "SCA":
        cells[metric, "ours"] = dict.fromkeys(LABELS, "0.500")
        cells[metric, "paper"] = dict.fromkeys(LABELS, "0.500")
        cells[metric, "ours_low"] = {c: "0.000" if (metric, c) in outside else "0.400" for c in LABELS}
        cells[metric, "ours_high"] = {c: "0.100" if (metric, c) in outside else "0.600" for c in LABELS}
    for key, value in (("collision_rate", "0.250"), ("time_to_goal_s", "10.0"), ("episodes", "7")):
        cells[key, "ours"] = dict.fromkeys(LABELS, value)
    return cells


def run(pooled: set[tuple[str, str]], mean: set[tuple[str, str]]) -> dict:
    return {"all": scope_cells(pooled), "split_mean": scope_cells(mean),
            **{split: scope_cells(set()) for split in ("eth", "hotel", "univ", "zara1", "zara2")}}


def test_table1_counts_the_cells_inside_and_names_each_cause_once(results):
    data = {
        "paper": run({("C", "Goal"), ("C", "L2"), ("S", "R")}, {("S", "R")}),
        "strict": run({("A", "R"), ("C", "Goal")}, {("A", "R")}),
        results.AT_FRAMES: {"all": {("C", "ours"): {"R": "0.958"}}, "split_mean": {("C", "ours"): {"R": "0.969"}}},
        results.FAR_GOAL: run(set(), set()),
    }
    text = results.table1_text(data)
    assert ("in 21 pooled and 23 averaged of its 24 cells under `paper` and 22 pooled and 23 averaged of its 24 "
            "cells under `strict`") in text
    causes = [line for line in text.splitlines() if line.startswith("- `")]
    assert len(causes) == 4
    assert causes[0].startswith("- `paper`, time scale") and causes[0].endswith(": pooled S R; averaged S R.")
    assert causes[1].startswith("- `paper`, our weights: those without the resistance loss")
    assert causes[1].endswith("0.25-0.25 of pooled episodes: pooled C Goal, L2.")
    assert causes[2].startswith("- `strict`, our weights") and causes[2].endswith(": pooled C Goal.")
    assert causes[3] == ("- `strict`, the sub-goal: handed the far goal, R arrives in 0.500 / 0.500, L2 in "
                         "0.500 / 0.500: pooled A R; averaged A R.")
    assert "| C, ours (`strict`) | 0.500 |" in text and "| C, the paper's | 0.500 |" in text
    assert "| 95 % | 0.000-0.100 | 0.000-0.100 | 0.400-0.600 |" in text


def test_a_cause_names_all_columns_or_all_but_a_few(results):
    assert results.cells_named(list(LABELS), list(LABELS)) == "all"
    assert results.cells_named(["Goal", "R"], list(LABELS)) == "Goal, R"
    assert results.cells_named([c for c in LABELS if c not in ("R", "human")], list(LABELS)) == "all but R, human"


@pytest.mark.slow
def test_the_results_page_matches_the_designs_and_the_qualitative_study():
    # The A/B study (the lattice plans against the clock) and Table I (minutes) are left to a
    # full `python scripts/results.py --check`.
    done = subprocess.run([sys.executable, str(SCRIPT), "--check", "--only", "designs,qualitative"],
                          capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 0, done.stdout + done.stderr
