"""Recompute the toolkit's measured results and write docs/results.md, or check that it is current.

Every figure in docs/results.md comes from this script, with the command and seed that make it,
so the page cannot drift from the code. Each section sits between `<!-- section: NAME -->` and
`<!-- end: NAME -->`; `--only` recomputes (or checks) just the named sections.

    python scripts/results.py                          # rewrite docs/results.md (hours: `trained` trains networks)
    python scripts/results.py --only table1            # Table I under both protocols (about 7 minutes on 2 cores)
    python scripts/results.py --check                  # exit 1 with a diff line if it is out of date
    python scripts/results.py --check --only designs,qualitative
"""

from __future__ import annotations

import argparse
import csv
import difflib
import hashlib
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results.md"
OUT_OF_DATE = 1

#: Seeds of the design table: the D-optimum is the same for each, the A- and G-efficiencies are not.
DESIGN_SEEDS = (0, 1, 2, 3)
#: The study seeds of the two simulated studies (public), and the A/B study's allocation seed.
QUALITATIVE_SEED = 2
AB_SEED = 3
AB_ALLOCATION_SEED = 0
#: The power section: its power seed, data sets per plan, and the plan sizes compared.
POWER_SEED = 2026
POWER_SIMULATIONS = 200
POWER_SIZES = (18, 72, 144, 288, 432)
#: The closed-loop tuning seeds, and the evasion networks' training seeds (the shipped networks are the first's).
TUNING_SEEDS = (0, 1, 2)
EVASION_SEEDS = (0, 1, 2)

HEADER = """# Measured results

Each figure with its command, written by `python scripts/results.py` (`--check` verifies it); judgments are simulated.
"""


def checkout_env() -> dict[str, str]:
    """The environment with this checkout's packages first on the path (ahead of any installed copy)."""
    return {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}


def trials(args: list[str], cwd: Path) -> None:
    """Run one `trials` command in `cwd` with this checkout's packages."""
    subprocess.run([sys.executable, "-m", "trials.cli", *args], cwd=cwd, env=checkout_env(), check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def table(header: list[str], rows: list[list[str]]) -> str:
    """A Markdown table."""
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join(" --- " for _ in header) + "|"]
    return "\n".join(lines + ["| " + " | ".join(row) + " |" for row in rows])


def designs() -> str:
    """The preset plans' efficiencies for a few design seeds (the D-optimum is the same for every seed)."""
    from designs.plan import build_plan
    from designs.presets import ab, qualitative
    from trials.controllers.registry import AB_PRESET

    rows = []
    for name, preset, command in (("qualitative, 27 runs", qualitative(), "trials design --runs 27"),
                                  ("A/B, 18 runs", ab(AB_PRESET), "trials design --ab")):
        per_seed = []
        for seed in DESIGN_SEEDS:
            plan = build_plan(replace(preset, seed=seed), allocation_seed=0)
            d = plan.diagnostics
            per_seed.append([str(d.p), f"{d.d_efficiency:.4f}", f"{plan.d_efficiency_vs_bound:.2f} %", f"{d.a_efficiency:.2f}",
                             f"{d.g_efficiency:.2f}", f"{plan.design.hits} of {plan.design.starts}"])
        rows.append([name, f"`{command} --seed S`", *(values[0] if len(set(values)) == 1 else " / ".join(values)
                                                      for values in zip(*per_seed))])
    seeds = ", ".join(map(str, DESIGN_SEEDS))
    return "\n".join([
        "## Designs",
        "",
        f"Diagnostics ([designs.md](designs.md)) for seeds S = {seeds}, one figure where all agree; the A-efficiency",
        "depends on which D-optimal design a seed ends on. `trials design` prints the rest.",
        "",
        table(["plan", "command", "p", "D-eff", "of the bound", "A-eff", "G-eff", "starts at the optimum"], rows),
    ])


def outcome_counts(rows: list[dict[str, str]]) -> str:
    """'17 goal, 1 timeout' for outcome rows."""
    statuses = [row["status"] for row in rows]
    return ", ".join(f"{statuses.count(s)} {s}" for s in ("goal", "collision", "timeout") if s in statuses)


