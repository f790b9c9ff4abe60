"""Logged trials: `trials run --from-log FILE` and plan rows with a `Log` column, on the real sample logs.

A log's tracked people and recorded robot motion go through the row's controller open loop; its
plans are logged at 2.5 Hz next to the robot's recorded positions, and the run gets its MCAP and
outcome row as a simulated run does. The sample bags have no odometry (the robot stands at the
sensor's origin); a bag written here adds a robot driving by odometry.
"""

from __future__ import annotations

import csv
import gzip
import json
import os
import re
import shutil
import subprocess
import sys
from decimal import Decimal
from pathlib import Path

import numpy as np
import pytest

from robot_logs.foxglove_log import FoxgloveReader
from robot_logs.frames import Pose2D
from robot_logs.lidar_sim import LidarSimulator
from robot_logs.physical import STEP_S
from robot_logs.pipeline import PersonTracker
from robot_logs.records import Odometry, Transform
from robot_logs.run_log import CONTROLLER_TOPICS
from tests.support.bag_writer import BagWriter
from tests.support.blinding import NAMES, mcap_text
from tests.support.mcap_schemas import validate_channels
from trials.cli import main

pytestmark = pytest.mark.slow  # logged trials: bags tracked and studies run end to end

SPEC = """
[study]
name = "{name}"
runs = 2
model = "main"
seed = 21

[[factors]]
name = "{factor}"
type = "{kind}"
{levels}

[[factors]]
name = "Controller"
type = "{controller_kind}"
{controller}
"""
#: Two NaviGAN-R rows (the factor does not matter to a logged trial).
OPEN = {"name": "replay-open", "factor": "Site", "kind": "categorical", "levels": 'levels = ["hall", "lab"]',
        "controller_kind": "fixed", "controller": 'value = "NaviGAN-R"'}
#: Both controllers, blinded.
BLIND = {"name": "replay-ab", "factor": "Site", "kind": "fixed", "levels": 'value = "hall"',
         "controller_kind": "categorical", "controller": 'blind = true\nlevels = ["NaviGAN-R", "Lattice"]'}
WINDOW = ("--start", "15", "--duration", "6")
MOVING_SPEED = 1.0
PEOPLE = np.array([[6.0, 2.0], [3.0, -1.8]])


def design(folder: Path, values: dict[str, str]) -> Path:
    folder.mkdir(parents=True)
    spec = folder.parent / f"{folder.name}.toml"
    spec.write_text(SPEC.format(**values))
    assert main(["design", "--spec", str(spec), "--study", str(folder)]) == 0
    return folder


