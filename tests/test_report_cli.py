"""`trials report` on synthesised study folders: blinded, unblinded, qualitative, unfinished."""

from __future__ import annotations

import base64
import csv
import io
import json
import re
import shutil
from html.parser import HTMLParser
from pathlib import Path

import matplotlib.image as mpimg
import pytest
from markdown_it import MarkdownIt
from scipy.stats import fisher_exact

from robot_logs.figure_files import DEFAULT_DPI
from tests.support.registration import recorded_digest
from tests.support.scripts import load_script
from tests.support.synthetic_study import Behaviour, design, run_all, write_run
from tests.support.system_packages import need
from trials.cli import main

pytestmark = pytest.mark.slow  # whole study folders synthesised and reported

#: A scorer's note that would be markup: report.md must show it as text.
NOTE = "<img src=x onerror=alert(1)> [a](b) | _c_"

screenshot_report = load_script("screenshot_report")

CONTROLLER_NAMES = ("navigan", "lattice", "sbpl")
DATA_URI = re.compile(r"data:image/png;base64,[A-Za-z0-9+/=]+")


@pytest.fixture(scope="module")
def ab_template(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The blinded 18-run A/B plan, every run finished (blind), simulated judgments (seed 5)."""
    root = tmp_path_factory.mktemp("ab") / "study"
    run_all(design(root))
    assert main(["respond", "--simulate", "--seed", "5", "--study", str(root)]) == 0
    return root


@pytest.fixture
def ab_study(ab_template: Path, tmp_path: Path) -> Path:
    return Path(shutil.copytree(ab_template, tmp_path / "study"))


def unblind(study: Path) -> list[str]:
    """`--unblind --commitment HEX` with the commitment `trials design` printed (design.json holds it too)."""
    return ["--unblind", "--commitment", recorded_digest(study)]


def _report_text(root: Path) -> str:
    """Every file under report/ as text, embedded images left out."""
    return "\n".join(DATA_URI.sub("", p.read_bytes().decode("latin-1")) for p in sorted((root / "report").rglob("*")) if p.is_file())


def test_blinded_report_names_no_controller(ab_study: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["report", "--study", str(ab_study)]) == 0
    console = capsys.readouterr()
    text = _report_text(ab_study)
    for name in CONTROLLER_NAMES:
        assert name not in text.lower(), name
        assert name not in (console.out + console.err).lower(), name
    record = json.loads((ab_study / "report" / "report.json").read_text())
    assert record["blinding"] == {"blinded": True, "controllers_named": False, "unblinded_utc": [], "arms": None, "key_check": None,
                                  "completeness": None, "interim": None, "compares_arms": True, "interim_look": None, "interim_looks": []}
    assert set(record["table_ii"][0]["arms"]) == {"A", "B"}
    markdown = (ab_study / "report" / "report.md").read_text()
    assert "| Runs with | A: runs | A: yes / judged |" in markdown
    # The design section: the power under JMP's alternating coefficients, and no paper score shares on the A/B plan.
    assert "| Direction | 2 | 0.675 |" in markdown and "anticipated coefficients by JMP's convention" in markdown
    assert "86.7 %" not in markdown
    assert not (ab_study / "unblinding.json").exists()
    stems = ("scores", "trajectories", "ab_shares", "min_distance", "residuals", "correlation_map")
    assert {p.name for p in (ab_study / "report" / "figures").iterdir()} == {f"{stem}.{kind}" for stem in stems for kind in ("png", "svg")}
    # Every table is also a CSV file: Table II's rows, with runs and judgments per arm.
    with (ab_study / "report" / "tables" / "a_b_comparison_table_ii.csv").open() as handle:
        table = list(csv.DictReader(handle))
    assert [row["min_pedestrians"] for row in table] == ["2", "4", "6"]
    assert [int(row["A_runs"]) + int(row["B_runs"]) for row in table] == [18, 11, 6]
    # Numbers in their own columns, as numbers: shares as fractions, interval ends and p-values apart, no "%" or "< 0.001".
    assert all(cell == "" or float(cell) == float(cell) for row in table for cell in row.values())
    assert float(table[0]["A_share_low"]) < float(table[0]["A_share"]) < float(table[0]["A_share_high"]) <= 1.0
    assert (ab_study / "report" / "tables" / "the_design.csv").read_text().startswith("measure,value\nD-efficiency,55.87")


def test_dpi_sets_the_png_resolution_and_the_html_keeps_its_own(ab_study: Path) -> None:
    figures = ab_study / "report" / "figures"
    assert main(["report", "--study", str(ab_study)]) == 0
    default = {p.name: mpimg.imread(p).shape[:2] for p in figures.glob("*.png")}
    page = (ab_study / "report" / "report.html").read_text(encoding="utf-8")
    svgs = {p.name: p.read_bytes() for p in figures.glob("*.svg")}
    assert main(["report", "--study", str(ab_study), "--dpi", "300"]) == 0
    for name, (height, width) in default.items():
        scale = 300 / DEFAULT_DPI
        assert mpimg.imread(figures / name).shape[:2] == pytest.approx((scale * height, scale * width), rel=0.01), name
    assert {p.name: p.read_bytes() for p in figures.glob("*.svg")} == svgs  # SVG has no resolution
    stamp = re.compile(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\+00:00")  # when the report was made
    assert stamp.sub("", (ab_study / "report" / "report.html").read_text(encoding="utf-8")) == stamp.sub("", page)


def _expected_table(root: Path, left_out: tuple[str, ...] = ()) -> dict[int, dict[str, tuple[int, int]]]:
    """Table II counted independently: plan, sealed key and responses.csv, without the judgments of runs `left_out`."""
    arms = json.loads((root / "sealed" / "allocation.json").read_text())["arms"]
    with (root / "plan.csv").open() as handle:
        plan = {row["run_code"]: row for row in csv.DictReader(handle)}
    with (root / "responses.csv").open() as handle:
        responses = [r for r in csv.DictReader(handle) if r["run_code"] not in left_out]
    table: dict[int, dict[str, tuple[int, int]]] = {}
    for k in (2, 4, 6):
        for controller in arms.values():
            chosen = [r for r in responses if arms[plan[r["run_code"]]["Controller"]] == controller and int(plan[r["run_code"]]["Pedestrians"]) >= k]
            table.setdefault(k, {})[controller] = (sum(r["compliant"] == "yes" for r in chosen), len(chosen))
    return table


def test_unblinded_report_has_table_ii(ab_study: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["report", "--study", str(ab_study), *unblind(ab_study)]) == 0
    out = capsys.readouterr().out
    record = json.loads((ab_study / "report" / "report.json").read_text())
    key = json.loads((ab_study / "sealed" / "allocation.json").read_text())["arms"]
    assert record["blinding"]["arms"] == key and record["blinding"]["controllers_named"]
    expected = _expected_table(ab_study)
    assert [row["min_pedestrians"] for row in record["table_ii"]] == [2, 4, 6]
    for row in record["table_ii"]:
        counted = expected[row["min_pedestrians"]]
        assert {arm: (v["yes"], v["judged"]) for arm, v in row["arms"].items()} == counted
        (y1, n1), (y2, n2) = counted.values()
        assert row["fisher_p"] == pytest.approx(fisher_exact([[y1, n1 - y1], [y2, n2 - y2]]).pvalue)
        assert row["fisher_p"] <= row["holm_p"] <= 1.0
        assert row["difference"]["estimate"] == pytest.approx(y1 / n1 - y2 / n2)
    # The D-optimal plan is unbalanced within rows: 9, 5, 3 runs for one arm and 9, 6, 3 for the other.
    runs = sorted([row["arms"][arm]["runs"] for row in record["table_ii"]] for arm in ("NaviGAN-R", "Lattice"))
    assert runs == [[9, 5, 3], [9, 6, 3]]
    assert record["fits"][0]["method"].startswith("logistic GEE clustered by run")
    assert out.index("Primary result (run-level randomization test of Controller") < out.index("Judged socially compliant")
    # The primary result's numbers, in report.json: the mean run shares counted here from responses.csv and the key.
    with (ab_study / "responses.csv").open() as handle:
        judged: dict[str, list[int]] = {}
        for r in csv.DictReader(handle):
            judged.setdefault(r["run_code"], []).append(r["compliant"] == "yes")
    with (ab_study / "plan.csv").open() as handle:
        arm_of = {row["run_code"]: key[row["Controller"]] for row in csv.DictReader(handle)}
    primary = record["primary"]
    for name in key.values():
        shares = [sum(v) / len(v) for code, v in judged.items() if arm_of[code] == name]
        assert primary["mean_run_share"][name] == pytest.approx(sum(shares) / len(shares))
    first, second = primary["arms"]
    assert primary["randomization"]["difference"] == pytest.approx(primary["mean_run_share"][first] - primary["mean_run_share"][second])
    assert primary["randomization"]["exact"] and primary["randomization"]["allocations"] == 48_620
    assert primary["odds_ratio"]["low"] < primary["odds_ratio"]["estimate"] < primary["odds_ratio"]["high"]
    assert f"odds ratio {first} to {second} {primary['odds_ratio']['estimate']:.2f}" in out
    markdown = (ab_study / "report" / "report.md").read_text()
    assert markdown.index("**Primary result**") < markdown.index("| Runs with |")
    assert "SBPL (paper)" in markdown and "| >= 6 pedestrians |" in markdown
    row_four = next(line for line in markdown.splitlines() if line.startswith("| >= 4 pedestrians |"))
    assert "| 64 % |" in row_four and "| 75 % |" in row_four  # the paper's SBPL and NaviGAN-R
    assert "Lattice" in out and "NaviGAN-R" in out
    assert "Controller\\[Lattice\\]" in markdown or "Controller\\[NaviGAN-R\\]" in markdown  # brackets escaped in Markdown
    first = json.loads((ab_study / "unblinding.json").read_text())["unblinded_utc"]
    assert len(first) == 1
    # Unblinding again keeps the first time; a blinded report afterwards still names no controller.
    assert main(["report", "--study", str(ab_study), *unblind(ab_study)]) == 0
    times = json.loads((ab_study / "unblinding.json").read_text())["unblinded_utc"]
    assert times[0] == first[0] and len(times) == 2
    capsys.readouterr()
    assert main(["report", "--study", str(ab_study)]) == 0
    console = capsys.readouterr().out
    text = _report_text(ab_study)
    assert not any(name in text.lower() or name in console.lower() for name in CONTROLLER_NAMES)
    assert f"The key was opened before (first at {first[0]})" in (ab_study / "report" / "report.md").read_text()
    # The record of the openings lies outside report/: deleting the report keeps it, and the next report knows.
    shutil.rmtree(ab_study / "report")
    capsys.readouterr()
    assert main(["status", "--study", str(ab_study)]) == 0
    assert f"yes, on {', '.join(times)}" in capsys.readouterr().out
    assert main(["report", "--study", str(ab_study)]) == 0
    assert f"The key was opened before (first at {first[0]})" in (ab_study / "report" / "report.md").read_text()


def _made(root: Path, made: dict[str, str]) -> None:
    """Rewrite outcomes.csv's perception of some runs, as a run played from a robot log (`log`) or driven live (`live`) records it."""
    with (root / "outcomes.csv").open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    for row in rows:
        if row["run_code"] in made:
            row.update(perception=made[row["run_code"]], noise_std_m="", dropout="")
    with (root / "outcomes.csv").open("w", newline="") as handle:
        writer = csv.DictWriter(handle, list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def test_a_run_played_from_an_external_log_is_left_out_of_the_comparisons(ab_study: Path, capsys: pytest.CaptureFixture[str]) -> None:
    codes = [row["run_code"] for row in csv.DictReader((ab_study / "plan.csv").open())]
    external, driven = codes[0], codes[1]
    _made(ab_study, {external: "log", driven: "live"})
    with (ab_study / "responses.csv").open() as handle:
        answers = [row["compliant"] for row in csv.DictReader(handle) if row["run_code"] == external]
    judgments, yes = len(answers), answers.count("yes")
    assert main(["score", external, "3", "--by", "ana", "--study", str(ab_study)]) == 0
    capsys.readouterr()
    assert main(["report", "--study", str(ab_study), *unblind(ab_study)]) == 0
    out = capsys.readouterr().out
    record = json.loads((ab_study / "report" / "report.json").read_text())
    assert record["runs"]["made"] == {"simulated": 16, "driven live": 1, "software robot": 0, "external log": 1}
    assert record["runs"]["left_out_of_comparisons"] == [external]
    # Table II: every arm figure counted without the external run's judgments; 17 runs in the first row.
    expected = _expected_table(ab_study, left_out=(external,))
    assert {row["min_pedestrians"]: {arm: (v["yes"], v["judged"]) for arm, v in row["arms"].items()} for row in record["table_ii"]} == expected
    assert sum(v["runs"] for v in record["table_ii"][0]["arms"].values()) == 17
    # The external run has 2 pedestrians and so 2 simulated judgments (one per pedestrian), of 70: its arm's first row
    # loses exactly those (its yes among them), the other arm's keeps all of its own.
    arm, with_it = record["scores"][external]["arm"], _expected_table(ab_study)
    assert judgments == 2 and sum(n for _, n in with_it[2].values()) == 70
    assert expected[2] == {**with_it[2], arm: (with_it[2][arm][0] - yes, with_it[2][arm][1] - 2)}
    assert {name: v["runs"] for name, v in record["table_ii"][0]["arms"].items()} == {name: 8 if name == arm else 9 for name in with_it[2]}
    # The model fits: 17 runs each (the GEE's 68 judgments); the score counts: 17 runs, without the external run's human 3.
    markdown = (ab_study / "report" / "report.md").read_text()
    assert re.search(r"logistic GEE clustered by run \(exchangeable working correlation[^\n]*\): 17 runs, 68 observations", markdown)
    squares = [line for line in markdown.splitlines() if line.startswith("least squares:")]  # run shares and the four metrics
    assert len(squares) == 5 and all(line.startswith("least squares: 17 runs, 17 observations;") for line in squares)
    assert sum(record["score_counts"].values()) == 17 and record["scores"][external]["made"] == "external log"
    note = (f"1 run ({external}) was played from an external robot log: the toolkit did not drive that robot, so its {judgments} judgment(s) "
            "and 1 human score(s) are not credited to a controller: it is left out of Table II, the scores by arm and factor, and the model fits.")
    assert note in markdown and f"Note: {note}" in out
    line = "How the finished runs were made: 1 driven live on the robot, 16 simulated, 1 played from an external robot log."
    assert line in markdown and line in out
    assert re.search(rf"\| {external} \|.*\| \w+ \(external log\) \|", markdown) and re.search(rf"\| {driven} \|.*\| \w+ \(driven live\) \|", markdown)


def test_tampered_key_is_refused_and_changes_nothing(ab_study: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["report", "--study", str(ab_study)]) == 0
    before = {p: p.read_bytes() for p in ab_study.rglob("*") if p.is_file()}
    key_path = ab_study / "sealed" / "allocation.json"
    key = json.loads(key_path.read_text())
    key["arms"] = {"A": key["arms"]["B"], "B": key["arms"]["A"]}
    key_path.write_text(json.dumps(key))
    before[key_path] = key_path.read_bytes()
    capsys.readouterr()
    assert main(["report", "--study", str(ab_study), *unblind(ab_study)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1 and "does not match the commitment" in err
    assert {p: p.read_bytes() for p in ab_study.rglob("*") if p.is_file()} == before


def test_unblinding_checks_the_recorded_commitment_and_keeps_the_blinded_report(ab_study: Path, capsys: pytest.CaptureFixture[str]) -> None:
    recorded = recorded_digest(ab_study)
    assert main(["report", "--study", str(ab_study)]) == 0
    blinded = {p.relative_to(ab_study / "report"): p.read_bytes() for p in (ab_study / "report").rglob("*") if p.is_file()}
    before = {p: p.read_bytes() for p in ab_study.rglob("*") if p.is_file()}
    capsys.readouterr()
    wrong = ("0" if recorded[0] != "0" else "1") + recorded[1:]
    for args, message in ((["--unblind", "--commitment", wrong], "preregistration.md does not match the digest you recorded"),
                          (["--unblind", "--commitment", "abc"], "expected the 64 hex digits")):
        assert main(["report", "--study", str(ab_study), *args]) == 2
        err = capsys.readouterr().err
        assert err.startswith("error: ") and err.count("\n") == 1 and message in err, err
        assert {p: p.read_bytes() for p in ab_study.rglob("*") if p.is_file()} == before
    assert main(["report", "--study", str(ab_study), "--unblind", "--commitment", recorded.upper()]) == 0
    out = capsys.readouterr().out
    assert "matched the digest recorded outside the study" in out and "The blinded report is kept in" in out
    record = json.loads((ab_study / "report" / "report.json").read_text())
    assert record["blinding"]["controllers_named"] and "recorded outside the study" in record["blinding"]["key_check"]
    assert "matched the digest recorded outside the study" in (ab_study / "report" / "report.md").read_text()
    assert "The key was opened with 18 of 18 runs finished." in (ab_study / "report" / "report.md").read_text()
    kept = {p.relative_to(ab_study / "report" / "blinded"): p.read_bytes() for p in (ab_study / "report" / "blinded").rglob("*") if p.is_file()}
    assert kept == blinded
    # Unblinding again replaces the unblinded report only; the blinded one stays as it was.
    assert main(["report", "--study", str(ab_study), *unblind(ab_study)]) == 0
    assert "matched the digest recorded outside the study" in capsys.readouterr().out
    assert {p.relative_to(ab_study / "report" / "blinded"): p.read_bytes() for p in (ab_study / "report" / "blinded").rglob("*") if p.is_file()} == kept
    assert not (ab_study / "superseded").exists()


def test_human_scores_override_and_qualitative_plan(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = design(tmp_path / "q", ab=False)
    plan = folder.read_plan()
    run_all(folder, limit=25, blind=False)
    collided = write_run(folder, plan[25], Behaviour(collide=True), 7, "NaviGAN-R")
    backed = write_run(folder, plan[26], Behaviour(backup_s=1.0), 8, "NaviGAN-R")
    assert collided["status"] == "collision"
    root = str(folder.root)
    assert main(["score", collided["run_code"], "3", "--by", "ana", "--note", "brushed, no harm", "--study", root]) == 0
    assert main(["score", collided["run_code"], "2", "--by", "ben", "--note", NOTE, "--study", root]) == 0
    early = tmp_path / "early.csv"
    early.write_text(f"run_code,score,scorer,recorded_utc\n{backed['run_code']},2,cem,2025-06-01T00:00:00+00:00\n")
    assert main(["score", "--import", str(early), "--study", root]) == 0
    capsys.readouterr()
    assert main(["report", "--study", root]) == 0
    out = capsys.readouterr().out
    record = json.loads((folder.root / "report" / "report.json").read_text())
    scores = record["scores"]
    assert scores[collided["run_code"]] == {"arm": "NaviGAN-R", "made": "simulated", "rubric": 1, "reasons": ["collision"], "human": [3, 2], "final": 2}
    assert scores[backed["run_code"]]["rubric"] == 2 and "backed up 1.0 s" in scores[backed["run_code"]]["reasons"]
    assert scores[backed["run_code"]]["human"] == [2]
    finals = [s["final"] for s in scores.values()]
    assert record["score_counts"] == {"1": finals.count(1), "2": finals.count(2), "3": finals.count(3)}
    assert finals.count(3) == 25  # the smooth runs
    assert "Scores 1: 0 (0.0 %), 2: 2 (7.4 %), 3: 25 (92.6 %)" in out
    markdown = (folder.root / "report" / "report.md").read_text()
    assert "| 3 | 25 | 92.6 % |" in markdown and "86.7 %" in markdown
    assert "### Scores against each factor" in markdown and "| CrossingDistance |" in markdown
    assert "3 by ana (brushed, no harm); 2 by ben (&lt;img src=x onerror=alert(1)> \\[a\\](b) \\| \\_c\\_)" in markdown
    shown = MarkdownIt("commonmark").enable("table").render(markdown)  # the note as text, in its one cell
    assert "<img src=x" not in shown and "3 by ana (brushed, no harm); 2 by ben (&lt;img src=x onerror=alert(1)&gt; [a](b) | _c_)</td>" in shown
    assert f"Run {backed['run_code']} finished again (2026-01-01T00:00:00+00:00) after 1 of its scores or judgments were recorded" in markdown
    assert record["table_ii"] == [] and "Table II" not in markdown


def test_unfinished_runs_are_reported(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = design(tmp_path / "ab")
    run_all(folder, limit=10)
    missing = [row["run_code"] for row in folder.read_plan()[10:]]
    capsys.readouterr()
    assert main(["report", "--study", str(folder.root)]) == 0
    out = capsys.readouterr().out
    assert f"not finished yet: {', '.join(missing)}" in out
    record = json.loads((folder.root / "report" / "report.json").read_text())
    assert record["runs"] == {"planned": 18, "finished": 10, "not_finished": missing,
                              "made": {"simulated": 10, "driven live": 0, "software robot": 0, "external log": 0}, "left_out_of_comparisons": []}
    assert "How the finished runs were made" not in (folder.root / "report" / "report.md").read_text()  # all simulated: nothing to say
    markdown = (folder.root / "report" / "report.md").read_text()
    assert f"**Not finished yet (8):** {', '.join(missing)}" in markdown
    assert "10 of 18 runs have finished in this blinded study, so this report compares no arms" in markdown
    assert "No judgments of finished runs yet" in markdown
    assert markdown.count("not run yet") == 8


class _Sources(HTMLParser):
    """Every src and href of an HTML page, and the tags that could load something."""

    def __init__(self) -> None:
        super().__init__()
        self.images: list[str] = []
        self.references: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        values = dict(attrs)
        if tag == "img":
            self.images.append(values.get("src") or "")
        self.references += [value or "" for key, value in attrs if key in ("src", "href") and tag != "img"]
        if tag in ("script", "link", "iframe", "object", "embed"):
            self.references.append(tag)


def test_html_is_self_contained_with_png_figures(ab_study: Path) -> None:
    assert main(["report", "--study", str(ab_study), *unblind(ab_study)]) == 0
    page = (ab_study / "report" / "report.html").read_text(encoding="utf-8")
    parser = _Sources()
    parser.feed(page)
    assert [r for r in parser.references if not r.startswith("#")] == []  # links within the page only: its contents
    assert "url(" not in page and "@import" not in page
    assert len(parser.images) == 6  # scores, trajectories, shares, minimum gap, residuals, correlation map
    for source in parser.images:
        prefix = "data:image/png;base64,"
        assert source.startswith(prefix)
        image = mpimg.imread(io.BytesIO(base64.b64decode(source[len(prefix):], validate=True)), format="png")
        assert image.ndim == 3 and image.shape[0] > 200 and image.shape[1] > 400
        assert image[..., :3].std() > 0.05  # not blank
    assert page.count("<table>") >= 5 and "A/B comparison (Table II)" in page


def test_html_renders_in_headless_chromium(ab_study: Path, tmp_path: Path) -> None:
    need(screenshot_report.find_browser() is not None, "Chromium", "sudo apt-get install chromium")
    assert main(["report", "--study", str(ab_study)]) == 0
    shot = tmp_path / "shot.png"
    page = ab_study / "report" / "report.html"
    tall = screenshot_report.screenshot(page, shot, width=1200)  # the whole page, however tall
    image = mpimg.imread(shot)
    assert image.shape[:2] == (tall, 1200) and tall == screenshot_report.page_height(page, 1200, screenshot_report.find_browser())
    # The figures are drawn: plenty of saturated (coloured) pixels, which text and tables do not have.
    rgb = image[..., :3]
    saturated = (rgb.max(axis=2) - rgb.min(axis=2)) > 0.3
    assert saturated.mean() > 0.005


def test_all_yes_against_all_no_arms_report_without_crashing(ab_study: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # Arm A judged yes by everyone, arm B by no one: Wilson ends at exactly 1 and 0, GEE has no
    # estimates (separated), Firth's fit gives profile intervals; the report is written all the same.
    with (ab_study / "plan.csv").open() as handle:
        arm = {row["run_code"]: row["Controller"] for row in csv.DictReader(handle)}
    responses = ab_study / "responses.csv"
    lines = responses.read_text().splitlines()
    cells = [line.split(",") for line in lines[1:]]
    responses.write_text("\n".join([lines[0], *(",".join([c[0], c[1], "yes" if arm[c[0]] == "A" else "no", *c[3:]]) for c in cells)]) + "\n")
    assert main(["report", "--study", str(ab_study)]) == 0
    capsys.readouterr()
    record = json.loads((ab_study / "report" / "report.json").read_text())
    for row in record["table_ii"]:
        assert row["arms"]["A"]["share"] == 1.0 and row["arms"]["A"]["high"] == 1.0
        assert row["arms"]["B"]["share"] == 0.0 and row["arms"]["B"]["low"] == 0.0
        assert row["difference"]["estimate"] == 1.0 and row["odds_ratio"]["low"] > 1.0
    primary, _, judgment_level = record["fits"][:3]
    assert all(p["estimate"] is None for p in primary["parameters"]) and any("separated" in n for n in primary["notes"])
    assert "Firth" in judgment_level["method"]
    assert (ab_study / "report" / "figures" / "ab_shares.svg").exists()
    # The planned primary result stands: nine runs all yes against nine all no, of 48,620 allocations only this one
    # and its mirror image are as far apart.
    assert record["primary"]["randomization"]["difference"] == 1.0
    assert record["primary"]["p"] == pytest.approx(2 / 48_620)
    assert "**Primary result** (run-level randomization test of Controller" in (ab_study / "report" / "report.md").read_text()


def test_every_run_judged_yes_says_that_no_interval_can_be_formed(ab_study: Path, capsys: pytest.CaptureFixture[str]) -> None:
    responses = ab_study / "responses.csv"
    lines = responses.read_text().splitlines()
    responses.write_text("\n".join([lines[0], *(",".join([c[0], c[1], "yes", *c[3:]]) for c in (line.split(",") for line in lines[1:]))]) + "\n")
    assert main(["report", "--study", str(ab_study)]) == 0
    test = json.loads((ab_study / "report" / "report.json").read_text())["primary"]["randomization"]
    assert (test["difference"], test["p"], test["low"], test["high"]) == (0.0, 1.0, None, None)
    assert test["no_interval"] == "every run's share of yes is 100%, so no interval can be formed"
    markdown = (ab_study / "report" / "report.md").read_text()
    assert "difference +0.0 points (every run's share of yes is 100%, so no interval can be formed), p = 1.000" in markdown
    assert "95 % CI -0.0" not in markdown


def test_judgments_recorded_after_the_key_was_opened_are_counted_apart(ab_study: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["report", "--study", str(ab_study), *unblind(ab_study)]) == 0
    primary = json.loads((ab_study / "report" / "report.json").read_text())["primary"]
    codes = [row["run_code"] for row in csv.DictReader((ab_study / "plan.csv").open())]
    for participant in ("P1", "P2"):  # people who saw the unblinded report judge three runs
        for code in codes[:3]:
            assert main(["respond", code, participant, "no", "--study", str(ab_study)]) == 0
    assert main(["score", codes[0], "1", "--by", "ana", "--study", str(ab_study)]) == 0
    capsys.readouterr()
    assert main(["report", "--study", str(ab_study), *unblind(ab_study)]) == 0
    record = json.loads((ab_study / "report" / "report.json").read_text())
    # Six human judgments would replace the simulated ones; recorded after the opening, they change nothing.
    assert record["primary"] == primary and record["judgments"]["source"] == "simulated"
    assert record["recorded_after_opening"] == {"opened": record["blinding"]["unblinded_utc"][0], "judgments": 6, "scores": 1,
                                                "runs": sorted(codes[:3])}
    assert record["scores"][codes[0]]["human"] == []
    markdown = (ab_study / "report" / "report.md").read_text()
    assert "**6 judgment(s) and 1 human score(s) were recorded after the key was first opened" in markdown
    assert "left out of every table, test and fit of this report and counted apart" in markdown
