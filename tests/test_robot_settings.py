"""The `[robot]` table and robot URIs: defaults that fit a Husky-class base, every key checked when read, one-line errors
naming the file and key, and `trials design --robot` carrying the table with the study."""

from __future__ import annotations

import tomllib

import pytest

from trials.cli import main
from trials.errors import StudyError
from trials.robot.settings import RobotSettings, read_robot_settings
from trials.robot.transport import ROS1, ROS2, RobotUri


def write(tmp_path, table: str):
    spec = tmp_path / "study.toml"
    spec.write_text(f'[study]\nname = "x"\n\n[robot]\n{table}\n', encoding="utf-8")
    return spec


def test_uris_are_read_and_bad_ones_refused():
    assert RobotUri.parse("ros1://127.0.0.1:11311") == RobotUri(ROS1, host="127.0.0.1", port=11311)
    assert RobotUri.parse("ros1://husky.local:11311/").master_uri == "http://husky.local:11311/"
    assert RobotUri.parse("ros2://42") == RobotUri(ROS2, domain=42)
    assert str(RobotUri.parse("ros2://0")) == "ros2://0"
    for bad in ("ros1://host", "ros1://host:0", "ros1://host:70000", "ros2://233", "ros2://-1", "http://x:1", "ros3://1", ""):
        with pytest.raises(StudyError, match="expected ros1://HOST:PORT"):
            RobotUri.parse(bad)


def test_defaults_fit_a_husky_and_the_table_overrides_them(tmp_path):
    assert read_robot_settings(tmp_path / "none.toml") is None
    default = RobotSettings()
    assert (default.scan_topic, default.odometry_topic, default.cmd_vel_topic, default.base_frame) == ("/scan", "/odom", "/cmd_vel", "base_link")
    assert (default.limits.max_speed, default.limits.max_reverse_speed, default.watchdog, default.command_rate) == (1.0, 0.5, 0.5, 20.0)
    spec = write(tmp_path, 'uri = "ros2://7"\nmax_speed = 0.6\ngoal = [8, 1]\nodometry_topic = ""\n[robot.goals]\nCrossing = [6.5, 0, 1.57]')
    settings = read_robot_settings(spec)
    assert settings is not None
    assert (settings.robot_uri.domain, settings.limits.max_speed, settings.limits.max_reverse_speed) == (7, 0.6, 0.3)
    assert settings.odometry_topic == ""
    assert settings.goal_for({"Direction": "Crossing"}) == (6.5, 0.0, 1.57)
    assert settings.goal_for({"Direction": "Parallel"}) == (8.0, 1.0)
    assert settings.recorded()["robot_goal"] == "8 1" and settings.recorded()["robot_max_speed"] == "0.6"
    # By default rows start and end relative to the study's start mark, the robot within 0.3 m and 0.35 rad.
    assert (RobotSettings().goal_frame, RobotSettings().start, RobotSettings().start_tolerance) == ("mark", (0.0, 0.0, 0.0), (0.3, 0.35))
    staged = read_robot_settings(write(tmp_path, 'goal_frame = "map"\nstart = [1.5, -2]\nstart_tolerance = [0.2, 0.1]'))
    assert staged is not None and (staged.goal_frame, staged.start, staged.start_tolerance) == ("map", (1.5, -2.0, 0.0), (0.2, 0.1))


