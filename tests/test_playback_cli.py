"""`trials playback`: outputs, resuming, and one-line errors (exit 2) for bad requests."""

from __future__ import annotations

import contextlib
import csv
import io
import json
import shutil
from pathlib import Path

import matplotlib.image as mpimg
import pytest
import torch

from navigan.playback.table import METRICS
from robot_logs.figure_files import DEFAULT_DPI
from trials.cli import main

QUICK = ["--split", "zara1", "--episodes", "3", "--threads", "1", "--quiet"]
COLUMNS = "navigan-r,navigan-r-dagger,human"


@pytest.fixture(autouse=True, scope="module")
def keep_threads():
    before = torch.get_num_threads()
    yield
    torch.set_num_threads(before)


def playback(data, out, *extra: str) -> int:
    return main(["playback", "--data", str(data), "--out", str(out), *QUICK, *extra])


def error_line(capsys) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: "), err
    return err


def table_rows(markdown: str) -> list[list[str]]:
    """The cells of every row of the Markdown tables in `markdown`."""
    return [[cell.strip() for cell in line.strip("|").split("|")] for line in markdown.splitlines() if line.startswith("| ")]  # rules start "|-"


@pytest.fixture(scope="module")
def walked(eth_ucy_dir, tmp_path_factory) -> tuple[Path, str]:
    """One playback of three columns on 3 zara1 episodes: its folder and what it printed."""
    out = tmp_path_factory.mktemp("walked") / "pb"
    with contextlib.redirect_stdout(io.StringIO()) as printed:
        assert playback(eth_ucy_dir, out, "--models", COLUMNS) == 0
    return out, printed.getvalue()


def stored_result(out: Path, model: str) -> dict:
    return json.loads((out / "episodes" / "zara1" / f"{model}.json").read_text())


