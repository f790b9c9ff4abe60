"""The console's live runs over HTTP (Flask's test client) on a blinded study with a [robot] table: Start runs
`trials run --robot` in the background (here a stand-in process, so no robot is needed), one at a time; the
state endpoint reads runs/live.json; E-STOP creates runs/estop and stops the process; the run's ending is
recorded in run_events.csv. And a run played from an external log is marked as such on every page."""

from __future__ import annotations

import csv
import html
import math
import re
import shutil
import sys
import time
from pathlib import Path

import pytest

import trials.console.live as live
from robot_logs.frames import Pose2D
from tests.support.blinding import NAMES
from tests.support.console import CSRF, add_outcome, design_study, unblind
from trials.console.access import console_access
from trials.console.actions import Console
from trials.console.app import create_app
from trials.console.times import local_time
from trials.live_checks import record_check, record_decision
from trials.responses import record_response
from trials.robot.live_state import read_state, write_state
from trials.robot.people_check import PeopleCheck
from trials.robot.staging import StartMark, write_mark
from trials.runner import study_lock
from trials.study import LIVE_ESTOP, RUN_EVENTS, StudyFolder

ROBOT = "ros1://127.0.0.1:9"
#: Stands in for `trials run --robot`: runs until its end file appears (exit 0) or SIGTERM (exit 1), writing nothing.
STAND_IN = """
import pathlib, signal, sys, time
signal.signal(signal.SIGTERM, lambda *_: sys.exit(1))
end = pathlib.Path(sys.argv[1])
while not end.exists():
    time.sleep(0.02)
"""
#: Seconds to wait for a stand-in's ending to be recorded (a loaded machine starts Python slowly).
DEADLINE_S = 120.0


@pytest.fixture(scope="module")
def template(tmp_path_factory) -> Path:
    return design_study(tmp_path_factory.mktemp("console-live") / "study")


@pytest.fixture
def plain(template, tmp_path) -> Path:
    """The blinded two-run study, not driven live."""
    return Path(shutil.copytree(template, tmp_path / "plain"))


@pytest.fixture
def study(template, tmp_path) -> Path:
    """The same study with a [robot] table, as `trials design --robot` writes it."""
    copy = Path(shutil.copytree(template, tmp_path / "live"))
    with (copy / "study.toml").open("a") as spec:
        spec.write(f'\n[robot]\nuri = "{ROBOT}"\n')
    return copy


@pytest.fixture
def started(monkeypatch, tmp_path) -> list[tuple[str, str, Path]]:
    """Every live run the console starts, as (uri, code, study); each is the stand-in, ended by `end(tmp_path, code)`."""
    calls: list[tuple[str, str, Path]] = []

    def command(uri: str, code: str, root: Path) -> list[str]:
        calls.append((uri, code, root))
        return [sys.executable, "-c", STAND_IN, str(tmp_path / f"end-{code}")]

    monkeypatch.setattr(live, "run_command", command)
    return calls


def console_of(study: Path) -> tuple[Console, object]:
    folder = StudyFolder(study)
    console = Console(folder)
    return console, create_app(console, console_access(folder))


@pytest.fixture
def served(study, started):
    console, app = console_of(study)
    client = app.test_client()
    assert client.get(f"/?token={console_access(StudyFolder(study)).experimenter_token}").status_code == 302
    yield console, client
    console.live.close()


def codes_of(study: Path) -> list[str]:
    with (study / "plan.csv").open() as handle:
        return [row["run_code"] for row in csv.DictReader(handle)]


def events(study: Path) -> list[tuple[str, str, str]]:
    if not (study / RUN_EVENTS).exists():
        return []
    with (study / RUN_EVENTS).open(newline="") as handle:
        return [(e["run_code"], e["event"], e["detail"]) for e in csv.DictReader(handle)]


def alert(response) -> str:
    found = re.search(r'role="alert">Not recorded: (.*?)</p>', response.text)
    return found.group(1).replace("&#39;", "'").replace("&#96;", "`") if found else ""


def post(client, path: str, **form: str):
    """A form sent from the console's own page (its CSRF token from the first run's page)."""
    first = re.search(r'id="run-(\w+)"', client.get("/").text).group(1)
    token = CSRF.search(client.get(f"/runs/{first}").text).group(1)
    return client.post(path, data={"csrf_token": token, **form})