def run_figures(rows: list[dict[str, str]], scores: dict[str, dict]) -> list[str]:
    """Outcomes, rubric scores, time to goal and closest gap of a group of runs."""
    finals = [scores[row["run_code"]]["final"] for row in rows]
    times = [float(row["time_to_goal_s"]) for row in rows if row["time_to_goal_s"]]
    gaps = [float(row["min_distance_m"]) for row in rows if row["min_distance_m"]]
    return [str(len(rows)), outcome_counts(rows), " / ".join(str(finals.count(s)) for s in (3, 2, 1)),
            f"{statistics.mean(times):.1f}", f"{statistics.median(gaps):.2f}", f"{min(gaps):.2f}"]


#: Stands in a command for the commitment the study's design printed (read from its design.json).
COMMITMENT = "HEX"


def simulated_study(design: list[str], run: list[str], report: list[str]) -> tuple[list[dict[str, str]], dict]:
    """Design, run and report a study in a fresh folder; its outcome rows and report.json."""
    with tempfile.TemporaryDirectory() as folder:
        where = Path(folder)
        trials(design, where)
        trials(run, where)
        digest = hashlib.sha256((where / "preregistration.md").read_bytes()).hexdigest()  # what `trials design` printed
        trials([digest if word == COMMITMENT else word for word in report], where)
        with (where / "outcomes.csv").open(newline="", encoding="utf-8") as handle:
            rows = list(csv.DictReader(handle))
        return rows, json.loads((where / "report" / "report.json").read_text(encoding="utf-8"))


RUN_HEADER = ["runs", "outcomes", "scored 3 / 2 / 1", "mean time to goal (s)", "closest gap, median (m)", "closest gap, least (m)"]


def qualitative() -> str:
    """The 27-run qualitative study with NaviGAN-R, simulated end to end."""
    design = ["design", "--runs", "27", "--seed", str(QUALITATIVE_SEED)]
    rows, report = simulated_study(design, ["run"], ["report"])
    judged = report["judgments"]["count"]
    return "\n".join([
        "## The qualitative study (NaviGAN-R, 27 runs)",
        "",
        "```bash",
        f"trials {' '.join(design)} && trials run && trials report",
        "```",
        "",
        f"The paper's rubric; closest gap from the robot's footprint to a body disc; {judged} judgments.",
        "",
        table(RUN_HEADER, [run_figures(rows, report["scores"])]),
    ])


def ab_study() -> str:
    """The blinded 18-run A/B study, unblinded: outcomes per controller and Table II."""
    design = ["design", "--ab", "--seed", str(AB_SEED), "--allocation-seed", str(AB_ALLOCATION_SEED)]
    rows, report = simulated_study(design, ["run", "--blind"], ["report", "--unblind", "--commitment", COMMITMENT])
    scores = report["scores"]
    arms = sorted({s["arm"] for s in scores.values()})
    outcome_rows = [[arm, *run_figures([r for r in rows if scores[r["run_code"]]["arm"] == arm], scores)] for arm in arms]
    shares = [[f">= {row['min_pedestrians']}"] + [f"{row['arms'][arm]['share']:.0%} ({row['arms'][arm]['yes']}/{row['arms'][arm]['judged']})"
                                                   for arm in arms] + [f"{row['fisher_p']:.3f}"] for row in report["table_ii"]]
    return "\n".join([
        "## The A/B study (NaviGAN-R against the lattice planner, 18 runs)",
        "",
        "```bash",
        f"trials {' '.join(design)} && trials run --blind && trials report --unblind --commitment {COMMITMENT}",
        "```",
        "",
        f"{COMMITMENT}: the pre-registration digest `trials design` printed; a real study leaves `--allocation-seed` out.",
        "",
        table(["controller", *RUN_HEADER], outcome_rows),
        "",
        "Table II: share judged compliant among runs with at least 2, 4, 6 pedestrians; Fisher's exact test.",
        "",
        table(["pedestrians", *arms, "Fisher's p"], shares),
    ])

#: Table I's columns in the paper's order, as `trials playback --models` names them.
PAPER_MODELS = ("goal-social-lstm", "navil2", "navil2-dagger", "navigan", "navigan-dagger", "navigan-r",
                "navigan-r-dagger", "human")
#: The two protocols of `trials playback --protocol`, the paper's first.
PROTOCOLS = ("paper", "strict")
SCOPES = (("all", "pooled"), ("split_mean", "averaged"))
#: The networks trained without the resistance loss, and R's intention alone.
UNRESISTED = ("Goal", "L2", "L2-dagger", "NG", "NG-dagger", "R-dagger")
#: The strict protocol with each of the paper protocol's departures undone alone: distances at the
#: frames (the strict walks rescored), the far goal (walked again with --subgoal-speed 0).
AT_FRAMES, FAR_GOAL = "strict, at the frames", "strict, far goal"