@pytest.mark.slow
def test_the_printed_table_is_the_pooled_table_of_the_csv_and_markdown(walked):
    out, printed = walked
    with (out / "table1.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0])[4:] == ["R", "R_dagger", "human"]
    assert {r["scope"] for r in rows} == {"all", "split_mean", "zara1"} and {r["protocol"] for r in rows} == {"strict"}
    pooled = {(r["metric"], r["source"]): list(r.values())[4:] for r in rows if r["scope"] == "all"}
    assert {("S", "paper"), ("C", "ours_low"), ("A", "ours_high"), ("ade_m", "ours")} <= set(pooled)
    assert pooled["episodes", "ours"][2] == "3" and pooled["A", "ours"][2] == "1.000"
    assert pooled["C", "paper"] == ["0.970", "0.850", "0.960"] and pooled["A", "ours_low"][2] == "0.439"  # Wilson, 3 of 3
    split_mean = {(r["metric"], r["source"]): list(r.values())[4:] for r in rows if r["scope"] == "split_mean"}
    assert split_mean == pooled  # one split: the two aggregations agree
    shown = table_rows(printed)[1:]  # below the header
    assert ["A, 95 % interval", "0.439-1.000", "0.439-1.000", "0.439-1.000"] in shown
    ours = [cells[1:] for cells in shown if not cells[0].endswith(("interval", "paper")) and cells[0] != ""]
    assert ours[: len(METRICS)] == [values for (_, source), values in pooled.items() if source == "ours"]
    markdown = table_rows((out / "table1.md").read_text())
    assert all(cells in markdown for cells in shown)
    assert ["zara1", "crowds_zara01.txt", "3", "0"] in markdown  # episodes per split: recordings, kept, left out


@pytest.mark.slow
def test_every_episode_and_figure_is_written(walked):
    out, _ = walked
    with (out / "episodes.csv").open() as f:
        episodes = list(csv.DictReader(f))
    assert len(episodes) == 9 and {e["model"] for e in episodes} == set(COLUMNS.split(","))
    assert {e["protocol"] for e in episodes} == {"strict"}
    assert {"min_distance_m", "time_to_goal_s", "irregularity_rad_per_m", "ade_m"} <= set(episodes[0])
    assert {e[k] for e in episodes for k in ("arrived", "comfortable", "collided")} <= {"0", "1"}
    assert not {v for e in episodes for v in e.values()} & {"n/a", "None", "True", "False", "inf"}
    for name in ("fig4_zara1", "forces_zara1", "min_distance"):
        assert (out / "figures" / f"{name}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert b"<svg" in (out / "figures" / f"{name}.svg").read_bytes()
    record = stored_result(out, "navigan-r")
    assert record["checkpoint"]["file"] == "navigan-r-zara1.pt"
    settings = record["identity"]["settings"]
    assert (settings["seed"], settings["gamma"], settings["v_pref"], settings["subgoal_speed"]) == (0, 0.9, 1.0, "recorded")
    assert (settings["protocol"], settings["targets"], settings["distances"]) == ("strict", "observed", "interpolated")
    assert len(record["results"]) == 3 and len(record["results"][0]["path"]) == record["results"][0]["steps"] + 1


@pytest.mark.slow
def test_a_rerun_walks_only_what_is_missing_and_refuses_other_settings(walked, eth_ucy_dir, tmp_path, capsys):
    out = Path(shutil.copytree(walked[0], tmp_path / "pb"))
    stored = {p: p.stat().st_mtime_ns for p in (out / "episodes" / "zara1").glob("*.json")}
    assert len(stored) == 3
    (out / "episodes" / "zara1" / "navigan-r-dagger.json").unlink()  # as if interrupted before it
    assert playback(eth_ucy_dir, out, "--models", COLUMNS) == 0
    for path, mtime in stored.items():
        if path.name != "navigan-r-dagger.json":
            assert path.stat().st_mtime_ns == mtime  # not walked again
    assert (out / "episodes" / "zara1" / "navigan-r-dagger.json").is_file()

    human = out / "episodes" / "zara1" / "human.json"
    before = human.read_bytes()
    assert playback(eth_ucy_dir, out, "--models", "human", "--gamma", "0.95") == 2
    assert error_line(capsys).startswith(f"error: {human} ")
    assert human.read_bytes() == before
    assert playback(eth_ucy_dir, out, "--models", "navigan-r", "--subgoal-speed", "0") == 2
    assert error_line(capsys).startswith(f"error: {out / 'episodes' / 'zara1' / 'navigan-r.json'} ")


@pytest.mark.slow
def test_subgoal_speed_0_walks_the_same_weights_toward_the_goal_itself(walked, eth_ucy_dir, tmp_path):
    assert playback(eth_ucy_dir, tmp_path / "goal", "--models", "navigan-r", "--subgoal-speed", "0") == 0
    direct = stored_result(tmp_path / "goal", "navigan-r")
    assert direct["identity"]["settings"]["subgoal_speed"] is None
    assert [r["path"] for r in direct["results"]] != [r["path"] for r in stored_result(walked[0], "navigan-r")["results"]]


@pytest.mark.slow  # over 1.5 s: left out of the quick loop
def test_the_shielded_column_walks_navigan_r_with_the_margin_asked(eth_ucy_dir, tmp_path):
    out = tmp_path / "pb"
    assert playback(eth_ucy_dir, out, "--models", "navigan-r,navigan-r-shield", "--shield", "0.6") == 0
    with (out / "table1.csv").open() as f:
        assert list(next(csv.DictReader(f)))[4:] == ["R", "R_shield"]
    assert "it would come within 0.6 m of anyone's constant-velocity forecast" in (out / "table1.md").read_text()
    record = json.loads((out / "episodes" / "zara1" / "navigan-r-shield.json").read_text())
    assert record["checkpoint"]["file"] == "navigan-r-zara1.pt" and record["identity"]["settings"]["shield"] == 0.6
    plain = json.loads((out / "episodes" / "zara1" / "navigan-r.json").read_text())
    assert [r["path"] for r in record["results"]] != [r["path"] for r in plain["results"]]
    # Fig. 4 and the forces are drawn without the dagger column asked for, which is walked but not stored
    for name in ("fig4_zara1.png", "forces_zara1.png"):
        assert (out / "figures" / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in (out / "episodes" / "zara1").iterdir()) == ["navigan-r-shield.json", "navigan-r.json"]


@pytest.mark.slow  # over 1.5 s: left out of the quick loop
def test_the_evasion_column_walks_the_networks_its_checkpoint_holds_and_refuses_one_without(
        eth_ucy_dir, tmp_path, capsys):
    from navigan import checkpoint as ckpt
    from navigan.config import EvasionConfig
    from navigan.data import load_split
    from navigan.evasion_training import train_evasion
    from navigan.playback.episodes import load_episodes

    weights = tmp_path / "weights"
    weights.mkdir()
    mine = weights / "navigan-r-zara1.pt"
    record = ckpt.load(ckpt.shipped("navigan-r", "zara1"))
    record.evasion = None  # the shipped networks left out
    ckpt.save(record, mine)
    out = tmp_path / "pb"
    assert playback(eth_ucy_dir, out, "--checkpoints", str(weights), "--models", "navigan-r,navigan-r-evasion") == 2
    assert error_line(capsys) == (f"error: no evasion networks in {mine}: add them with trials train --evasion, "
                                  "or leave the -evasion column out\n")
    assert not out.exists()
    episodes = load_episodes(load_split(eth_ucy_dir, "zara1").train, "observed").subset(range(20))
    config = EvasionConfig(rounds=1, epochs=2, width=16, shortfall_batches=20)
    train_evasion(ckpt.load(mine), mine, episodes, config, save=lambda r: ckpt.save(r, mine))
    assert playback(eth_ucy_dir, out, "--checkpoints", str(weights), "--models", "navigan-r,navigan-r-evasion") == 0
    with (out / "table1.csv").open() as f:
        assert list(next(csv.DictReader(f)))[4:] == ["R", "R_evasion"]
    assert "R+evasion walks NaviGAN-R with its evasion networks" in (out / "table1.md").read_text()
    record = json.loads((out / "episodes" / "zara1" / "navigan-r-evasion.json").read_text())
    assert record["checkpoint"]["file"] == "navigan-r-zara1.pt" and len(record["results"]) == 3


@pytest.mark.slow  # over 1.5 s: left out of the quick loop
def test_figures_are_png_at_the_dpi_asked_and_svg_that_a_redraw_keeps_byte_for_byte(eth_ucy_dir, tmp_path):
    out = tmp_path / "pb"
    assert playback(eth_ucy_dir, out, "--models", "navigan-r,human", "--dpi", str(2 * DEFAULT_DPI)) == 0
    figures = out / "figures"
    names = {"fig4_zara1", "forces_zara1", "min_distance"}
    assert {p.name for p in figures.iterdir()} == {n + s for n in names for s in (".png", ".svg")}
    fine = {n: mpimg.imread(figures / f"{n}.png").shape[:2] for n in names}
    svgs = {n: (figures / f"{n}.svg").read_bytes() for n in names}
    assert all(s.startswith(b"<?xml") and b"<svg" in s and b"<dc:date>" not in s for s in svgs.values())
    stored = (out / "episodes" / "zara1" / "navigan-r.json").read_bytes()
    # the default resolution redraws the figures from the stored results: the dpi is not a setting of the scores
    assert playback(eth_ucy_dir, out, "--models", "navigan-r,human") == 0
    assert (out / "episodes" / "zara1" / "navigan-r.json").read_bytes() == stored
    for n in names:
        assert (figures / f"{n}.svg").read_bytes() == svgs[n], n
        height, width = mpimg.imread(figures / f"{n}.png").shape[:2]
        assert fine[n] == pytest.approx((2 * height, 2 * width), rel=0.01), n  # cropped to the drawing: within a few pixels


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--split", "mars"], "unknown split mars"),
        (["--models", "navigan,teleport"], "unknown model teleport"),
        (["--models", "human", "--gamma", "0"], "--gamma"),
        (["--models", "human", "--v-pref", "-1"], "--v-pref"),
        (["--models", "human", "--episodes", "0"], "--episodes"),
        (["--models", "human", "--subgoal-speed", "-1"],
         "--subgoal-speed: expected 'recorded' or a speed >= 0 in m/s, got '-1'"),
        (["--models", "human", "--subgoal-speed", "fast"], "--subgoal-speed: expected 'recorded'"),
        (["--models", "human", "--shield", "0"], "argument --shield: expected a finite number in (0, 10], got '0'"),
        (["--models", "human", "--dpi", "20"], "argument --dpi: expected a whole number from 50 to 1200, got '20'"),
    ],
)
def test_bad_requests_fail_in_one_line(eth_ucy_dir, tmp_path, capsys, args, message):
    out = tmp_path / "pb"
    assert playback(eth_ucy_dir, out, *args) == 2
    assert message in error_line(capsys)
    assert not out.exists()