def ended(client, code: str) -> dict:
    """The run's live state once its ending is recorded (polled: the console records it from its own thread)."""
    deadline = time.monotonic() + DEADLINE_S
    while (state := client.get(f"/runs/{code}/live").json)["running"]:
        assert time.monotonic() < deadline, f"run {code}'s live run did not end within {DEADLINE_S} s"
        time.sleep(0.05)
    return state


def test_start_is_refused_in_a_study_not_driven_live(plain):
    _, app = console_of(plain)
    client = app.test_client()
    client.get(f"/?token={console_access(StudyFolder(plain)).experimenter_token}")
    code = codes_of(plain)[0]
    response = post(client, f"/runs/{code}/live")
    assert response.status_code == 400
    assert alert(response) == ("this study is not driven live: study.toml has no [robot] table (`trials design --robot URI` writes one) "
                               "and `trials serve` was not given --robot URI")
    assert events(plain) == []
    page = client.get(f"/runs/{code}").text
    assert 'id="live"' not in page and 'id="estop"' not in page and 'name="event" value="start" id="start"' in page
    assert client.get(f"/runs/{code}/live").json == {"run_code": code, "running": False}


def test_start_runs_trials_run_robot_one_live_run_at_a_time(study, started, served):
    console, client = served
    first, second = codes_of(study)
    page = client.get(f"/runs/{first}").text
    assert f'action="/runs/{first}/live"' in page and 'id="live-state">not started<' in page and 'id="estop"' not in page
    assert post(client, f"/runs/{first}/live").status_code == 302
    assert started == [(ROBOT, first, study)]
    assert events(study) == [(first, "start", f"driven live on {ROBOT}")]
    assert client.get(f"/runs/{first}/live").json == {"run_code": first, "state": "starting", "running": True,
                                                      "detail": "loading the controllers and reaching the robot"}

    refused = post(client, f"/runs/{second}/live")
    assert refused.status_code == 400
    assert alert(refused) == f"run {first} is being driven live now, and one live run goes at a time: wait for it to end, or press E-STOP"
    assert alert(post(client, f"/runs/{first}/live")) == f"run {first} is running: it cannot start (only a run that is pending or aborted can)"
    assert alert(post(client, f"/runs/{first}/event", event="finish")) == f"run {first} is being driven live: it ends by itself, or press E-STOP to stop it now"
    assert alert(post(client, f"/runs/{second}/event", event="start")).startswith(f"this study's runs are driven live on {ROBOT}")
    assert started == [(ROBOT, first, study)] and events(study) == [(first, "start", f"driven live on {ROBOT}")]
    for path in ("/", f"/runs/{second}", "/progress"):
        assert 'id="estop"' in client.get(path).text  # E-STOP on every experimenter page while a run is live

    # The worker reports through runs/live.json; the run ends at the goal with its outcome row.
    folder = StudyFolder(study)
    write_state(folder, first, "driving", "goal (10.00, 0.00) in odom")
    written = read_state(folder)
    assert client.get(f"/runs/{first}/live").json == {**written, "since": local_time(written["since_utc"]), "running": True}
    write_state(folder, first, "goal", "0.45 m from the goal")
    add_outcome(study, first, perception="live")
    (study.parent / f"end-{first}").touch()
    assert ended(client, first) == {**read_state(folder), "since": local_time(read_state(folder)["since_utc"]), "running": False}
    assert events(study) == [(first, "start", f"driven live on {ROBOT}"), (first, "finish", "")]
    page = client.get(f"/runs/{first}").text
    assert 'id="live-state">goal<' in page and "Driven live by the toolkit." in page and 'id="estop"' not in page
    assert re.search(rf'id="run-{first}">.*?<td>goal <span class="origin">\(driven live\)</span>', client.get("/").text, re.S)
    for path in ("/", f"/runs/{first}", f"/runs/{first}/live", f"/runs/{second}", "/progress"):
        answer = client.get(path)
        assert answer.status_code == 200 and not NAMES.search(answer.data), path
    write_state(folder, second, "waiting for sensors", "a scan on /scan")  # the state file moves on to the next run
    assert 'id="live-state">goal<' in client.get(f"/runs/{first}").text  # the first shows its outcome


