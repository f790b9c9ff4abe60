"""A field day through `trials serve` that cannot quietly go wrong (issue 38), over HTTP (Flask's test client) on the
blinded two-run study: every experimenter page says whether the study is blinded or since when it is not; the progress
page compares no arms before unblinding; participants' links carry an address their phones reach, or the run page
says that they cannot; times are local with their zone; a finished run's page shows its outcome and picture; a log is
played in the background and a corrected one replaces it with the earlier kept aside; the questionnaire opens once the
run is finished."""

from __future__ import annotations

import csv
import io
import re
import shutil
import socket
import struct
import threading
import time
from pathlib import Path
from types import SimpleNamespace

import pytest
import segno

import trials.console.actions as actions
from analysis.records import Response
from tests.support.blinding import NAMES
from tests.support.console import CSRF, SPEC, add_outcome, add_run_log, design_study, unblind
from trials.attached_logs import MAGIC
from trials.console.access import console_access
from trials.console.actions import Console
from trials.console.address import Reach, is_loopback, network_address, participant_reach
from trials.console.app import create_app
from trials.console.times import local_day, local_time
from trials.errors import StudyError
from trials.outcomes import Outcomes, read_outcomes
from trials.responses import append_responses
from trials.runner import Summary, supersede_runs
from trials.study import LOGS, OUTCOMES, RESPONSES, RUN_EVENTS, SUPERSEDED, UNBLINDING, StudyFolder

#: Central European time without the zone database: CET in winter, CEST in summer.
CENTRAL_EUROPE = "CET-1CEST,M3.5.0,M10.5.0/3"
#: Seconds to wait for a log played in the background (here a stand-in or a log refused at once).
DEADLINE_S = 60.0


@pytest.fixture(scope="module")
def template(tmp_path_factory) -> Path:
    return design_study(tmp_path_factory.mktemp("console-field-day") / "study")


@pytest.fixture
def study(template, tmp_path) -> Path:
    return Path(shutil.copytree(template, tmp_path / "study"))


@pytest.fixture
def codes(study) -> list[str]:
    with (study / "plan.csv").open() as handle:
        return [row["run_code"] for row in csv.DictReader(handle)]


@pytest.fixture
def arms(study, codes) -> dict[str, str]:
    """Each run's arm label."""
    with (study / "plan.csv").open() as handle:
        return {row["run_code"]: row["Controller"] for row in csv.DictReader(handle)}


@pytest.fixture
def central_europe(monkeypatch):
    """The laptop's zone set to Central European time for one test."""
    monkeypatch.setenv("TZ", CENTRAL_EUROPE)
    time.tzset()
    yield
    monkeypatch.undo()
    time.tzset()


def app_of(study: Path, reach: Reach | None = None):
    folder = StudyFolder(study)
    console = Console(folder)
    return console, create_app(console, console_access(folder), *([reach] if reach else []))


def signed_in(app, study: Path, base: str = "http://localhost"):
    client = app.test_client()
    assert client.get(f"/?token={console_access(StudyFolder(study)).experimenter_token}", base_url=base).status_code == 302
    return client


@pytest.fixture
def served(study):
    """The console of the study and its app."""
    return app_of(study)


@pytest.fixture
def console(served):
    return served[0]


@pytest.fixture
def experimenter(served, study):
    return signed_in(served[1], study)


def token_of(client, code: str) -> str:
    return CSRF.search(client.get(f"/runs/{code}").text).group(1)


def alert(response) -> str:
    found = re.search(r'role="alert">Not recorded: (.*?)</p>', response.text, re.S)
    return found.group(1).replace("&#39;", "'").replace("&#34;", '"') if found else ""


def events(study: Path) -> list[tuple[str, str, str]]:
    if not (study / RUN_EVENTS).exists():
        return []
    with (study / RUN_EVENTS).open(newline="") as handle:
        return [(e["run_code"], e["event"], e["detail"]) for e in csv.DictReader(handle)]


def finish(client, code: str) -> None:
    token = token_of(client, code)
    for event in ("start", "finish"):
        assert client.post(f"/runs/{code}/event", data={"event": event, "csrf_token": token}).status_code == 302


def header(page: str) -> str:
    found = re.search(r'id="blinding">(.*?)</span>', page, re.S)
    return found.group(1) if found else ""


# --- 1. blinded, or unblinded and since when, on every experimenter page ----------------------------------------------