def test_missing_checkpoint_is_named(eth_ucy_dir, tmp_path, capsys):
    empty = tmp_path / "weights"
    empty.mkdir()
    out = tmp_path / "pb"
    assert playback(eth_ucy_dir, out, "--models", "navil2-dagger,human", "--checkpoints", str(empty)) == 2
    assert f"missing checkpoint: {empty / 'navil2-zara1.pt'}" in error_line(capsys)
    assert not out.exists()


def test_the_paper_protocol_is_recorded_everywhere_and_never_mixed_with_the_strict_one(eth_ucy_dir, tmp_path, capsys):
    out = tmp_path / "pb"
    assert main(["playback", "--data", str(eth_ucy_dir), "--out", str(out), "--split", "zara1", "--models", "human",
                 "--protocol", "paper", "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert printed.startswith("Protocol paper; all splits pooled:") and "episodes per split: zara1 19" in printed
    assert "| C, paper | 0.960 |" in printed  # the paper's row beside ours
    markdown = (out / "table1.md").read_text()
    assert "Protocol `paper`: targets `present`, distances `frames`, networks handed the goal itself." in markdown
    assert "(pedestrians present for 44 consecutive frames)" in markdown
    settings = stored_result(out, "human")["identity"]["settings"]
    assert (settings["protocol"], settings["targets"], settings["distances"], settings["subgoal_speed"]) == (
        "paper", "present", "frames", None)
    for name in ("table1.csv", "episodes.csv"):
        with (out / name).open() as f:
            assert {r["protocol"] for r in csv.DictReader(f)} == {"paper"}
    assert main(["playback", "--data", str(eth_ucy_dir), "--out", str(out), "--split", "zara1", "--models", "human",
                 "--quiet"]) == 2
    assert "human.json was made with other settings and episodes" in error_line(capsys)


def test_missing_data_folder(tmp_path, capsys):
    assert playback(tmp_path / "nowhere", tmp_path / "pb", "--models", "human") == 2
    assert "splits.json" in error_line(capsys)


def transcription(folder, values, source="Tsai & Oh 2020, Table I (hand copy)") -> str:
    path = folder / "paper.json"
    path.write_text(json.dumps({"source": source, "values": values}))
    return str(path)


@pytest.mark.slow  # over 1.5 s: left out of the quick loop
def test_a_transcription_of_the_paper_is_printed_beside_ours(eth_ucy_dir, tmp_path):
    out = tmp_path / "pb"
    paper = transcription(tmp_path, {"S": {"human": -0.125}, "C": {"R": 0.875, "human": 0.75}, "A": {"R": 1}})
    assert playback(eth_ucy_dir, out, "--models", "navigan-r-shield,human", "--paper", paper) == 0
    with (out / "table1.csv").open() as f:
        rows = {(r["scope"], r["metric"], r["source"]): r for r in csv.DictReader(f)}
    assert rows["all", "C", "paper"]["human"] == "0.750" and rows["all", "S", "paper"]["human"] == "-0.125"
    assert rows["all", "A", "paper"]["human"] == ""  # not transcribed: an empty cell
    assert rows["all", "C", "paper"]["R_shield"] == ""  # not a column of the paper's
    assert ("zara1", "C", "paper") not in rows
    markdown = (out / "table1.md").read_text()
    assert "| C, paper |  | 0.750 |" in markdown
    assert "The paper's rows: Tsai & Oh 2020, Table I (hand copy)." in markdown

    # the shipped file: the paper's own values, and no hint that a transcription is missing
    assert playback(eth_ucy_dir, out, "--models", "navigan-r-shield,human") == 0
    markdown = (out / "table1.md").read_text()
    assert "| C, paper |  | 0.960 |" in markdown and "`trials playback --paper FILE`" not in markdown


def test_the_shipped_transcription_is_well_formed():
    from navigan.playback.paper import PAPER_COLUMNS, load_paper

    paper = load_paper()
    assert "Tsai & Oh" in paper.source and paper.transcribed == 24
    assert {m: sorted(row) for m, row in paper.values.items()} == {m: sorted(PAPER_COLUMNS) for m in "SCA"}
    assert paper.values["C"]["R"] == 0.97 and paper.values["A"]["R"] == 0.85 and paper.values["S"]["human"] == 0.44


@pytest.mark.parametrize(
    ("values", "message"),
    [
        ({"C": {"R": 1.7}}, "values.C.R: expected null or a fraction in [0, 1], got 1.7"),
        ({"A": {"human": True}}, "values.A.human: expected null or a fraction in [0, 1], got true"),
        ({"S": {"R": "0.3"}}, "values.S.R: expected null or a number, got \"0.3\""),
        ({"C": {"NaviGAN-R": 0.9}}, "values.C.NaviGAN-R: unknown column; expected Goal, L2,"),
        ({"D": {"R": 0.9}}, "values.D: unknown metric; expected S, C, A"),
        ({"C": [0.9]}, "values.C: expected an object of columns"),
        ([], "\"values\": expected an object of metrics"),
    ],
)
def test_a_bad_transcription_is_refused_before_any_work(eth_ucy_dir, tmp_path, capsys, values, message):
    out = tmp_path / "pb"
    paper = transcription(tmp_path, values)
    assert playback(eth_ucy_dir, out, "--models", "human", "--paper", paper) == 2
    assert f"error: {paper}: {message}" in error_line(capsys)
    assert not out.exists()


def test_an_unreadable_or_unsourced_transcription_is_refused(eth_ucy_dir, tmp_path, capsys):
    out = tmp_path / "pb"
    broken = tmp_path / "broken.json"
    broken.write_text('{"source": "x", "values": {"C": {"R": 0.9,}}}')
    assert playback(eth_ucy_dir, out, "--models", "human", "--paper", str(broken)) == 2
    assert f"cannot read the paper's table {broken}: Expecting property name" in error_line(capsys)
    assert playback(eth_ucy_dir, out, "--models", "human", "--paper", transcription(tmp_path, {}, source=" ")) == 2
    assert "expected an object with a non-empty \"source\" text" in error_line(capsys)
    assert playback(eth_ucy_dir, out, "--models", "human", "--paper", str(tmp_path / "absent.json")) == 2
    assert "cannot read the paper's table" in error_line(capsys) and not out.exists()
