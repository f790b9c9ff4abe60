"""A real run's MCAP against its schemas: every navtrials.* channel declares its fields, every message fits,
the foxglove.* schemas are Foxglove's own, and --wall-clock moves the log times only."""

from __future__ import annotations

import json
import re
import shutil
import time
from pathlib import Path

import pytest
from jsonschema import Draft202012Validator, ValidationError

from robot_logs import run_log as fmt
from robot_logs.foxglove_log import FoxgloveReader
from robot_logs.foxglove_schemas import foxglove_schema
from robot_logs.run_log import read_run
from tests.support.mcap_schemas import validate_channels
from tests.support.run_studies import design_small_study
from trials.cli import main

pytestmark = pytest.mark.slow  # two runs of a small study end to end


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> tuple[Path, Path, dict[str, str]]:
    """One NaviGAN-R and one lattice row, run once with log times from 0 and once with --wall-clock."""
    study = tmp_path_factory.mktemp("schemas") / "study"
    design_small_study(study, blind=False)
    with (study / "plan.csv").open(encoding="utf-8") as handle:
        import csv

        rows = list(csv.DictReader(handle))
    codes = {row["Controller"]: row["run_code"] for row in rows}
    clocked = Path(shutil.copytree(study, study.parent / "clocked"))
    assert main(["run", "--study", str(study), "--only", *codes.values()]) == 0
    assert main(["run", "--study", str(clocked), "--only", *codes.values(), "--wall-clock"]) == 0
    return study, clocked, codes


def test_every_message_of_a_run_fits_its_channels_schema(runs):
    study, _, codes = runs
    for controller, code in codes.items():
        counts = validate_channels(study / "runs" / f"{code}.mcap")
        assert counts[fmt.ROBOT_STATE.schema] > 50 and counts[fmt.EVENTS.schema] == 2, controller
        assert counts[fmt.CONTROLLER_RECORD.schema] == counts[fmt.PLAN.schema] > 5
        assert counts["foxglove.SceneUpdate"] == counts[fmt.ROBOT_STATE.schema]


def test_the_run_logs_own_types_declare_their_fields(runs):
    study, _, codes = runs
    log = FoxgloveReader(study / "runs" / f"{codes['Lattice']}.mcap")
    state = fmt.SCHEMAS[fmt.ROBOT_STATE.schema]
    assert {"t", "x", "y", "theta", "v", "w", "v_cmd", "w_cmd"} <= set(state["properties"])
    assert all(field["type"] == "number" for field in state["properties"].values())
    own = {schema for schema in log.topics.values() if schema.startswith("navtrials.")}
    assert own == {fmt.ROBOT_STATE.schema, fmt.PEDESTRIANS.schema, fmt.PLAN.schema, fmt.CONTROLLER_RECORD.schema, fmt.EVENTS.schema}
    assert own <= set(fmt.SCHEMAS)


def test_a_message_that_breaks_the_format_fails_its_schema():
    validator = Draft202012Validator(fmt.SCHEMAS[fmt.ROBOT_STATE.schema])
    good = fmt.robot_state(1.2, (0.5, -0.25, 0.1), (0.4, 0.0), (0.45, 0.01))
    validator.validate(good)
    with pytest.raises(ValidationError, match="'theta' is a required property"):
        validator.validate({k: v for k, v in good.items() if k != "theta"})
    with pytest.raises(ValidationError, match="'speed' was unexpected"):
        validator.validate({**good, "speed": 1.0})
    with pytest.raises(ValidationError, match="'arrived' is not one of"):
        Draft202012Validator(fmt.SCHEMAS[fmt.EVENTS.schema]).validate(fmt.event(3.0, "arrived", ""))


def test_foxglove_types_carry_every_field_of_the_sdks_definition(runs):
    from foxglove import messages
    from google.protobuf.descriptor_pb2 import FileDescriptorSet

    scene = foxglove_schema("foxglove.SceneUpdate")
    entity = scene["properties"]["entities"]["items"]
    descriptor = next(m for f in FileDescriptorSet.FromString(messages.SceneEntity.get_schema().data).file
                      for m in f.message_type if m.name == "SceneEntity")
    assert list(entity["properties"]) == [field.name for field in descriptor.field]
    assert entity["properties"]["timestamp"]["title"] == "time" and entity["properties"]["lifetime"]["title"] == "duration"
    assert entity["properties"]["lines"]["items"]["properties"]["type"] == {"type": "integer"}
    assert foxglove_schema("foxglove.LaserScan")["properties"]["ranges"] == {"type": "array", "items": {"type": "number"}}
    with pytest.raises(KeyError):
        foxglove_schema("foxglove.NoSuchType")
    # Every entity in a real run's scene carries every field of Foxglove's SceneEntity.
    study, _, codes = runs
    required = Draft202012Validator({**entity, "required": list(entity["properties"])})
    scenes = [m.data for m in FoxgloveReader(study / "runs" / f"{codes['NaviGAN-R']}.mcap").messages(["/scene"])]
    for update in scenes[:20]:
        for item in update["entities"]:
            required.validate(item)


def test_wall_clock_moves_log_times_and_nothing_else(runs):
    study, clocked, codes = runs
    code = codes["NaviGAN-R"]
    plain, stamped = FoxgloveReader(study / "runs" / f"{code}.mcap"), FoxgloveReader(clocked / "runs" / f"{code}.mcap")
    assert plain.metadata[fmt.CLOCK_METADATA] == {"start_ns": "0", "start_utc": ""}
    start = int(stamped.metadata[fmt.CLOCK_METADATA]["start_ns"])
    assert abs(start / 1e9 - time.time()) < 600 and stamped.metadata[fmt.CLOCK_METADATA]["start_utc"].startswith("20")
    first = next(stamped.messages([fmt.ROBOT_STATE.name]))
    assert first.stamp_ns == start + round(first.data["t"] * 1e9)
    transform = next(stamped.messages([fmt.TRANSFORM.name])).data["timestamp"]
    assert transform["sec"] * 10**9 + transform["nsec"] == start  # the scene's own stamps move with the log times
    one, two = read_run(study / "runs" / f"{code}.mcap"), read_run(clocked / "runs" / f"{code}.mcap")
    assert (one.time == two.time).all() and (one.pose == two.pose).all() and one.events == two.events
    assert json.dumps(one.metadata, sort_keys=True) == json.dumps(two.metadata, sort_keys=True)


def test_inspect_lists_the_schemas_and_show_names_the_layout(runs, capsys):
    study, _, codes = runs
    path = study / "runs" / f"{codes['Lattice']}.mcap"
    assert main(["log", "inspect", str(path)]) == 0
    out = capsys.readouterr().out
    assert "schemas (JSON schemas: the fields Foxglove's panels offer):" in out
    assert re.search(r"navtrials\.RobotState +jsonschema +t, x, y, theta, v, w, v_cmd, w_cmd\n", out)
    assert re.search(r"foxglove\.SceneUpdate +jsonschema +deletions, entities\n", out)
    assert main(["log", "show", str(path)]) == 0
    assert f"Foxglove: open {path} with the layout {fmt.LAYOUT} (scene, robot velocity, events)" in capsys.readouterr().out