def test_every_experimenter_page_says_blinded_until_the_key_is_opened_then_since_when(study, codes, experimenter, central_europe):
    add_outcome(study, codes[0])
    pages = ("/", f"/runs/{codes[0]}", f"/runs/{codes[0]}/score", "/progress")
    for path in pages:
        assert header(experimenter.get(path).text) == "field-day · blinded", path
    missing = experimenter.get("/runs/ZZZZZ")
    assert missing.status_code == 404 and header(missing.text) == "field-day · blinded"
    assert "blinded: arms by label only" in experimenter.get("/").text

    unblind(study, "2026-05-01T16:30:00+00:00")
    for path in pages:
        assert header(experimenter.get(path).text) == "field-day · unblinded on 2026-05-01 18:30 CEST", path
    assert "unblinded on 2026-05-01 18:30 CEST: arms by label here, the report names their controllers" in experimenter.get("/").text
    link = f"/q/{console_access(StudyFolder(study)).participant_token(codes[0])}"
    assert 'id="blinding"' not in experimenter.get(link).text  # a participant's page says nothing of the blinding

    (study / UNBLINDING).write_text("{not json")
    page = experimenter.get("/")
    assert page.status_code == 500 and header(page.text).startswith("blinding unknown: ") and "unblinding.json is damaged" in alert(page)


def test_a_key_opened_for_another_design_leaves_the_study_blinded(study, experimenter):
    unblind(study)
    record = (study / UNBLINDING).read_text()
    commitment = re.search(r'"commitment": "(\w+)"', record).group(1)
    (study / UNBLINDING).write_text(record.replace(commitment, "0" * len(commitment)))
    assert header(experimenter.get("/").text) == "field-day · blinded"


# --- 2. no unplanned interim look ------------------------------------------------------------------------------------

COMPARISONS = re.compile(r'id="table-ii"|Table II|\d+%|Holm|points|Share of|−')


def judged(study: Path, codes: list[str], controller: str | None = None) -> None:
    """Run 1 finished (simulated) with two human judgments, yes and no, and run 2 failed in `trials run`."""
    add_outcome(study, codes[0], perception="positions", controller=controller)
    append_responses(StudyFolder(study), [Response(codes[0], "P01", True, "human", "2026-05-01T10:05:00+00:00"),
                                          Response(codes[0], "P02", False, "human", "2026-05-01T10:06:00+00:00")])
    failure = StudyFolder(study).run_failure(codes[1])
    failure.parent.mkdir(parents=True, exist_ok=True)
    failure.write_text(f"run {codes[1]} failed: the robot's battery ran out\n")


def arm_rows(page: str) -> dict[str, list[int]]:
    table = re.search(r'<table id="completeness">(.*?)</table>', page, re.S).group(1)
    return {cells[0]: [int(c) for c in cells[1:]] for cells in (re.findall(r"<td>(.*?)</td>", row) for row in re.findall(r"<tr>(<td>.*?)</tr>", table))}


def test_a_blinded_progress_page_counts_and_compares_no_arms(study, codes, arms, experimenter):
    judged(study, codes)
    page = experimenter.get("/progress").text
    assert not COMPARISONS.search(page), COMPARISONS.search(page)
    assert "compares no arms" in page
    # planned, finished, pending, running, aborted, failed, judgments
    assert arm_rows(page) == {arms[codes[0]]: [1, 1, 0, 0, 0, 0, 2], arms[codes[1]]: [1, 0, 0, 0, 0, 1, 0]}
    assert "1 of 2 runs recorded; 2 judgment(s) from 2 participant(s); 0 score(s)." in page
    for path in ("/", f"/runs/{codes[0]}", f"/runs/{codes[1]}", f"/runs/{codes[0]}/score"):
        assert not COMPARISONS.search(experimenter.get(path).text), path

    unblind(study)
    page = experimenter.get("/progress").text
    arm = arms[codes[0]]
    assert 'id="table-ii"' in page and "50% (1/2; 1 runs)" in page and arm_rows(page)[arm] == [1, 1, 0, 0, 0, 0, 2]


def test_an_open_study_compares_its_arms_as_it_goes(tmp_path):
    study = design_study(tmp_path / "open", SPEC.replace("blind = true\n", ""))
    with (study / "plan.csv").open() as handle:
        plan = list(csv.DictReader(handle))
    codes = [row["run_code"] for row in plan]
    judged(study, codes, plan[0]["Controller"])
    page = signed_in(app_of(study)[1], study).get("/progress").text
    assert 'id="table-ii"' in page and "50% (1/2; 1 runs)" in page and header(page) == "field-day"