@pytest.mark.parametrize("table, message", [
    ("speed = 1", "unknown key 'speed'"),
    ("max_speed = 0", "max_speed must be a number in [0.01, 5]"),
    ("max_speed = true", "max_speed must be a number"),
    ("watchdog = nan", "watchdog must be a number in [0.05, 5]"),
    ('uri = "ros1://robot"', "uri: robot URI 'ros1://robot'"),
    ('scan_topic = ""', "scan_topic must be a non-empty name"),
    ('base_frame = " base"', "base_frame must be a non-empty name without surrounding spaces"),
    ("goal = [1]", "goal must be [x, y] or [x, y, yaw]"),
    ('goal = [1, "2"]', "goal must be [x, y] or [x, y, yaw]"),
    ("goals = 3", "goals must be a table"),
    ("[robot.goals]\nCrossing = [1e9, 0]", "goals.Crossing must be [x, y]"),
    ("watchdog = 0.05\ncommand_rate = 20", "watchdog 0.05 s is shorter than two commands at 20 Hz"),
    ('cmd_vel_type = "TwistStampd"', "cmd_vel_type must be one of Twist, TwistStamped, got 'TwistStampd'"),
    ('nav_stack_cmd_vel_type = "twist"', "nav_stack_cmd_vel_type must be one of Twist, TwistStamped, got 'twist'"),
    ('nav_stack_cmd_vel_topic = "/cmd_vel"', "nav_stack_cmd_vel_topic must differ from cmd_vel_topic and estop_topic"),
    ('nav_stack_action = " move_base"', "nav_stack_action must be a name (may be empty)"),
    ("footprint = [0.5]", "footprint must be [length, width] in metres, each in [0.05, 10], got [0.5]"),
    ("footprint = [0.5, -0.4]", "footprint must be [length, width]"),
    ("min_valid_share = 1.5", "min_valid_share must be a number in [0, 1]"),
    ("protective_hold = 0", "protective_hold must be a number in [0.5, 600]"),
    ("start = [0, 0, 0, 0]", "start must be [x, y] or [x, y, yaw]"),
    ("start_tolerance = [0.3]", "start_tolerance must be [metres, radians], in [0.01, 5] and [0.01, 3.142], got [0.3]"),
    ("start_tolerance = [0.3, 4]", "start_tolerance must be [metres, radians]"),
])
def test_a_bad_table_is_one_line_naming_file_and_key(tmp_path, table, message):
    spec = write(tmp_path, table)
    with pytest.raises(StudyError) as error:
        read_robot_settings(spec)
    text = str(error.value)
    assert message in text and str(spec) in text and "[robot]" in text and "\n" not in text


def test_design_writes_the_robot_table_and_a_bad_one_exits_2(tmp_path, capsys):
    study = tmp_path / "s"
    assert main(["design", "--ab", "--robot", "ros2://3", "--seed", "1", "--study", str(study), "--quiet"]) == 0
    settings = read_robot_settings(study / "study.toml")
    assert settings is not None and settings.uri == "ros2://3"
    spec = study / "study.toml"
    spec.write_text(spec.read_text(encoding="utf-8").replace("max_speed = 1.0\n", "max_speed = -1\n"), encoding="utf-8")
    capsys.readouterr()
    assert main(["run", "--robot", "ros2://3", "--study", str(study)]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [f"error: {spec} [robot]: max_speed must be a number in [0.01, 5], got -1"]
    assert main(["run", "--robot", "ros9://3", "--study", str(study)]) == 2
    assert "expected ros1://HOST:PORT" in capsys.readouterr().err


def test_the_footprint_and_safety_keys_reach_the_limits_and_design_writes_every_default(tmp_path):
    settings = read_robot_settings(write(tmp_path, 'footprint = [0.45, 0.4]\ncmd_vel_type = "TwistStamped"\nstall_time = 4'))
    assert settings is not None and (settings.limits.half_length, settings.limits.half_width) == (0.225, 0.2)
    assert (settings.cmd_vel_type, settings.stall_time, settings.protective_margin) == ("TwistStamped", 4.0, 0.1)
    study = tmp_path / "s"
    assert main(["design", "--robot", "ros1://10.0.0.2:11311", "--seed", "1", "--study", str(study), "--quiet"]) == 0
    table = tomllib.loads((study / "study.toml").read_text(encoding="utf-8"))["robot"]
    defaults = {name: list(v) if isinstance(v := getattr(RobotSettings(), name), tuple) else v
                for name in RobotSettings.__dataclass_fields__ if name != "goals"}
    assert table == {**defaults, "uri": "ros1://10.0.0.2:11311"} and len(table) == 33
