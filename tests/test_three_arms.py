"""A blinded study of three arms end to end: NaviGAN-R, the lattice planner and a lab's planner from a package the toolkit
has never seen (the example plug-in, pip-installed into a folder of its own). In the simulator, and live against the
software robot over ROS 1 and over DDS: no public file or console line names a controller, the key unblinds each arm
to the controller that really drove it, and the report has the planned k-arm analysis."""

from __future__ import annotations

import json
import re
import subprocess
import time

import pytest

from robot_logs import run_log as fmt
from tests.support.blinding import mcap_text
from tests.support.example_plugin import NAME, install_example
from tests.support.live_rig import TRIALS, live_rig, set_robot_keys
from tests.support.registration import recorded_digest
from trials.outcomes import read_outcomes
from trials.sealed_runs import read_sealed_run
from trials.study import OUTCOMES, StudyFolder

pytestmark = pytest.mark.slow

ARMS = ("NaviGAN-R", "Lattice", NAME)
#: Any of the three controllers' names, their modules or their packages.
NAMED = re.compile(rb"navigan|lattice|sbpl|gapkeeper|gap_keeper|lab_planner|lab-planner", re.IGNORECASE)
#: What each controller's own record holds every step, in the sealed part: the evidence of which one drove.
OWN_RECORD = {"NaviGAN-R": "forces", "Lattice": "expansions", NAME: "nearest_person_m"}


def trials(env: dict[str, str], *args: str) -> subprocess.CompletedProcess:
    done = subprocess.run([*TRIALS, *args], capture_output=True, env=env, timeout=900)
    assert done.returncode == 0, done.stdout.decode() + done.stderr.decode()
    return done


def public_files(study: StudyFolder) -> list:
    return [p for p in study.root.rglob("*") if p.is_file() and "sealed" not in p.relative_to(study.root).parts]


def assert_names_nothing(study: StudyFolder, consoles: list[subprocess.CompletedProcess]) -> None:
    for console in consoles:
        assert not NAMED.search(console.stdout + console.stderr), console.stdout + console.stderr
    for path in public_files(study):
        assert not NAMED.search(readable(path)) and not NAMED.search(path.name.encode()), path


def readable(path) -> bytes:
    """What a file says: an MCAP's every record, a PNG's text chunks, any other file's bytes with embedded base64 images
    left out (compressed pixels spell anything by chance)."""
    if path.suffix == ".mcap":
        return mcap_text(path)
    if path.suffix == ".png":
        from PIL import Image

        with Image.open(path) as image:
            return json.dumps(image.text).encode()
    return re.sub(rb"base64,[A-Za-z0-9+/=]+", b"", path.read_bytes())


def assert_the_key_unblinds_to_what_drove(study: StudyFolder, codes: list[str]) -> None:
    arms = study.read_sealed().arms
    assert sorted(arms.values()) == sorted(ARMS)
    labels = {row["run_code"]: row["Controller"] for row in study.read_plan()}
    for code in codes:
        sealed = read_sealed_run(study, code)
        driver = arms[labels[code]]
        assert sealed["arm"] == labels[code] and sealed["controller"] == driver
        records = [step["record"] for step in sealed["topics"][fmt.CONTROLLER_RECORD.name]]
        assert records and all(OWN_RECORD[driver] in record for record in records), (driver, records[0])


def test_three_arms_in_the_simulator(tmp_path):
    env = install_example(tmp_path / "site")
    study = StudyFolder(tmp_path / "study")
    design = trials(env, "design", "--arms", ",".join(ARMS), "--seed", "21", "--power", "0", "--study", str(study.root))
    assert study.read_design()["blinding"]["arms"] == ["A", "B", "C"]
    counts = [row["Controller"] for row in study.read_plan()]
    assert sorted(counts) == ["A"] * 6 + ["B"] * 6 + ["C"] * 6  # 18 runs, balanced
    run = trials(env, "run", "--blind", "--study", str(study.root))
    respond = trials(env, "respond", "--simulate", "--study", str(study.root))
    report = trials(env, "report", "--study", str(study.root))
    assert_names_nothing(study, [design, run, respond, report])
    assert_the_key_unblinds_to_what_drove(study, [row["run_code"] for row in study.read_plan()])
    primary = json.loads(study.path("report/report.json").read_text(encoding="utf-8"))["primary"]
    assert primary["arms"] == ["A", "B", "C"] and primary["k_arms"]["correction"] == "Holm"
    assert [(p["first"], p["second"]) for p in primary["k_arms"]["pairs"]] == [("A", "B"), ("A", "C"), ("B", "C")]
    assert primary["p"] == primary["k_arms"]["global"]["p"] and 0.0 < primary["p"] <= 1.0
    # opened against the pre-registration's digest, the report names the controllers that drove
    trials(env, "report", "--unblind", "--commitment", recorded_digest(study.root), "--study", str(study.root))
    opened = json.loads(study.path("report/report.json").read_text(encoding="utf-8"))["primary"]
    arms = study.read_sealed().arms
    assert opened["arms"] == [arms[label] for label in ("A", "B", "C")]
    assert {(p["first"], p["second"]) for p in opened["k_arms"]["pairs"]} == {(arms[a], arms[b]) for a, b in (("A", "B"), ("A", "C"), ("B", "C"))}


@pytest.fixture
def plugin_env(tmp_path, middleware) -> tuple[str, dict[str, str]]:
    """The robot's URI and its rig's environment with the example plug-in installed."""
    uri, env = middleware
    installed = install_example(tmp_path / "site")
    return uri, {**env, "PYTHONPATH": installed["PYTHONPATH"] + (":" + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")}


def test_three_arms_live_against_the_software_robot(tmp_path, plugin_env):
    uri, env = plugin_env
    study = StudyFolder(tmp_path / "study")
    design = trials(env, "design", "--arms", ",".join(ARMS), "--robot", uri, "--seed", "5", "--power", "0", "--study", str(study.root))
    set_robot_keys(study.root, goal_frame='"odom"')
    one_each = list({row["Controller"]: row["run_code"] for row in study.read_plan()}.values())
    assert len(one_each) == 3
    consoles = [design]
    for code in one_each:
        with live_rig(uri, study.root, env) as rig:
            run = rig.trials_run("--only", code, "--blind")
            assert run.wait(timeout=300) == 0, rig.output()
            time.sleep(0.5)
            assert rig.last_heard() == (0.0, 0.0) and rig.moving_commands() > 20
            consoles.append(subprocess.CompletedProcess([], 0, rig.output().encode(), b""))
    finished = {row.run_code: row for row in read_outcomes(study.path(OUTCOMES), True)}
    assert set(finished) == set(one_each) and all(row.status in ("goal", "collision") for row in finished.values())
    assert all(row.perception == "software-robot" for row in finished.values())
    assert_names_nothing(study, consoles)
    assert_the_key_unblinds_to_what_drove(study, one_each)
