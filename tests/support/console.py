"""A blinded field-day study for the console's tests and screenshots (with its runs' outcome rows, logs and
unblinding written through their owners when a test needs them at once), the console as a Flask test client,
`trials serve` as a process, and Debian's Chromium driven through Selenium."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from analysis.records import Blinding, Outcome
from tests.support.system_packages import need
from trials.atomic import write_files
from trials.cli import main
from trials.outcomes import Outcomes
from trials.run_log import RunLog
from trials.sim.robot import RobotState
from trials.study import UNBLINDING, StudyFolder
from trials.study_data import unblinding_record

#: Two runs, the controller blinded as arms A and B, and one Likert item.
SPEC = """
[study]
name = "field-day"
runs = 2
model = "main"
seed = 21

[[factors]]
name = "Pedestrians"
type = "fixed"
value = 2

[[factors]]
name = "Controller"
type = "categorical"
blind = true
levels = ["NaviGAN-R", "Lattice"]

[[questionnaire]]
name = "comfort"
question = "How comfortable did you feel near the robot?"
scale = 5
low = "very uncomfortable"
high = "very comfortable"
"""
#: The part of the sample bag a run plays: 6 s from 15 s in (people walk past the sensor then).
WINDOW = {"start": "15", "duration": "6"}
CHROMIUM, CHROMEDRIVER = Path("/usr/bin/chromium"), Path("/usr/bin/chromedriver")
#: A phone's window, for the participants' questionnaire.
PHONE = (390, 844)
CSRF = re.compile(r'name="csrf_token" value="([^"]+)"')


def design_study(folder: Path, spec: str = SPEC) -> Path:
    """`trials design` of `spec` into `folder`."""
    folder.parent.mkdir(parents=True, exist_ok=True)
    source = folder.parent / f"{folder.name}.toml"
    source.write_text(spec)
    assert main(["design", "--spec", str(source), "--study", str(folder)]) == 0
    return folder


def add_outcome(folder: Path, code: str, perception: str = "log", finished_utc: str = "2026-05-01T10:00:00+00:00", duration_s: float = 12.0,
                controller: str | None = None) -> None:
    """An outcome row for run `code` through outcomes.csv's owner, as if its log had been played (or, with perception
    `live`, as if it had been driven live); an open study's names its `controller`."""
    outcomes = Outcomes(StudyFolder(folder), blind=controller is None)
    outcomes.append(Outcome(run_code=code, status="goal", seed=7, perception=perception, duration_s=duration_s, time_to_goal_s=duration_s,
                            path_length_m=9.5, min_distance_m=0.8, time_within_0_5m_s=0.0, time_within_1_2m_s=1.2, collisions=0,
                            max_deceleration_mps2=0.4, max_jerk_mps3=1.0, path_irregularity_rad_per_m=0.1, turn_in_place_s=0.0,
                            backing_up_s=0.0, stopped_s=0.0, controller=controller, finished_utc=finished_utc))


def add_run_log(folder: Path, code: str, arm: str = "A") -> Path:
    """runs/<code>.mcap as a blinded logged trial leaves it (through the run-log writer): 8 s at 0.4 s steps, the robot
    driving 0.8 m/s along x towards (10, 0) while two people cross its path; it ends at the goal."""
    path = StudyFolder(folder).run_log(code)
    path.parent.mkdir(parents=True, exist_ok=True)
    metadata = {"run_code": code, "study": "field-day", "seed": "7", "perception": "log", "Pedestrians": "2", "Controller": arm,
                "log": "robot.bag", "goal_x": "10", "goal_y": "0"}
    with RunLog(path, metadata, (10.0, 0.0), None, blind=True) as log:
        log.event(0.0, "start", "log from 0.0 s, goal (10, 0) in frame laser")
        for k in range(21):
            t = 0.4 * k
            people = SimpleNamespace(ids=(1, 2), position=np.array([[4.0, 3.0 - 0.6 * t], [6.0, -3.0 + 0.6 * t]]),
                                     velocity=np.array([[0.0, -0.6], [0.0, 0.6]]))
            log.state(t, RobotState(2.0 + 0.8 * t, 0.0, 0.0, 0.8, 0.0), (0.8, 0.0), people)
        log.event(8.0, "goal", "0.40 m from the goal")
    return path