#: run -> scope -> (metric, source) -> column label -> cell text, as table1.csv holds them.
Cells = dict[str, dict[str, dict[tuple[str, str], dict[str, str]]]]


def playback_cells(folder: Path, name: str, options: list[str]) -> dict[str, dict[tuple[str, str], dict[str, str]]]:
    """The rows of `trials playback OPTIONS` over the paper's columns, by scope (its walks kept in folder/name)."""
    from navigan.playback.table import COLUMNS, CSV_NAMES

    out = folder / name
    trials(["playback", *options, "--models", ",".join(PAPER_MODELS), "--out", str(out), "--quiet"], folder)
    with (out / "table1.csv").open(newline="", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    cells: dict[str, dict[tuple[str, str], dict[str, str]]] = {}
    for row in rows:
        cells.setdefault(row["scope"], {})[row["metric"], row["source"]] = {COLUMNS[m]: row[CSV_NAMES[m]] for m in PAPER_MODELS}
    return cells


def comfort_at_frames(walks: Path, protocol: str, model: str = "navigan-r") -> dict[str, dict[tuple[str, str], dict[str, str]]]:
    """A column's C from its stored walks (paths to 0.1 mm) rescored with distances at the recorded frames,
    pooled and averaged over splits."""
    import numpy as np

    from navigan.data import SHIPPED_DATA, load_split
    from navigan.playback.episodes import load_episodes
    from navigan.playback.metrics import DISCOMFORT_DISTANCE, step_distances
    from navigan.playback.protocols import FRAMES
    from navigan.playback.table import COLUMNS

    rates = []
    for split in SPLITS:
        episodes = load_episodes(load_split(SHIPPED_DATA, split).test, protocol)
        record = json.loads((walks / "episodes" / split / f"{model}.json").read_text(encoding="utf-8"))
        assert record["identity"]["episodes"] == episodes.ids
        rates.append([step_distances(np.asarray(r["path"]), episodes.others(e)[: len(r["path"])], FRAMES)
                      .min(initial=np.inf) >= DISCOMFORT_DISTANCE for e, r in enumerate(record["results"])])
    pooled, mean = float(np.mean(np.concatenate(rates))), float(np.mean([np.mean(r) for r in rates]))
    return {"all": {("C", "ours"): {COLUMNS[model]: f"{pooled:.3f}"}},
            "split_mean": {("C", "ours"): {COLUMNS[model]: f"{mean:.3f}"}}}


def table1() -> str:
    """Table I over the five ETH/UCY splits under both protocols, pooled and averaged over splits, with
    95 % intervals, beside the paper's; and the strict protocol with one departure undone at a time."""
    with tempfile.TemporaryDirectory() as folder:
        where = Path(folder)
        data: Cells = {p: playback_cells(where, p, ["--protocol", p]) for p in PROTOCOLS}
        data[AT_FRAMES] = comfort_at_frames(where / "strict", "strict")
        data[FAR_GOAL] = playback_cells(where, "far", ["--protocol", "strict", "--subgoal-speed", "0"])
    return table1_text(data)


def inside(cells: dict[tuple[str, str], dict[str, str]], metric: str, column: str) -> bool:
    """Whether the paper's value of a cell lies inside our 95 % interval."""
    paper = float(cells[metric, "paper"][column])
    return float(cells[metric, "ours_low"][column]) <= paper <= float(cells[metric, "ours_high"][column])


def count_inside(data: Cells, protocol: str, scope: str) -> int:
    """How many of the paper's 24 cells lie inside our interval under a protocol and aggregation."""
    cells = data[protocol][scope]
    return sum(inside(cells, m, c) for m in "SCA" for c in cells[m, "paper"])


def cause(data: Cells, protocol: str, scope: str, metric: str, column: str) -> str:
    """Why the paper's value of a cell lies outside our interval under a protocol and aggregation, in a few
    words, with what was measured about it."""
    def of(run: str, where: str, key: str, col: str) -> str:
        return data[run][where][key, "ours"][col]

    def both(run: str, key: str, col: str) -> str:
        return f"{of(run, 'all', key, col)} / {of(run, 'split_mean', key, col)}"

    other = "split_mean" if scope == "all" else "all"
    if metric == "S":
        return (f"time scale: R arrives after {both(protocol, 'time_to_goal_s', 'R')} s; the paper's S needs 8.2-9.6 s "
                "(it omits the discount's unit and v_pref)")
    if metric == "C" and column in UNRESISTED:
        rates = [float(of(protocol, "all", "collision_rate", c)) for c in UNRESISTED]
        return (f"our weights: those without the resistance loss, and R-dagger, collide (< 0.1 m) in "
                f"{min(rates):.2f}-{max(rates):.2f} of pooled episodes")
    if protocol == "strict" and metric == "C" and column == "R":
        return f"distances within each step: at the frames, R's own walks give C {both(AT_FRAMES, 'C', 'R')}"
    if protocol == "strict" and metric == "A":
        return (f"the sub-goal: handed the far goal, R arrives in {both(FAR_GOAL, 'A', 'R')}, "
                f"L2 in {both(FAR_GOAL, 'A', 'L2')}")
    if protocol == "strict":
        return (f"target selection: the recordings' own C is {both(protocol, 'C', 'human')}, "
                f"{both('paper', 'C', 'human')} with `paper`'s targets")
    if metric == "C" and inside(data[protocol][other], metric, column):
        return (f"aggregation (inside under the other): univ holds {of(protocol, 'univ', 'episodes', 'R')} of "
                f"{of(protocol, 'all', 'episodes', 'R')} episodes, eth {of(protocol, 'eth', 'episodes', 'R')}, "
                f"hotel {of(protocol, 'hotel', 'episodes', 'R')}")
    return (f"our weights: with the paper's settings, R arrives in {both(protocol, 'A', 'R')} (paper 0.85), "
            f"L2 in {both(protocol, 'A', 'L2')} (0.88)")


def cells_named(columns: list[str], labels: list[str]) -> str:
    """The columns of a row that a cause explains: `all`, `all but` the few it does not, or the few it does."""
    if columns == labels:
        return "all"
    rest = [c for c in labels if c not in columns]
    return f"all but {', '.join(rest)}" if len(rest) < len(columns) else ", ".join(columns)


def table1_text(data: Cells) -> str:
    """The Table I section from the cells of both protocols and the two strict runs with one departure undone:
    the pooled table with the paper's row, the cells inside our intervals under both aggregations, and the causes."""
    labels = list(data[PROTOCOLS[0]]["all"]["C", "paper"])
    counts = {p: data[p]["all"]["episodes", "ours"]["human"] for p in PROTOCOLS}
    lines = [
        "## Table I: long-term playback on ETH/UCY",
        "",
        "```bash",
        *(f"trials playback --protocol {p}" for p in PROTOCOLS),
        "trials playback --protocol strict --subgoal-speed 0",
        "```",
        "",
        f"Shipped weights, noise seed 0, [protocols](playback.md#protocols) `paper` ({counts['paper']} episodes) and",
        f"`strict` ({counts['strict']}), pooled, with 95 % intervals; the commands also print the mean over splits.",
        "",
    ]
    outside: dict[tuple[str, str], list[tuple[str, str, str]]] = {}
    body = []
    for metric in "SCA":
        for protocol in PROTOCOLS:
            cells = data[protocol]["all"]
            body.append([f"{metric}, ours (`{protocol}`)", *(cells[metric, "ours"][c] for c in labels)])
            body.append(["95 %", *(f"{cells[metric, 'ours_low'][c]}-{cells[metric, 'ours_high'][c]}" for c in labels)])
        body.append([f"{metric}, the paper's", *(data[PROTOCOLS[0]]["all"][metric, "paper"][c] for c in labels)])
    for scope, title in SCOPES:
        for metric in "SCA":
            for protocol in PROTOCOLS:
                for c in labels:
                    if not inside(data[protocol][scope], metric, c):
                        outside.setdefault((protocol, cause(data, protocol, scope, metric, c)), []).append((title, metric, c))
    lines += [table(["", *labels], body), "",
              "The paper's value lies inside our 95 % interval in "
              + " and ".join(f"{count_inside(data, p, 'all')} pooled and {count_inside(data, p, 'split_mean')} averaged "
                             f"of its 24 cells under `{p}`" for p in PROTOCOLS)
              + ". Elsewhere, by cause (figures pooled / averaged):", ""]
    for protocol in PROTOCOLS:
        for (run, reason), where in outside.items():
            if run == protocol:
                named = "; ".join(f"{title} {metric} {cells_named([c for t, m, c in where if (t, m) == (title, metric)], labels)}"
                                  for title, metric in dict.fromkeys((t, m) for t, m, _ in where))
                lines.append(f"- `{protocol}`, {reason}: {named}.")
    return "\n".join(lines)


#: The five leave-one-scene-out splits.
SPLITS = ("eth", "hotel", "univ", "zara1", "zara2")
#: The model whose ADE/FDE the page shows (`trials evaluate` gives the family's others alike).
ADE_MODEL = "navigan-r"
#: Social GAN's SGAN-1V-1 ADE/FDE (m) on the same splits (Gupta et al. 2018, Table 1): a goal-free predictor.
SGAN_1V_1 = {"eth": (1.13, 2.21), "hotel": (1.01, 2.18), "univ": (0.60, 1.28), "zara1": (0.42, 0.91), "zara2": (0.52, 1.11)}


def r_alone(checkpoints: Path | None, folder: Path, model: str = "navigan-r") -> dict[tuple[str, str], str]:
    """A NaviGAN-R column's C and A per scope (`all`, `split_mean`, each split) in `trials playback`,
    with the weights in `checkpoints` (None: the shipped ones); by default R alone."""
    from navigan.playback.table import CSV_NAMES

    out = folder / f"playback-{model}"
    trials(["playback", "--models", model, "--out", str(out), "--quiet",
            *(["--checkpoints", str(checkpoints)] if checkpoints else [])], folder)
    with (out / "table1.csv").open(newline="", encoding="utf-8") as handle:
        return {(r["scope"], r["metric"]): r[CSV_NAMES[model]] for r in csv.DictReader(handle)
                if r["source"] == "ours" and r["metric"] in ("C", "A")}


def shipped_then(options: list[str], folder: Path) -> Path:
    """A folder of the shipped per-split NaviGAN-R, each taken further by `trials train --recipe
    playback` with `options` (the closed-loop tuning, or the evasion networks)."""
    weights = folder / "weights"
    weights.mkdir()
    for split in SPLITS:
        out = weights / f"navigan-r-{split}.pt"
        shutil.copyfile(ROOT / "navigan" / "weights" / out.name, out)
        trials(["train", "--recipe", "playback", "--split", split, *(["--epochs", "60"] if split == "univ" else []),
                *options, "--threads", "1", "--out", str(out), "--quiet"], folder)
    return weights

def trained() -> str:
    """NaviGAN-R taken further by `trials train`: closed-loop tuning and the evasion networks, over three seeds
    each, beside R+shield (R alone is in Table I)."""
    figures = {}
    with tempfile.TemporaryDirectory() as folder:
        shipped = Path(folder) / "shipped"
        shipped.mkdir()
        for option, seeds, model, label in (("closed-loop", TUNING_SEEDS, "navigan-r", "tuned"),
                                            ("evasion", EVASION_SEEDS, "navigan-r-evasion", "R+evasion")):
            for seed in seeds:
                run = Path(folder) / f"{option}-{seed}"
                run.mkdir()
                extra = ["--retrain-evasion"] if option == "evasion" else []
                weights = shipped_then([f"--{option}", f"--{option}-seed", str(seed), *extra], run)
                figures[f"{label}, seed {seed}" + (" (shipped)" if option == "evasion" and seed == seeds[0] else "")] = \
                    r_alone(weights, run, model)
        figures["shipped, R+shield"] = r_alone(None, shipped, "navigan-r-shield")
    return trained_text(figures)


def by_scope(figures: dict[str, dict[tuple[str, str], str]]) -> str:
    """Pooled C / A, one row per set of weights (the command also prints the mean over splits and each split)."""
    return table(["weights", "C / A, pooled"], [[name, f"{cells['all', 'C']} / {cells['all', 'A']}"] for name, cells in figures.items()])


def trained_text(figures: dict[str, dict[tuple[str, str], str]]) -> str:
    return f"""## NaviGAN-R trained further

```bash
cp navigan/weights/navigan-r-SPLIT.pt DIR/       # each split; univ's command adds --epochs 60
trials train --recipe playback --split SPLIT --closed-loop --closed-loop-seed SEED --threads 1 --out DIR/navigan-r-SPLIT.pt
trials playback --checkpoints DIR --models navigan-r
```

`strict`, noise seed 0, after [closed-loop tuning](navigan_training.md#closed-loop-tuning---closed-loop) or with
[evasion networks](navigan_training.md#evasion-networks---evasion) (`--evasion --evasion-seed SEED --retrain-evasion`,
model `navigan-r-evasion`); R alone is Table I's. Tuning costs arrival, so no shipped weights use it.

{by_scope(figures)}"""


def evaluation(args: list[str], folder: Path) -> dict:
    """The record `trials evaluate ARGS` writes."""
    out = folder / "eval.json"
    trials([*args, "--json", str(out)], folder)
    return json.loads(out.read_text(encoding="utf-8"))


def ade_fde() -> str:
    """ADE/FDE of the shipped NaviGAN-R weights (its way-points) and the constant-velocity baseline on each test scene."""
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for split in SPLITS:
            cells = [split, "{:.2f} / {:.2f}".format(*SGAN_1V_1[split])]
            baseline = evaluation(["evaluate", "--baseline", "constant-velocity", "--split", split], Path(folder))
            model = evaluation(["evaluate", "--checkpoint", f"{ADE_MODEL}-{split}"], Path(folder))
            rows.append(cells + [f"{m['ade']:.2f} / {m['fde']:.2f}" for m in (baseline["full"], model["full"])])
    return ade_fde_text(rows)


def ade_fde_text(rows: list[list[str]]) -> str:
    header = ["split", "SGAN-1V-1 (published)", "constant velocity", "NaviGAN-R"]
    return f"""## ADE / FDE on the ETH/UCY test scenes

```bash
trials evaluate --checkpoint navigan-r-SPLIT      # one noise sample, seed 0; likewise the other models
trials evaluate --baseline constant-velocity --split SPLIT
```

ADE / FDE (m), 8 observed and 12 planned steps. NaviGAN-R is handed its goal 4.8 s ahead, which Social GAN
must guess: not like for like.

{table(header, rows)}"""


def reactive() -> str:
    """The non-learned yardstick beside Table I: scripts/reactive_reference.py over the same episodes."""
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "reactive_reference.py")], env=checkout_env(), check=True,
                          capture_output=True, text=True)
    return f"""## A reactive walker in Table I's episodes

The [yardstick](playback.md#a-yardstick) under `strict`: `python scripts/reactive_reference.py` prints each split, then

```text
{done.stdout.strip().splitlines()[-1]}
```"""