def test_estop_creates_the_stop_file_and_stops_trials_run(study, started, served):
    console, client = served
    first, second = codes_of(study)
    estop = study / LIVE_ESTOP
    nothing = post(client, "/estop")
    assert nothing.status_code == 302 and estop.exists()  # it also stops a live run started elsewhere, from its file
    assert "none was going from this console" in client.get("/").text
    estop.unlink()

    assert post(client, f"/runs/{first}/live").status_code == 302
    stopped = post(client, "/estop", code=first)
    assert stopped.status_code == 302 and stopped.headers["Location"].endswith(f"/runs/{first}") and estop.exists()
    state = ended(client, first)
    assert (state["state"], state["detail"]) == ("aborted", "E-STOP from the console before the run started")
    assert events(study)[-1] == (first, "abort", "E-STOP from the console before the run started")
    assert 'name="event" value="abort"' not in client.get(f"/runs/{first}").text

    # A run the worker stopped says why in runs/<code>.failed.txt (`trials run` writes it); that is the reason recorded.
    assert post(client, f"/runs/{first}/live").status_code == 302  # an aborted run starts again
    why = f"run {first} aborted: e-stop from the console; its log is runs/aborted/{first}-2026-05-01T100000Z.mcap"
    StudyFolder(study).run_failure(first).write_text(why + "\n")
    write_state(StudyFolder(study), first, "aborted", "e-stop from the console")
    assert post(client, "/estop").status_code == 302
    assert ended(client, first)["detail"] == "e-stop from the console"
    assert events(study)[-1] == (first, "abort", why)
    assert [e for _, e, _ in events(study)] == ["start", "abort", "start", "abort"]
    write_state(StudyFolder(study), second, "driving", "goal (10.00, 0.00) in odom")  # another run, live from a terminal
    page = client.get(f"/runs/{first}").text
    assert 'id="live-state">aborted<' in page and f'id="live-detail">{why}<' in page  # the first shows why it was aborted


def test_the_new_actions_need_the_experimenter_and_the_forms_token(study, started, served):
    console, client = served
    code = codes_of(study)[0]
    stranger = console_of(study)[1].test_client()
    assert stranger.get(f"/runs/{code}/live").status_code == 403
    assert stranger.post("/estop").status_code in (400, 403) and not (study / LIVE_ESTOP).exists()
    forged = client.post(f"/runs/{code}/live", data={})
    assert forged.status_code == 400 and "not sent from this console" in forged.text
    assert client.post("/estop", data={}).status_code == 400
    assert started == [] and not (study / LIVE_ESTOP).exists() and events(study) == []
    assert client.get("/runs/ZZZZZ/live").status_code == 404


def test_state_of_a_live_run_started_elsewhere_comes_from_live_json(study, started, served):
    console, client = served
    first, second = codes_of(study)
    folder = StudyFolder(study)
    write_state(folder, first, "waiting for sensors", "a scan on /scan")
    with study_lock(folder):  # the `trials run` that drives it, started elsewhere, holds the study
        assert client.get(f"/runs/{first}/live").json == {**read_state(folder), "since": local_time(read_state(folder)["since_utc"]), "running": False}
        assert client.get(f"/runs/{second}/live").json == {"run_code": second, "running": False}
        page = client.get(f"/runs/{second}").text
        assert 'id="estop"' in page and f'<a href="/runs/{first}">{first}</a> is live on the robot' in page
    # That `trials run` gone (killed with its worker), the run is never shown as live, and E-STOP is no longer offered.
    gone = client.get(f"/runs/{first}/live").json
    assert (gone["state"], gone["detail"]) == ("aborted", "the `trials run` that drove it is no longer running")
    assert 'id="estop"' not in client.get("/").text
    write_state(folder, first, "aborted", "stale scans: none on /scan for 0.61 s (watchdog 0.5 s)")
    assert 'id="estop"' not in client.get("/").text