# --- 3. phones reach the questionnaire -------------------------------------------------------------------------------

def test_where_phones_reach_the_console():
    assert [is_loopback(host) for host in ("127.0.0.1", "127.0.1.1", "localhost", "::1", "[::1]", "0.0.0.0", "192.168.1.5", "lab-laptop")] == [
        True, True, True, True, True, False, False, False]
    for loopback in ("127.0.0.1", "localhost", "::1"):
        reach = participant_reach(loopback, lambda: pytest.fail("no network address is looked for on loopback"))
        assert reach.local_only and reach.host is None
    assert participant_reach("0.0.0.0", lambda: "192.168.1.23") == Reach("0.0.0.0", "192.168.1.23")
    assert participant_reach("::", lambda: "10.0.0.7") == Reach("::", "10.0.0.7")
    assert participant_reach("0.0.0.0", lambda: None) == Reach("0.0.0.0", None)  # none found: the browser's address
    assert participant_reach("192.168.1.5", lambda: pytest.fail("the address served on is the one")) == Reach("192.168.1.5", "192.168.1.5")
    assert not participant_reach("0.0.0.0", lambda: None).local_only


def test_the_network_address_found_is_this_machines_own():
    found = network_address()
    if found is None:
        return  # a machine with loopback only: the links carry the browser's address (tested above)
    assert not is_loopback(found)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as own:
        own.bind((found, 0))  # only an address of this machine binds; nothing is sent


def participant_link(page: str) -> str:
    return re.search(r'id="participant-link">([^<]+)<', page).group(1)


def qr_of(page: str) -> str:
    return re.search(r'<div class="qr">(.*?)</div>', page, re.S).group(1)


def test_on_loopback_the_run_page_says_phones_cannot_reach_it_and_how_to_let_them_in(study, codes, experimenter):
    page = experimenter.get(f"/runs/{codes[0]}").text
    assert "Phones cannot reach this link: the console listens on 127.0.0.1, this laptop only." in page
    assert f'id="serve-command">trials serve --study {study} --host 0.0.0.0<' in page
    token = console_access(StudyFolder(study)).participant_token(codes[0])
    assert participant_link(page) == f"http://localhost/q/{token}"
    assert qr_of(page) == segno.make(participant_link(page), error="m").svg_inline(scale=4)


@pytest.mark.parametrize(("reach", "base", "expected"), [
    (Reach("0.0.0.0", "192.168.1.23"), "http://127.0.0.1:8765", "http://192.168.1.23:8765"),
    (Reach("::", "fd00::5"), "http://127.0.0.1:8765", "http://[fd00::5]:8765"),
    (Reach("192.168.1.5", "192.168.1.5"), "http://192.168.1.5:8000", "http://192.168.1.5:8000"),
    (Reach("0.0.0.0", None), "http://127.0.0.1:8765", "http://127.0.0.1:8765"),  # nothing found: the address the browser used
])
def test_on_the_network_links_and_codes_carry_the_laptops_address(study, codes, reach, base, expected):
    client = signed_in(app_of(study, reach)[1], study, base)
    page = client.get(f"/runs/{codes[0]}", base_url=base).text
    token = console_access(StudyFolder(study)).participant_token(codes[0])
    assert participant_link(page) == f"{expected}/q/{token}"
    assert qr_of(page) == segno.make(f"{expected}/q/{token}", error="m").svg_inline(scale=4)
    assert "Phones cannot reach" not in page
    assert ("No network address of this laptop was found" in page) == (reach.host is None)


# --- 4. local times with their zone ----------------------------------------------------------------------------------

def test_times_are_shown_in_local_time_with_the_zone(central_europe):
    assert local_time("2026-05-01T10:00:00+00:00") == "2026-05-01 12:00 CEST"
    assert local_time("2026-12-03T13:32:00+00:00") == "2026-12-03 14:32 CET"
    assert local_time("2026-12-03T13:32:00") == "2026-12-03 14:32 CET"  # a file's time without a zone is UTC
    assert (local_time(""), local_time("soon")) == ("", "soon")
    assert local_day("2026-05-01T22:30:00+00:00") == "2026-05-02"