#: The judged-compliant shares (lattice, NaviGAN-R) whose difference the power section asks about: the paper's
#: Table II row at 6 or more pedestrians, and the smaller gap of 67 % against 75 %.
POWER_SHARES = ((0.58, 0.75), (0.67, 0.75))


def _power_of(study: Path, shares: tuple[float, float]) -> tuple[list[str], dict]:
    out = study / f"power-{shares[0]:g}-{shares[1]:g}"
    args = ["power", "--shares", f"{shares[0]:g},{shares[1]:g}", "--terms", "Controller", "--runs", ",".join(map(str, POWER_SIZES)),
            "--simulations", str(POWER_SIMULATIONS), "--seed", str(POWER_SEED)]
    trials([*args, "--out", str(out)], study)
    return args, json.loads((out / "power.json").read_text(encoding="utf-8"))


def _runs_for_80(record: dict) -> str:
    needed = record["smallest_runs"]["model_based"]
    by_runs = [(plan["runs"], plan["judgments"]["Controller"]["power"]) for plan in record["plans"]]
    crossing = next((a + (b - a) * (0.8 - pa) / (pb - pa) for (a, pa), (b, pb) in zip(by_runs, by_runs[1:]) if pa < 0.8 <= pb), None)
    where = f" (interpolated: about {crossing:.0f})" if crossing else ""
    return f"{needed if needed else 'none of those tried'}{where}"