def test_a_run_played_from_an_external_log_is_marked_and_left_out_of_table_ii(plain):
    console, app = console_of(plain)
    client = app.test_client()
    client.get(f"/?token={console_access(StudyFolder(plain)).experimenter_token}")
    external, simulated = codes_of(plain)
    add_outcome(plain, external)  # perception `log`: played through `trials run`'s log player
    add_outcome(plain, simulated, perception="positions")
    for code in (external, simulated):
        for participant, answer in (("P01", "yes"), ("P02", "no")):
            record_response(console.folder, code, participant, answer)
    assert "External log: the toolkit did not drive this run." in client.get(f"/runs/{external}").text
    assert "External log" not in client.get(f"/runs/{simulated}").text
    assert re.search(rf'id="run-{external}">.*?<td>goal <span class="origin">\(external log\)</span>', client.get("/").text, re.S)
    assert 'id="table-ii"' not in client.get("/progress").text  # blinded: no comparison of arms until the key is opened
    unblind(plain)
    progress = client.get("/progress").text
    assert f"Left out: 1 run(s) played from an external robot log ({external})." in progress
    # Table II counts the simulated run's two judgments only: one yes of two, in its arm's column; none in the other arm's.
    sheet = console.sheet()
    arm = sheet.row(simulated).settings["Controller"]
    expected = [("1", "2", "1") if label == arm else ("0", "0", "0") for label in sheet.arms]
    assert re.findall(r"\((\d+)/(\d+); (\d+) runs\)", progress) == expected


def test_serve_refuses_a_bad_robot_uri(plain, capsys):
    from trials.cli import main

    assert main(["serve", "--study", str(plain), "--port", "0", "--robot", "http://robot:11311"]) == 2
    assert capsys.readouterr().err.startswith("error: robot URI 'http://robot:11311': expected ros1://HOST:PORT")


def test_the_live_command_is_trials_run_robot_on_the_one_run(tmp_path):
    assert live.run_command(ROBOT, "ABCDE", tmp_path) == [sys.executable, "-m", "trials.cli", "run", "--robot", ROBOT, "--only", "ABCDE",
                                                          "--study", str(tmp_path), "--quiet"]


def test_the_run_page_and_the_staging_sheet_show_each_rows_scene(served, study):
    console, client = served
    code = codes_of(study)[0]
    unmarked = client.get(f"/runs/{code}")  # staged on the start mark by default, and none was measured
    assert unmarked.status_code == 200 and 'id="staging-error"' in unmarked.text and "trials run --robot URI --mark" in unmarked.text
    assert client.get("/staging").status_code == 409
    write_mark(StudyFolder(study), StartMark("odom", Pose2D(1.0, 2.0, math.pi / 2), "2026-12-05T10:00:00+00:00"))
    page = client.get(f"/runs/{code}").text
    # The mark turned a quarter left: the start is the mark, the goal 10 m ahead of it (x 1, y 12) in odom.
    assert "robot: start (1.00, 2.00) facing 90 deg, goal (1.00, 12.00)" in page and 'id="staging-picture"' in page
    picture = client.get(f"/runs/{code}/staging.png")
    assert picture.status_code == 200 and picture.data.startswith(b"\x89PNG")
    sheet = client.get("/staging").text
    assert all(f'id="staging-{c}"' in sheet for c in codes_of(study)) and sheet.count("robot: start (1.00, 2.00)") == len(codes_of(study))
    assert 'id="staging-link"' in client.get("/").text
    for line in console.staging(code).lines():  # each walker's part, in the words the page shows
        assert html.escape(line, quote=False).replace("'", "&#39;") in page


def test_the_run_sheet_shows_each_live_runs_check_and_decision(served, study):
    _, client = served
    first, second = codes_of(study)[:2]
    folder = StudyFolder(study)
    record_check(folder, first, "goal", "", PeopleCheck(4, 3, 2.5, 2), blind=True)
    record_check(folder, second, "timeout", "after 60 s", PeopleCheck(2, 0, None, 1), blind=True)
    sheet = client.get("/").text
    assert '<td class="check">ok</td>' in sheet
    assert ("flagged: timeout: after 60 s; condition not met: at most 0 tracked at once, the row asks 2 (at least 1) [undecided]"
            in sheet)
    record_decision(folder, second, "stands", "walkers came late", blind=True)
    assert "[stands: walkers came late]" in client.get("/").text