def test_times_without_a_zone_name_show_the_offset(monkeypatch):
    monkeypatch.setenv("TZ", "<+0530>-5:30")
    time.tzset()
    try:
        assert local_time("2026-05-01T10:00:00+00:00") in ("2026-05-01 15:30 +0530", "2026-05-01 15:30 +05:30")
    finally:
        monkeypatch.undo()
        time.tzset()


def test_pages_show_events_outcomes_and_days_in_local_time(study, codes, experimenter, central_europe):
    code = codes[0]
    token = token_of(experimenter, code)
    assert experimenter.post(f"/runs/{code}/event", data={"event": "start", "csrf_token": token}).status_code == 302
    assert experimenter.post(f"/runs/{code}/event", data={"event": "note", "detail": "wet floor", "csrf_token": token}).status_code == 302
    with (study / RUN_EVENTS).open(newline="") as handle:
        started, noted = (row["recorded_utc"] for row in csv.DictReader(handle))
    page = experimenter.get(f"/runs/{code}").text
    assert f"Started {local_time(started)}." in page and f"<li>{local_time(noted)} note: wet floor</li>" in page
    assert re.fullmatch(r"\d{4}-\d\d-\d\d \d\d:\d\d CES?T", local_time(started)) and started not in page
    add_outcome(study, codes[1], finished_utc="2026-05-01T22:30:00+00:00")
    assert "<tr><th>Finished</th><td>2026-05-02 00:30 CEST</td></tr>" in experimenter.get(f"/runs/{codes[1]}").text
    assert "<tr><td>2026-05-02</td><td>1</td></tr>" in experimenter.get("/progress").text  # the local day, not the UTC one


# --- 5. a run page that shows the run ---------------------------------------------------------------------------------

def figures(page: str) -> list[tuple[str, str]]:
    return re.findall(r"<tr><th>(.*?)</th><td>(.*?)</td></tr>", re.search(r'<table class="figures">(.*?)</table>', page, re.S).group(1))