def table(path: Path) -> list[dict[str, str]]:
    with path.open(newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


def messages(path: Path, topic: str) -> list[dict]:
    return [m.data for m in FoxgloveReader(path).messages([topic])]


def write_plan(study: Path, logs: dict[str, str]) -> None:
    """Add a Log column to plan.csv, as a researcher would in a spreadsheet."""
    rows = table(study / "plan.csv")
    with (study / "plan.csv").open("w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, [*rows[0], "Log"], lineterminator="\n")
        writer.writeheader()
        writer.writerows({**row, "Log": logs.get(row["run_code"], "")} for row in rows)


@pytest.fixture(scope="module")
def template(tmp_path_factory) -> Path:
    return design(tmp_path_factory.mktemp("open") / "study", OPEN)


@pytest.fixture(scope="module")
def played(template, robot_logs_dir, tmp_path_factory):
    """The first row played from the ROS1 bag with --from-log, and, in a copy of the study, from the ROS2
    bag named in the plan's Log column (a path relative to the study), with the labelled bag in row two."""
    root = tmp_path_factory.mktemp("played")
    first, second = (row["run_code"] for row in table(template / "plan.csv"))
    ros1 = Path(shutil.copytree(template, root / "ros1"))
    assert main(["run", "--study", str(ros1), "--from-log", str(robot_logs_dir / "stationary_ros1.bag"), *WINDOW,
                 "--only", first]) == 0
    ros2 = Path(shutil.copytree(template, root / "ros2"))
    write_plan(ros2, {first: os.path.relpath(robot_logs_dir / "stationary_ros2", ros2),
                      second: str(robot_logs_dir / "legs_labelled_ros1.bag")})
    assert main(["run", "--study", str(ros2), *WINDOW]) == 0
    return ros1, ros2, first, second


def test_the_ros1_and_ros2_bags_give_identical_outcome_rows(played):
    ros1, ros2, first, _ = played
    (one,) = table(ros1 / "outcomes.csv")
    two = next(row for row in table(ros2 / "outcomes.csv") if row["run_code"] == first)
    assert {k: v for k, v in one.items() if k != "finished_utc"} == {k: v for k, v in two.items() if k != "finished_utc"}
    assert one["perception"] == "log" and one["controller"] == "NaviGAN-R"
    # The robot stood still (no odometry) for the whole 6 s window, 10 m short of its default goal.
    assert one["status"] == "timeout" and one["path_length_m"] == "0.000"
    assert 5.8 <= float(one["duration_s"]) <= 6.0
    assert 0.0 < float(one["min_distance_m"]) < 1.2 and 0.0 < float(one["time_within_1_2m_s"]) <= float(one["duration_s"])
    assert float(one["stopped_s"]) == pytest.approx(float(one["duration_s"]) - 1.0, abs=0.11)


def test_the_ros1_and_ros2_bags_give_equivalent_run_logs(played):
    ros1, ros2, first, _ = played
    one, two = FoxgloveReader(ros1 / "runs" / f"{first}.mcap"), FoxgloveReader(ros2 / "runs" / f"{first}.mcap")
    assert one.topics == two.topics
    assert {"/replay/comparison", "/replay/recorded_poses", "/controller/plan", "/robot/state"} <= set(one.topics)
    differ = {k for k in one.metadata["run"] if one.metadata["run"][k] != two.metadata["run"].get(k)}
    assert differ == {"log", "log_format"}
    assert one.metadata["replay"] == two.metadata["replay"]
    assert untimed(one) == untimed(two)
    assert validate_channels(ros1 / "runs" / f"{first}.mcap")["navtrials.ReplayComparison"] > 5


def untimed(log: FoxgloveReader) -> list[tuple[str, int, dict]]:
    """Every message of a run log, the controller's own wall-clock timings left out."""
    found = []
    for m in log.messages():
        data = m.data
        if m.topic == "/controller/record":
            data = {**data, "record": {k: v for k, v in data["record"].items() if not k.endswith("_seconds")}}
        found.append((m.topic, m.stamp_ns, data))
    return found


@pytest.mark.parametrize("flags", [(), ("--wall-clock",)], ids=["by default", "with --wall-clock"])
def test_a_logged_trial_keeps_the_real_times_its_log_was_recorded_at(template, robot_logs_dir, tmp_path, flags):
    study = Path(shutil.copytree(template, tmp_path / "study"))
    first = table(study / "plan.csv")[0]["run_code"]
    assert main(["run", "--study", str(study), "--from-log", str(robot_logs_dir / "stationary_ros1.bag"), *WINDOW,
                 "--only", first, *flags]) == 0
    log = FoxgloveReader(study / "runs" / f"{first}.mcap")
    start = int(log.metadata["clock"]["start_ns"])
    assert start == int(Decimal(log.metadata["run"]["log_start_stamp"]) * 10**9)
    assert log.metadata["clock"]["start_utc"].startswith("2014-")  # the sample bag's recording, not 1970
    state = next(log.messages(["/robot/state"]))
    assert state.data["t"] == 0.0 and state.stamp_ns == start


def test_plans_are_recorded_at_2_5_hz_next_to_the_recorded_robot(played):
    ros1, _, first, _ = played
    log = ros1 / "runs" / f"{first}.mcap"
    meta = FoxgloveReader(log).metadata
    assert meta["run"]["log_start_stamp"].startswith("1403201198.")  # header stamps, 15 s into the bag
    assert meta["run"]["odometry"].startswith("none") and meta["run"]["log_frame"] == "laser"
    states, plans, compared = (messages(log, t) for t in ("/robot/state", "/controller/plan", "/replay/comparison"))
    times = np.array([p["t"] for p in plans])
    end = states[-1]["t"]
    assert times[0] == 0.0 and np.allclose(np.diff(times), STEP_S) and len(times) == int(end / STEP_S + 1e-9) + 1
    assert np.allclose(np.diff([s["t"] for s in states]), 0.1, atol=0.02)  # one state per scan, 10 Hz
    assert all(s["x"] == s["y"] == s["theta"] == s["v"] == 0.0 for s in states)  # standing at the sensor's origin
    assert [c["t"] for c in compared] == list(times)
    deviations = []
    for plan, comparison in zip(plans, compared):
        covered = [p for k, p in enumerate(plan["waypoints"]) if plan["t"] + STEP_S * (k + 1) <= end + 1e-6]
        assert np.array(comparison["recorded"]).reshape(-1, 2).tolist() == [[0.0, 0.0]] * len(covered)
        if covered:
            expected = np.hypot(*np.array(covered).T).mean()
            assert comparison["deviation_m"] == pytest.approx(expected, abs=1e-3)
            deviations.append(comparison["deviation_m"])
        else:
            assert comparison["deviation_m"] is None
    summary = meta["replay"]
    assert int(summary["plans"]) == len(plans)
    assert float(summary["plan_deviation_mean_m"]) == pytest.approx(np.mean(deviations), abs=1e-3)
    clearances = [c["min_clearance_m"] for c in compared if c["min_clearance_m"] is not None]
    assert clearances and float(summary["plan_min_clearance_m"]) == pytest.approx(min(clearances), abs=1e-3)


def test_a_bag_stamped_on_another_clock_plays_by_its_header_stamps(played):
    _, ros2, _, second = played
    row = next(row for row in table(ros2 / "outcomes.csv") if row["run_code"] == second)
    # It plays to the end of its window by header stamps. Width rules once tracked a leg-like segment
    # inside the footprint the robot would have at the laser's origin (a collision); the shipped leg
    # detector does not take it for a person.
    assert row["status"] == "timeout" and row["collisions"] == "0" and float(row["min_distance_m"]) > 0.0
    log = ros2 / "runs" / f"{second}.mcap"
    meta = FoxgloveReader(log).metadata["run"]
    assert meta["scan_topic"] == "/training_scan"
    # Header stamps (2014-02-28), not the record times written 380 days later.
    assert meta["log_start_stamp"].startswith("13936158")
    times = [p["t"] for p in messages(log, "/controller/plan")]
    assert times[0] == 0.0 and np.allclose(np.diff(times), STEP_S) and len(times) == int(float(row["duration_s"]) / STEP_S) + 1
    assert [m["event"] for m in messages(log, "/events")] == ["start", "timeout"]


def test_log_show_summarises_a_logged_trial(played, capsys):
    ros1, _, first, _ = played
    assert main(["log", "show", first, "--study", str(ros1)]) == 0
    out = capsys.readouterr().out
    assert "played from" in out and "stationary_ros1.bag" in out and "plans against the log:" in out
    (row,) = table(ros1 / "outcomes.csv")
    printed = {line.split()[0]: line.split()[1] for line in out.splitlines() if line.startswith("  ")}
    for column in ("min_distance_m", "time_within_1_2m_s", "stopped_s"):
        assert float(printed[column]) == pytest.approx(float(row[column]), abs=0.02), column
    assert (ros1 / "runs" / f"{first}.png").exists()


@pytest.fixture(scope="module")
def moving_bag(tmp_path_factory) -> Path:
    """A robot driving straight along x at 1 m/s by odometry past two people standing aside, its laser
    0.3 m ahead of its base (tf_static), for 11 s."""
    path = tmp_path_factory.mktemp("moving") / "moving.bag"
    mount = Pose2D(0.3, 0.0, 0.0)
    lidar = LidarSimulator(seed=5)
    with BagWriter(path, "ros1") as bag:
        bag.transforms([Transform(1_000_000_000, "base_link", "laser", mount, True)], "/tf_static")
        for k in range(111):
            t = 1.0 + 0.1 * k
            base = Pose2D(MOVING_SPEED * (t - 1.0), 0.0, 0.0)
            bag.odometry(Odometry(int(round(t * 1e9)), "odom", "base_link", base, MOVING_SPEED, 0.0))
            bag.scan(lidar.scan(t, base.compose(mount), PEOPLE, None))
    return path


def test_a_robot_driving_by_odometry_reaches_its_goal(template, moving_bag, tmp_path, capsys, monkeypatch):
    # Simulated legs are not what the shipped detector learned from real scans: track them by width.
    monkeypatch.setattr(PersonTracker, "learned", classmethod(lambda cls, *args, **kwargs: cls()))
    study = Path(shutil.copytree(template, tmp_path / "study"))
    first = table(study / "plan.csv")[0]["run_code"]
    assert main(["run", "--study", str(study), "--from-log", str(moving_bag), "--only", first]) == 0
    assert "played from its log" in capsys.readouterr().out
    (row,) = table(study / "outcomes.csv")
    # Default goal: 10 m ahead of the first pose; reached (0.5 m) 9.5 s in.
    assert row["status"] == "goal" and float(row["time_to_goal_s"]) == pytest.approx(9.5, abs=0.06)
    assert float(row["path_length_m"]) == pytest.approx(9.5, abs=0.06)
    log = study / "runs" / f"{first}.mcap"
    meta = FoxgloveReader(log).metadata["run"]
    assert meta["odometry"] == "/odom" and meta["log_frame"] == "odom" and (meta["goal_x"], meta["goal_y"]) == ("10", "0")
    states = messages(log, "/robot/state")
    assert all(s["x"] == pytest.approx(MOVING_SPEED * s["t"], abs=1e-3) and s["v"] == MOVING_SPEED for s in states)
    early = next(s for s in messages(log, "/pedestrians/state") if s["t"] >= 2.0)  # both still in the laser's view
    seen = np.column_stack([early["x"], early["y"]])
    assert len(seen) == 2 and all(np.hypot(*(seen - p).T).min() < 0.15 for p in PEOPLE)  # tracked in odom
    plans, compared = messages(log, "/controller/plan"), messages(log, "/replay/comparison")
    assert plans[0]["t"] == pytest.approx(2.8)  # 8 samples 0.4 s apart observed first
    for comparison in compared:
        recorded = np.array(comparison["recorded"]).reshape(-1, 2)
        times = comparison["t"] + STEP_S * np.arange(1, len(recorded) + 1)
        assert np.allclose(recorded, np.column_stack([MOVING_SPEED * times, np.zeros(len(times))]), atol=1e-3)
    assert float(FoxgloveReader(log).metadata["replay"]["plan_min_clearance_m"]) > 0.5


@pytest.fixture
def fresh(template, tmp_path) -> Path:
    return Path(shutil.copytree(template, tmp_path / "study"))


def damaged_bag(folder: Path) -> Path:
    path = folder / "damaged.bag"
    path.write_bytes(b"#ROSBAG V2.0\n" + bytes(range(256)) * 40)
    return path


def odometry_only_bag(folder: Path) -> Path:
    path = folder / "odometry.bag"
    with BagWriter(path, "ros1") as bag:
        for k in range(20):
            bag.odometry(Odometry(1_000_000_000 + k * 100_000_000, "odom", "base_link", Pose2D(), 0.0, 0.0))
    return path


def short_bag(folder: Path) -> Path:
    """2 s of scans: less than the controller's 2.8 s observation window."""
    path = folder / "short.bag"
    lidar = LidarSimulator(seed=1)
    with BagWriter(path, "ros1") as bag:
        for k in range(21):
            bag.scan(lidar.scan(1.0 + 0.1 * k, Pose2D(), PEOPLE, None))
    return path


def one_cell_map(folder: Path, resolution: str) -> Path:
    """A ROS map_server map of one black cell, in its own folder."""
    folder = folder / f"map{resolution}"
    folder.mkdir()
    (folder / "map.pgm").write_bytes(b"P5\n1 1\n255\n\x00")
    path = folder / "map.yaml"
    path.write_text(f"image: map.pgm\nresolution: {resolution}\norigin: [0.0, 0.0, 0.0]\n")
    return path


@pytest.mark.parametrize("case, expected", [
    ("missing", r"nowhere\.bag: no such file"),
    ("damaged", r"damaged\.bag is damaged \(truncated or corrupt"),
    ("no scans", r"odometry\.bag has no LaserScan topic; its topics: /odom \(nav_msgs/msg/Odometry, 20\)"),
    ("short", r"short\.bag: too short for a logged trial: .* needs 2\.8 s of log \(8 steps of 0\.4 s\)"),
    ("short window", r"stationary_ros1\.bag: too short for a logged trial: its scans from 0\.0 s to 1\.0 s"),
    ("start past the end", r"--start 500 s lies beyond the log's last scan"),
    ("bad map", r"map\.yaml: field resolution: expected a cell size in metres above 0, got -0\.05$"),
    ("map without odometry", r"stationary_ros1\.bag has no Odometry topic"),
])
def test_bad_logs_are_one_line_errors_and_start_no_run(fresh, robot_logs_dir, tmp_path, capsys, case, expected):
    sample = str(robot_logs_dir / "stationary_ros1.bag")
    args = {
        "missing": ["--from-log", str(tmp_path / "nowhere.bag")],
        "damaged": ["--from-log", str(damaged_bag(tmp_path))],
        "no scans": ["--from-log", str(odometry_only_bag(tmp_path))],
        "short": ["--from-log", str(short_bag(tmp_path))],
        "short window": ["--from-log", sample, "--duration", "1"],
        "start past the end": ["--from-log", sample, "--start", "500"],
        "bad map": ["--from-log", sample, "--map", str(one_cell_map(tmp_path, "-0.05"))],
        "map without odometry": ["--from-log", sample, "--map", str(one_cell_map(tmp_path, "0.05"))],
    }[case]
    plan_before = (fresh / "plan.csv").read_bytes()
    assert main(["run", "--study", str(fresh), *args]) == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and re.search(expected, lines[0]), err
    assert not list((fresh / "runs").glob("*.mcap")) and not (fresh / "outcomes.csv").exists()
    assert (fresh / "plan.csv").read_bytes() == plan_before


def test_a_plan_log_that_is_missing_is_an_error_before_any_run(fresh, robot_logs_dir, capsys):
    codes = [row["run_code"] for row in table(fresh / "plan.csv")]
    write_plan(fresh, {codes[0]: str(robot_logs_dir / "stationary_ros1.bag"), codes[1]: "logs/lost.bag"})
    assert main(["run", "--study", str(fresh), *WINDOW]) == 2
    assert re.search(r"^error: .*logs/lost\.bag: no such file or folder$", capsys.readouterr().err.strip())
    assert not list((fresh / "runs").glob("*.mcap")) and not (fresh / "outcomes.csv").exists()


def test_a_blinded_logged_trial_names_no_controller(robot_logs_dir, tmp_path_factory):
    study = design(tmp_path_factory.mktemp("blind") / "study", BLIND)
    command = [sys.executable, "-m", "trials.cli"]
    run = subprocess.run([*command, "run", "--study", str(study), "--from-log", str(robot_logs_dir / "stationary_ros2"),
                          "--start", "8", "--duration", "3"], capture_output=True, timeout=300)
    assert run.returncode == 0, run.stderr.decode()
    assert b"2 runs finished" in run.stdout and b"played from its log" in run.stdout
    codes = [row["run_code"] for row in table(study / "plan.csv")]
    show = subprocess.run([*command, "log", "show", codes[0], "--study", str(study)], capture_output=True, timeout=120)
    assert show.returncode == 0, show.stderr.decode()
    for process in (run, show):
        assert not NAMES.search(process.stdout + process.stderr), process.stdout + process.stderr
    rows = table(study / "outcomes.csv")
    assert "controller" not in rows[0] and {r["perception"] for r in rows} == {"log"}
    checked = 0
    for path in study.rglob("*"):
        if path.is_dir() or "sealed" in path.relative_to(study).parts:
            continue
        content = mcap_text(path) if path.suffix == ".mcap" else path.read_bytes()
        assert not NAMES.search(content), f"{path} names a controller"
        checked += 1
    assert checked >= 2 + 1 + 4  # both logs, a picture, and the study's own files
    for code in codes:
        record = json.loads(gzip.decompress((study / "sealed" / "runs" / f"{code}.json.gz").read_bytes()))
        assert NAMES.search(record["controller"].encode())
        # The plans, the controller's records and the plans against the log are sealed, not public.
        assert {"/controller/plan", "/controller/record", "/replay/comparison"} <= set(record["topics"])
        assert int(record["metadata"]["replay"]["plans"]) == len(record["topics"]["/controller/plan"]) > 0
        public = FoxgloveReader(study / "runs" / f"{code}.mcap")
        assert "replay" not in public.metadata and not set(public.topics) & {t.name for t in CONTROLLER_TOPICS}