def power() -> str:
    """The power of the paper's 18-run A/B plan to detect the paper's own difference, and the runs it would need."""
    with tempfile.TemporaryDirectory() as folder:
        study = Path(folder)
        trials(["design", "--ab", "--seed", str(AB_SEED), "--allocation-seed", str(AB_ALLOCATION_SEED)], study)
        results = [_power_of(study, shares) for shares in POWER_SHARES]

    def cell(figure: dict | None) -> str:
        if not figure:
            return "n/a"
        untested = f"; no fit on {figure['untested']} of {figure['total']}" if figure.get("untested") else ""
        return f"{figure['power']:.3f} ({figure['low']:.3f}-{figure['high']:.3f}){untested}"

    gaps = [f"{100 * low:.0f} % vs {100 * high:.0f} %" for low, high in POWER_SHARES]
    rows = [[str(plan["runs"]), *(cell(record["plans"][index]["judgments"]["Controller"]) for _, record in results)]
            for index, plan in enumerate(results[0][1]["plans"])]
    commands = [f"trials {' '.join(args)}" for args, _ in results]
    needed = "; ".join(f"{gap}: {_runs_for_80(record)}" for gap, (_, record) in zip(gaps, results))
    return "\n".join([
        "## Power: how many runs the A/B study needs",
        "",
        "```bash",
        f"trials design --ab --seed {AB_SEED} --allocation-seed {AB_ALLOCATION_SEED}",
        *commands,
        "```",
        "",
        "[Power](power.md) of the GEE's Controller test, the lattice planner judged compliant 58 % of the time against",
        f"NaviGAN-R's 75 % (the paper's Table II) or 67 % against 75 %; D-optimal plans, {POWER_SIMULATIONS} data sets each, with",
        "each power's Wilson 95 % Monte Carlo interval; a data set whose fit does not exist (separated judgments) counts as not",
        "rejecting, and how many there were is stated.",
        "",
        table(["runs", *gaps], rows),
        "",
        f"Smallest plan with power 0.8: {needed}. 18 runs leave the GEE 7 degrees of freedom.",
    ])