def test_a_finished_runs_page_shows_its_outcome_and_its_picture(study, codes, experimenter, central_europe):
    code, other = codes
    add_outcome(study, code)
    add_run_log(study, code)
    page = experimenter.get(f"/runs/{code}").text
    assert figures(page) == [("Status", "goal"), ("Duration", "12.0 s"), ("Time to goal", "12.0 s"), ("Path length", "9.50 m"),
                             ("Closest gap", "0.80 m"), ("Within 0.5 m", "0.0 s"), ("Within 1.2 m", "1.2 s"), ("Collisions", "0"),
                             ("Finished", "2026-05-01 12:00 CEST")]
    assert f'<img id="picture" class="picture" src="/runs/{code}/picture.png"' in page and not NAMES.search(page.encode())
    picture = experimenter.get(f"/runs/{code}/picture.png")
    assert picture.status_code == 200 and picture.mimetype == "image/png" and picture.data[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = struct.unpack(">II", picture.data[16:24])
    assert width > 400 and height > 250
    assert experimenter.get(f"/runs/{code}/picture.png").data == picture.data  # drawn once, kept while the log is the same
    assert app_of(study)[1].test_client().get(f"/runs/{code}/picture.png").status_code == 403
    missing = experimenter.get(f"/runs/{other}/picture.png")
    assert missing.status_code == 404 and f"run {other} has no log yet" in missing.text
    assert 'id="picture"' not in experimenter.get(f"/runs/{other}").text and 'class="figures"' not in experimenter.get(f"/runs/{other}").text
    assert 'id="correct"' in page  # played from a log: a corrected one may replace it


def test_a_run_made_by_the_toolkit_offers_no_corrected_log(study, codes, experimenter):
    add_outcome(study, codes[0], perception="live")
    assert 'id="correct"' not in experimenter.get(f"/runs/{codes[0]}").text
    response = experimenter.post(f"/runs/{codes[0]}/log", data={"log": (io.BytesIO(MAGIC[".bag"] + b"x"), "fix.bag"), "replace": "1",
                                                                "csrf_token": token_of(experimenter, codes[0])}, content_type="multipart/form-data")
    assert alert(response) == f"run {codes[0]} was not played from an attached robot log, so it has no log to correct"
    assert not (study / LOGS).exists()


@pytest.fixture
def stand_in(monkeypatch):
    """`run_study` replaced by a stand-in that waits for `go` and then does what `trials run --from-log` (with --rerun,
    moving the earlier run aside through the runner's own `supersede_runs`) would, or fails; records each call."""
    state = SimpleNamespace(go=threading.Event(), calls=[], fail="", duration=15.5)

    def run_study(study, workers, only, rerun, options, on_start, on_done, on_failed):
        state.calls.append((only, rerun, options.replay.log, options.replay.start_s, options.replay.duration_s))
        assert state.go.wait(DEADLINE_S)
        if state.fail:
            raise StudyError(state.fail)
        folder = study.folder
        superseded = supersede_runs(folder, Outcomes(folder, True), rerun, "2026-05-01T120000+0000") if rerun else None
        code = (only or rerun)[0]
        add_outcome(folder.root, code, duration_s=state.duration)
        outcome = next(o for o in read_outcomes(folder.path(OUTCOMES)) if o.run_code == code)
        return Summary(finished=[SimpleNamespace(code=code, outcome=outcome)], superseded=superseded)

    monkeypatch.setattr(actions, "run_study", run_study)
    return state


def played(client, code: str) -> dict:
    """The log's state once it is no longer being played (polled, as the run page's script does)."""
    deadline = time.monotonic() + DEADLINE_S
    while (state := client.get(f"/runs/{code}/log").json)["running"]:
        assert time.monotonic() < deadline, f"run {code}'s log was still being played after {DEADLINE_S} s"
        time.sleep(0.02)
    return state


def upload(client, code: str, content: bytes, name: str = "robot.bag", **form: str):
    return client.post(f"/runs/{code}/log", data={"log": (io.BytesIO(content), name), "csrf_token": token_of(client, code), **form},
                       content_type="multipart/form-data")


def test_a_log_is_played_in_the_background_while_its_page_says_so(study, codes, experimenter, console, stand_in):
    code, other = codes
    finish(experimenter, code)
    finish(experimenter, other)
    bag = MAGIC[".bag"] + b"a robot's log"
    sent = upload(experimenter, code, bag, start="15", duration="6")
    assert sent.status_code == 302  # at once: the log is played in the background
    page = experimenter.get(f"/runs/{code}").text
    assert f"Run {code}: its log logs/{code}.bag is being checked and played" in page
    assert 'id="playing"' in page and "Checking and playing the log..." in page and 'id="attach"' not in page
    assert experimenter.get(f"/runs/{code}/log").json["running"] is True
    busy = upload(experimenter, other, bag)
    assert busy.status_code == 400
    assert alert(busy) == f"run {code}'s log is being checked and played; one log at a time: wait until its page shows the outcome"
    assert experimenter.get("/progress").status_code == 200  # the other pages stay open meanwhile
    stand_in.go.set()
    assert played(experimenter, code) == {"run_code": code, "running": False, "log": f"logs/{code}.bag", "outcome": "goal", "error": "",
                                          "since": local_time(console.playing(code).since_utc)}
    assert stand_in.calls == [([code], [], study / LOGS / f"{code}.bag", 15.0, 6.0)]
    assert events(study)[-1] == (code, "log", f"logs/{code}.bag") and (study / LOGS / f"{code}.bag").read_bytes() == bag
    page = experimenter.get(f"/runs/{code}").text
    assert 'id="playing"' not in page and ("Duration", "15.5 s") in figures(page) and 'role="alert"' not in page


def test_a_log_that_cannot_be_played_is_reported_on_its_page_and_nothing_is_recorded(study, codes, experimenter):
    code = codes[0]
    finish(experimenter, code)
    before = events(study)
    assert upload(experimenter, code, MAGIC[".bag"] + b"\x00" * 64).status_code == 302  # a bag by its first bytes only
    state = played(experimenter, code)
    assert state["running"] is False and state["outcome"] == "" and state["error"].startswith(f"run {code}: its log could not be played: ")
    page = experimenter.get(f"/runs/{code}")
    assert alert(page) == state["error"] and 'id="attach"' in page.text  # it may be attached again
    assert events(study) == before and not (study / OUTCOMES).exists()


def test_a_corrected_log_replaces_the_earlier_which_is_kept_aside(study, codes, experimenter, stand_in):
    code = codes[0]
    finish(experimenter, code)
    first = MAGIC[".bag"] + b"the wrong part of the day"
    stand_in.go.set()
    assert upload(experimenter, code, first).status_code == 302
    assert played(experimenter, code)["outcome"] == "goal"
    add_run_log(study, code)
    assert 'id="correct"' in experimenter.get(f"/runs/{code}").text
    stand_in.duration = 9.0
    corrected = MAGIC[".mcap"] + b"the right part"
    assert upload(experimenter, code, corrected, "robot.mcap", replace="1", start="3").status_code == 302
    assert played(experimenter, code)["outcome"] == "goal"
    assert stand_in.calls[-1] == ([], [code], study / LOGS / f"{code}.mcap", 3.0, None)  # as `trials run --rerun CODE --from-log LOG`
    kept = study / SUPERSEDED / "2026-05-01T120000+0000"
    assert [o.duration_s for o in read_outcomes(kept / OUTCOMES)] == [15.5]
    assert [o.duration_s for o in read_outcomes(study / OUTCOMES)] == [9.0]
    assert (kept / LOGS / f"{code}.bag").read_bytes() == first and (kept / "runs" / f"{code}.mcap").exists()
    assert sorted(p.name for p in (study / LOGS).iterdir()) == [f"{code}.mcap"] and (study / LOGS / f"{code}.mcap").read_bytes() == corrected
    assert events(study)[-2:] == [(code, "note", f"log corrected: the earlier run log, outcome row and upload are kept in {SUPERSEDED}/{kept.name}/"),
                                  (code, "log", f"logs/{code}.mcap")]
    assert ("Duration", "9.0 s") in figures(experimenter.get(f"/runs/{code}").text)


def test_a_correction_that_fails_before_the_earlier_run_moves_keeps_everything_as_it_was(study, codes, experimenter, stand_in):
    code = codes[0]
    finish(experimenter, code)
    first = MAGIC[".bag"] + b"the log played"
    stand_in.go.set()
    assert upload(experimenter, code, first).status_code == 302
    played(experimenter, code)
    rows, before = (study / OUTCOMES).read_bytes(), events(study)
    stand_in.fail = "robot.bag: the log has no laser scans on /scan"
    assert upload(experimenter, code, MAGIC[".bag"] + b"another", replace="1").status_code == 302
    assert played(experimenter, code)["error"] == f"run {code}: its log could not be played: robot.bag: the log has no laser scans on /scan"
    assert (study / LOGS / f"{code}.bag").read_bytes() == first and sorted(p.name for p in (study / LOGS).iterdir()) == [f"{code}.bag"]
    assert (study / OUTCOMES).read_bytes() == rows and events(study) == before and not (study / SUPERSEDED).exists()
    assert alert(experimenter.get(f"/runs/{code}")).endswith("no laser scans on /scan")


# --- 6. the questionnaire opens when the run is finished -------------------------------------------------------------

def test_the_questionnaire_opens_once_the_run_is_finished_before_its_log(study, codes, experimenter):
    code = codes[0]
    link = f"/q/{console_access(StudyFolder(study)).participant_token(code)}"
    phone = app_of(study)[1].test_client()
    token = token_of(experimenter, code)
    assert experimenter.post(f"/runs/{code}/event", data={"event": "start", "csrf_token": token}).status_code == 302
    waiting = phone.get(link).text
    assert "The robot has not finished this run yet." in waiting and 'id="send"' not in waiting
    early = experimenter.post(link, data={"csrf_token": token, "participant": "P01", "compliant": "yes"})
    assert early.status_code == 400 and alert(early) == f"run {code} has not finished yet: its questionnaire opens once the robot has finished the run"
    assert not (study / RESPONSES).exists()
    assert experimenter.post(f"/runs/{code}/event", data={"event": "finish", "csrf_token": token}).status_code == 302
    assert "The questionnaire is open." in experimenter.get(f"/runs/{code}").text
    page = phone.get(link).text
    assert "The robot has finished this run. Answer the questions below about how it moved around the people, then press Send." in page
    assert phone.post(link, data={"participant": "P01", "compliant": "yes"}).status_code == 400  # no CSRF token: refused
    assert not (study / RESPONSES).exists()
    assert phone.post(link, data={"csrf_token": CSRF.search(page).group(1), "participant": "P01", "compliant": "yes", "comfort": "4"}).status_code == 302
    with (study / RESPONSES).open(newline="") as handle:
        assert [(r["run_code"], r["participant"], r["compliant"], r["comfort"]) for r in csv.DictReader(handle)] == [(code, "P01", "yes", "4")]
    assert not (study / OUTCOMES).exists()  # answered before the log was attached
    assert phone.get("/q/" + "f" * 24).status_code == 404