def unblind(folder: Path, when: str = "2026-05-01T16:30:00+00:00") -> None:
    """unblinding.json as `trials report --unblind` leaves it (through its owner), the key opened at `when`."""
    study = StudyFolder(folder)
    commitment = study.read_design()["blinding"]["commitment"]["digest"]
    record = unblinding_record(study, Blinding(True, "Controller", {}, True, commitment, (when,), "", "2 of 2 runs finished"))
    study.path(UNBLINDING).parent.mkdir(parents=True, exist_ok=True)
    write_files({study.path(UNBLINDING): record})


def need_chromium() -> None:
    """Skip, or in CI fail, a test that drives a browser when Debian's chromium and chromium-driver are not installed."""
    need(CHROMIUM.exists() and CHROMEDRIVER.exists(), "Chromium (Debian's chromium and chromium-driver)",
         "sudo apt-get install chromium chromium-driver")


@contextmanager
def browser(size: tuple[int, int] = (1280, 900)) -> Iterator:
    """A headless Chromium with a fresh profile (its own cookies: one person's browser), offline-minded flags."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    profile = tempfile.mkdtemp(prefix="console-browser-")
    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    for flag in ("--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-component-update",
                 "--disable-sync", "--no-first-run", "--hide-scrollbars", f"--user-data-dir={profile}", f"--window-size={size[0]},{size[1]}"):
        options.add_argument(flag)
    driver = webdriver.Chrome(options=options, service=Service(str(CHROMEDRIVER)))
    try:
        yield driver
    finally:
        driver.quit()
        shutil.rmtree(profile, ignore_errors=True)


@contextmanager
def served(study: Path, *options: str, env: dict[str, str] | None = None, printed: list[str] | None = None) -> Iterator[str]:
    """`trials serve` on the study at a free port, on loopback unless `options` say otherwise (with more `options`, in
    `env`); yields the experimenter's URL it prints first, and keeps the next two lines it prints in `printed`."""
    process = subprocess.Popen([sys.executable, "-m", "trials.cli", "serve", "--study", str(study), "--port", "0", *options],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        assert process.stdout is not None
        first = process.stdout.readline().strip()
        assert re.fullmatch(r"http://127\.0\.0\.1:\d+/\?token=[\w-]{32}", first), first + (process.stderr.read() if process.poll() is not None else "")
        if printed is not None:
            printed += [process.stdout.readline().strip() for _ in range(2)]
        yield first
    finally:
        process.terminate()  # a live run going is stopped first, which takes its own time
        try:
            process.wait(timeout=60)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()


def go(driver, by: str, value: str) -> None:
    """Click what opens or submits a page, and wait until the next page has replaced this one: a mark set
    on this page's window is gone once a new document has loaded. (Waiting for an old element to go
    stale races Chromium's inspector, which may answer that its node left the document.)"""
    from selenium.common.exceptions import WebDriverException
    from selenium.webdriver.support.ui import WebDriverWait

    driver.execute_script("window.leavingThisPage = true")
    driver.find_element(by, value).click()
    WebDriverWait(driver, 120, ignored_exceptions=(WebDriverException,)).until(
        lambda d: d.execute_script("return window.leavingThisPage === undefined && document.readyState === 'complete'"))


#: Seconds a log may take to be played in the background here: a worker process starts, loads both controllers and
#: tracks the people in the bag, on a loaded 2-core machine.
PLAY_DEADLINE_S = 300


def played(driver) -> None:
    """Wait until the run page has followed its log to the end (its script reloads it then) and shows the outcome with
    its picture drawn; fails with the page's error if the log could not be played."""
    from selenium.common.exceptions import WebDriverException
    from selenium.webdriver.support.ui import WebDriverWait

    def done(d) -> bool:
        state = d.execute_script("""
            if (document.readyState !== 'complete' || document.getElementById('playing')) { return 'playing'; }
            var alert = document.querySelector('[role=alert]');
            if (alert) { return alert.textContent; }
            var picture = document.getElementById('picture');
            return document.getElementById('outcome') && (!picture || (picture.complete && picture.naturalWidth > 0)) ? 'done' : 'playing';""")
        assert state in ("playing", "done"), state
        return state == "done"

    WebDriverWait(driver, PLAY_DEADLINE_S, poll_frequency=0.5, ignored_exceptions=(WebDriverException,)).until(done)


def field_day(experimenter_url: str, study: Path, log: Path, shots: Path | None = None) -> list[str]:
    """Work through the study in real browsers as its field day would: the experimenter starts, finishes and
    attaches the log of each run (run 1 by upload, run 2 by its path; each is played in the background while its
    page follows it), an evaluator scores both, three
    participants, each in their own browser, answer both runs' questionnaires (P01 and P02 say yes to
    the first run, P03 no; all no to the second). Returns the source of every page seen; with `shots`,
    saves screenshots of the main pages there."""
    from selenium.webdriver.common.by import By

    pages: list[str] = []

    def seen(driver, name: str | None = None) -> None:
        pages.append(driver.title + "\n" + driver.current_url + "\n" + driver.page_source)
        if shots is not None and name is not None:
            width, height = driver.get_window_size()["width"], driver.get_window_size()["height"]
            content = driver.execute_script("return document.documentElement.scrollHeight")
            driver.set_window_size(width, content + height - driver.execute_script("return window.innerHeight"))
            driver.save_screenshot(str(shots / f"{name}.png"))
            driver.set_window_size(width, height)

    links = []
    with browser() as experimenter:
        experimenter.get(experimenter_url)
        seen(experimenter)
        codes = [row.get_attribute("id").removeprefix("run-") for row in experimenter.find_elements(By.CSS_SELECTOR, "table.sheet tbody tr")]
        for i, code in enumerate(codes):
            go(experimenter, By.CSS_SELECTOR, f"#run-{code} a")
            go(experimenter, By.ID, "start")
            experimenter.find_element(By.ID, "note").send_keys(f"run {i + 1}: two people walked past")
            go(experimenter, By.ID, "add-note")
            go(experimenter, By.ID, "finish")
            if i == 0:
                experimenter.find_element(By.ID, "log-file").send_keys(str(log))
            else:
                experimenter.find_element(By.ID, "log-path").send_keys(str(log))
            experimenter.find_element(By.ID, "log-start").send_keys(WINDOW["start"])
            experimenter.find_element(By.ID, "log-duration").send_keys(WINDOW["duration"])
            go(experimenter, By.ID, "attach")
            seen(experimenter)  # the log being checked and played
            played(experimenter)
            seen(experimenter, "run_page" if i == 0 else None)
            links.append(experimenter.find_element(By.ID, "participant-link").get_attribute("href"))
            go(experimenter, By.ID, "score-link")
            experimenter.find_element(By.CSS_SELECTOR, f"input[name=score][value='{3 - i}']").click()
            scorer = experimenter.find_element(By.ID, "scorer")
            assert scorer.get_attribute("value") == ("" if i == 0 else "evaluator-1")  # remembered from the first score
            scorer.clear()
            scorer.send_keys("evaluator-1")
            seen(experimenter, "score_form" if i == 0 else None)
            go(experimenter, By.ID, "record-score")
            go(experimenter, By.LINK_TEXT, "Run sheet")
            seen(experimenter)
        for participant, answers in (("P01", ("yes", "no")), ("P02", ("yes", "no")), ("P03", ("no", "no"))):
            with browser(PHONE) as phone:
                for k, (link, answer) in enumerate(zip(links, answers)):
                    phone.get(link)
                    if k == 0:
                        phone.find_element(By.ID, "participant").send_keys(participant)
                    phone.find_element(By.ID, f"compliant-{answer}").click()
                    phone.find_element(By.ID, "comfort-4").click()
                    seen(phone, "questionnaire_phone" if participant == "P01" and k == 0 else None)
                    go(phone, By.ID, "send")
                    seen(phone)
        experimenter.get(experimenter_url.split("?")[0])
        seen(experimenter, "run_sheet")
        go(experimenter, By.LINK_TEXT, "Progress")
        seen(experimenter, "progress")
    return pages