SECTIONS: dict[str, Callable[[], str]] = {
    "designs": designs, "qualitative": qualitative, "ab": ab_study, "table1": table1, "trained": trained,
    "reactive": reactive, "adefde": ade_fde, "power": power,
}


def wrap(name: str, body: str) -> str:
    return f"<!-- section: {name} -->\n{body}\n<!-- end: {name} -->"


def sections_of(text: str) -> dict[str, str]:
    """The sections of a results page, by name."""
    return {m.group(1): m.group(0) for m in re.finditer(r"<!-- section: (\w+) -->\n.*?\n<!-- end: \1 -->", text, re.DOTALL)}


def page(bodies: dict[str, str]) -> str:
    return HEADER + "\n" + "\n\n".join(bodies[name] for name in SECTIONS) + "\n"


def first_difference(old: str, new: str) -> str:
    """The first changed line between two texts, as a diff line."""
    changed = (line for line in difflib.unified_diff(old.splitlines(), new.splitlines(), lineterm="", n=0)
               if line[:1] in "+-" and not line.startswith(("+++", "---")))
    return next(changed, "(the texts differ)")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Recompute docs/results.md, or check that it is current.")
    parser.add_argument("--check", action="store_true", help="compare instead of writing; exit 1 when out of date")
    parser.add_argument("--only", default=",".join(SECTIONS), metavar="LIST",
                        help=f"comma-separated sections to recompute (default: all of {', '.join(SECTIONS)})")
    args = parser.parse_args(argv)
    names = [name for name in args.only.split(",") if name]
    unknown = [name for name in names if name not in SECTIONS]
    if unknown:
        parser.error(f"unknown section {unknown[0]!r} (sections: {', '.join(SECTIONS)})")
    sys.path.insert(0, str(ROOT))
    current = RESULTS.read_text(encoding="utf-8") if RESULTS.exists() else ""
    existing = sections_of(current)
    fresh = {name: wrap(name, SECTIONS[name]()) for name in names}
    if args.check:
        for name in names:
            if existing.get(name) != fresh[name]:
                print(f"{RESULTS.relative_to(ROOT)} is out of date in section {name}: "
                      f"{first_difference(existing.get(name, ''), fresh[name])} (run python scripts/results.py)")
                return OUT_OF_DATE
        print(f"{RESULTS.relative_to(ROOT)} is up to date ({', '.join(names)})")
        return 0
    missing = [name for name in SECTIONS if name not in fresh and name not in existing]
    if missing:
        parser.error(f"{RESULTS} lacks section {missing[0]!r}: recompute it too (--only ...,{missing[0]})")
    RESULTS.write_text(page({**existing, **fresh}), encoding="utf-8")
    print(f"wrote {RESULTS.relative_to(ROOT)} ({', '.join(names)})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
