"""The console's pages (Flask, server-rendered Jinja2 templates, one CSS file of its own; no scripts,
fonts or styles from elsewhere, so it works offline).

Experimenter pages (run sheet, run page, score form, progress) need the experimenter's token once
(`/?token=...`, kept in the signed session cookie); a participant's questionnaire link opens only its
run's form, and the participant's code, entered once, stays in their cookie. Every form carries a
CSRF token (Flask-WTF). Nothing from the study folder is served: pages are rendered from it, and a
run's picture is drawn from its log. Every experimenter page says whether the study is blinded or when
it was unblinded; times are shown in the laptop's local time with its zone (the `local` filter).

A log attached to a run is played in the background; in a study driven live, a run page's Start starts
the live run. A small script of the console's own (static/run.js) follows either through
`/runs/<code>/log` or `/runs/<code>/live`, and every experimenter page shows E-STOP while a run is live.
"""

from __future__ import annotations

import math
import shlex
from typing import Any

import segno
from flask import Flask, abort, flash, jsonify, redirect, render_template, request, session, url_for
from flask_wtf.csrf import CSRFError, CSRFProtect
from markupsafe import Markup
from werkzeug.exceptions import HTTPException
from werkzeug.wrappers import Response as HttpResponse

from trials.attached_logs import MAX_UPLOAD_BYTES
from trials.console.access import ConsoleAccess
from trials.console.actions import Console, LogRequest, UnknownRun
from trials.console.address import LOOPBACK, NETWORK_OPTION, Reach, url_host
from trials.console.pictures import PAGE_DPI, RunPictures
from trials.console.progress import progress
from trials.console.sheet import SheetRow, study_key
from trials.console.times import local_time
from trials.errors import USER_ERRORS
from trials.numbers import finite_number
from trials.run_events import ABORT, ABORTED, EVENTS
from trials.staging_figure import staging_figure
from trials.study import LIVE_ESTOP

#: Field names of the participant's code and compliance answer.
PARTICIPANT, COMPLIANT = "participant", "compliant"
#: What a form's bad value raises: a field's ValueError, or a user error from the owning module.
FORM_ERRORS = (ValueError, *USER_ERRORS)


def create_app(console: Console, access: ConsoleAccess, reach: Reach = LOOPBACK) -> Flask:
    """The console's WSGI app for one study folder, served as `reach` says (the address phones' links carry)."""
    app = Flask(__name__)
    app.config.update(SECRET_KEY=access.secret_key, MAX_CONTENT_LENGTH=MAX_UPLOAD_BYTES, WTF_CSRF_TIME_LIMIT=None,
                      SESSION_COOKIE_SAMESITE="Lax", SESSION_COOKIE_NAME="trials_console")
    app.add_template_filter(local_time, "local")
    CSRFProtect(app)
    pictures = RunPictures(console.folder)

    def experimenter() -> None:
        if not session.get("experimenter"):
            abort(403, "this page needs the experimenter's link: the first line `trials serve` printed (http://...?token=...)")

    def fail(message: str, status: int, template: str = "message.html", **context: Any) -> tuple[str, int]:
        return render_template(template, error=message, title=context.pop("title", "Not done"), **context), status

    @app.errorhandler(CSRFError)
    def csrf_failed(error: CSRFError) -> tuple[str, int]:
        return fail("the form was not sent from this console's own page (or the page is too old): reload the page and send it again", 400)

    @app.errorhandler(HTTPException)
    def http_failed(error: HTTPException) -> tuple[str, int]:
        if error.code == 413:
            return fail(f"the upload is larger than the {MAX_UPLOAD_BYTES // 2**20} MiB a log may have", 413)
        return fail(error.description or error.name, error.code or 500)

    @app.errorhandler(UnknownRun)
    def unknown_run(error: UnknownRun) -> tuple[str, int]:
        return fail(str(error), 404)

    def unreadable(error: Exception) -> tuple[str, int]:
        """A study file (or a run's log) that cannot be read: the page says which, and what is wrong with it."""
        return fail(f"the study's files cannot be shown: {error}", 500)

    for kind in USER_ERRORS:
        app.register_error_handler(kind, unreadable)

    @app.context_processor
    def live_now() -> dict[str, Any]:
        """The run E-STOP stops: this console's live run, else one live.json says is under way (started elsewhere)."""
        if not session.get("experimenter"):
            return {}
        running = console.live.running
        return {"live_now": running, "estop_run": running or console.live.elsewhere()}

    @app.context_processor
    def blinding() -> dict[str, Any]:
        """The study's name and key state for every experimenter page's header (blinded, or unblinded and when)."""
        if not session.get("experimenter"):
            return {}
        try:
            return {"study_key": study_key(console.folder)}
        except USER_ERRORS as exc:  # shown in the header: a page must still render to say what is wrong
            return {"study_key_error": str(exc)}

    @app.get("/")
    def sheet() -> str | HttpResponse:
        token = request.args.get("token")
        if token is not None:
            if not access.is_experimenter(token):
                abort(403, "this experimenter link's token is not this study's")
            session["experimenter"] = True
            return redirect(url_for("sheet"))
        experimenter()
        return render_template("sheet.html", sheet=console.sheet(), title="Run sheet", staging=console.live.uri is not None)

    @app.get("/staging")
    def staging_sheet() -> str | tuple[str, int]:
        """Every run's staging, in plan order, to print: where the robot starts and goes, and each walker's part."""
        experimenter()
        sheet = console.sheet()
        try:
            scenes = [console.staging(code) for code in sheet.codes]
        except USER_ERRORS as exc:
            return fail(f"the runs cannot be staged: {exc}", 409)
        if not any(scenes):
            abort(404, "this study is not driven live: it has no staging")
        return render_template("staging.html", sheet=sheet, scenes=scenes, title="Staging sheet")

    @app.get("/runs/<code>/staging.png")
    def staging_picture(code: str) -> HttpResponse:
        """Run `code`'s scene as the operator stages it (`trials.staging_figure`)."""
        experimenter()
        console.run(code)
        scene = console.staging(code)
        if scene is None:
            abort(404, "this study is not driven live: it has no staging")
        return HttpResponse(staging_figure(scene).png(PAGE_DPI), mimetype="image/png", headers={"Cache-Control": "no-store"})

    @app.get("/runs/<code>")
    def run_page(code: str) -> str:
        experimenter()
        return _run_page(code, 200)[0]

    def _run_page(code: str, status: int, error: str = "") -> tuple[str, int]:
        sheet, row = console.run(code)
        link = participant_link(code)
        qr = Markup(segno.make(link, error="m").svg_inline(scale=4))
        live = console.live.state(code)
        playing = console.playing(code)
        if not error and playing is not None and playing.error:
            error = playing.error  # the latest log played for this run, in the background, failed
        serve = f"trials serve --study {shlex.quote(str(console.folder.root))} {NETWORK_OPTION}"
        try:
            staging, staging_error = console.staging(code), ""
        except USER_ERRORS as exc:
            staging, staging_error = None, str(exc)
        return render_template("run.html", sheet=sheet, row=row, link=link, qr=qr, error=error, title=f"Run {code}",
                               live_uri=console.live.uri, live=live, shown=_shown(row, live), playing=playing,
                               busy=console.playing_now(), picture=row.outcome and console.folder.run_log(code).exists(),
                               reach=reach, serve=serve, staging=staging, staging_error=staging_error), status

    def participant_link(code: str) -> str:
        """Run `code`'s questionnaire link: at this laptop's network address when phones reach it there, else at the
        address the experimenter's browser used."""
        token = access.participant_token(code)
        if reach.host is None:
            return url_for("questionnaire", token=token, _external=True)
        port = request.environ.get("SERVER_PORT", "")
        return f"{request.scheme}://{url_host(reach.host)}{'' if port in ('', '80') else ':' + port}{url_for('questionnaire', token=token)}"

    @app.post("/runs/<code>/live")
    def live_start(code: str) -> tuple[str, int] | HttpResponse:
        experimenter()
        try:
            console.start_live(code)
        except USER_ERRORS as exc:
            return _run_page(code, 400, str(exc))
        flash(f"Run {code}: started live on {console.live.uri}.")
        return redirect(url_for("run_page", code=code))

    @app.get("/runs/<code>/live")
    def live_state(code: str) -> HttpResponse:
        experimenter()
        console.run(code)
        state = console.live.state(code)
        return jsonify({**state, "since": local_time(state["since_utc"])} if "since_utc" in state else state)

    @app.post("/estop")
    def estop() -> HttpResponse:
        experimenter()
        stopped = console.live.estop()
        if stopped is not None:
            flash(f"E-STOP: run {stopped} was told to stop the robot now ({LIVE_ESTOP} created, `trials run` sent SIGTERM).")
        else:
            flash(f"E-STOP: {LIVE_ESTOP} created, which stops a live run of this study started elsewhere; none was going from this console.")
        code = stopped or request.form.get("code", "")
        return redirect(url_for("run_page", code=code) if code in console.sheet().codes else url_for("sheet"))

    @app.post("/runs/<code>/event")
    def run_event(code: str) -> tuple[str, int] | HttpResponse:
        experimenter()
        event = request.form.get("event", "")
        if event not in EVENTS:
            return _run_page(code, 400, f"unknown action {event!r}")
        try:
            console.record_event(code, event, request.form.get("detail", ""))
        except USER_ERRORS as exc:
            return _run_page(code, 400, str(exc))
        flash(f"Run {code}: {event} recorded.")
        return redirect(url_for("run_page", code=code))

    @app.post("/runs/<code>/log")
    def attach_log(code: str) -> tuple[str, int] | HttpResponse:
        experimenter()
        upload = request.files.get("log")
        replace = request.form.get("replace") == "1"
        try:
            goal = (_number(request.form, "goal_x"), _number(request.form, "goal_y"))
            if (goal[0] is None) != (goal[1] is None):
                raise ValueError("give both goal x and goal y, or neither")
            start = _number(request.form, "start") or 0.0
            duration = _number(request.form, "duration")
            if start < 0 or (duration is not None and duration <= 0):
                raise ValueError("start must be 0 or more seconds, and duration more than 0")
            name = upload.filename or "" if upload is not None else ""
            log = LogRequest(name, upload.read() if upload is not None and name else b"", request.form.get("path", ""),
                             (goal[0], goal[1]) if goal[0] is not None and goal[1] is not None else None, start, duration)
            playing = console.attach_log(code, log, replace)
        except FORM_ERRORS as exc:
            return _run_page(code, 400, str(exc))
        which = "the corrected" if replace else "its"
        flash(f"Run {code}: {which} log {playing.log} is being checked and played; this page shows the outcome when it is done.")
        return redirect(url_for("run_page", code=code))

    @app.get("/runs/<code>/log")
    def log_state(code: str) -> HttpResponse:
        """Whether run `code`'s log is still being played (the run page asks every second while it is)."""
        experimenter()
        console.run(code)
        playing = console.playing(code)
        if playing is None:
            return jsonify({"run_code": code, "running": False})
        return jsonify({"run_code": code, "running": playing.running, "log": playing.log, "since": local_time(playing.since_utc),
                        "outcome": playing.outcome, "error": playing.error})

    @app.get("/runs/<code>/picture.png")
    def picture(code: str) -> HttpResponse:
        """The run's picture from its log, as `trials log show` draws it: its path, the people tracked, the goal."""
        experimenter()
        console.run(code)
        png = pictures.png(code)
        if png is None:
            abort(404, f"run {code} has no log yet, so no picture")
        return HttpResponse(png, mimetype="image/png", headers={"Cache-Control": "no-store"})

    @app.route("/runs/<code>/score", methods=["GET", "POST"])
    def score(code: str) -> tuple[str, int] | HttpResponse:
        experimenter()
        _, row = console.run(code)
        if request.method == "GET":
            return render_template("score.html", row=row, title=f"Score run {code}", form={}), 200
        form = request.form
        session["scorer"] = form.get("scorer", "").strip()
        try:
            console.score(code, form.get("score", ""), form.get("scorer", ""), form.get("note", ""))
        except USER_ERRORS as exc:
            return render_template("score.html", row=row, title=f"Score run {code}", error=str(exc), form=form), 400
        flash(f"Run {code}: score {form['score']} by {form['scorer'].strip()} recorded.")
        return redirect(url_for("run_page", code=code))

    @app.get("/progress")
    def progress_page() -> str:
        experimenter()
        sheet = console.sheet()
        return render_template("progress.html", sheet=sheet, progress=progress(console.folder, sheet), title="Progress", percent=_percent,
                               points=_points)

    @app.route("/q/<token>", methods=["GET", "POST"])
    def questionnaire(token: str) -> tuple[str, int] | HttpResponse:
        sheet = console.sheet()
        code = access.run_of(token, sheet.codes)
        if code is None:
            abort(404, "this questionnaire link is not valid; ask the experimenter for the run's link")
        row = sheet.row(code)
        participant = session.get(PARTICIPANT, "")
        context = {"row": row, "sheet": sheet, "participant": participant, "title": "Questionnaire", "form": request.form,
                   "answered": bool(participant) and console.answered(code, participant)}
        if request.method == "GET":
            return render_template("questionnaire.html", change="change" in request.args, **context), 200
        participant = request.form.get(PARTICIPANT, participant).strip()
        ratings = {item.name: request.form.get(item.name, "") for item in sheet.questionnaire}
        try:
            console.respond(code, participant, request.form.get(COMPLIANT, ""), ratings)
        except USER_ERRORS as exc:
            return render_template("questionnaire.html", error=str(exc), change=not participant, **context), 400
        session[PARTICIPANT] = participant
        flash("Thank you: your answer is recorded.")
        return redirect(url_for("questionnaire", token=token))

    return app


def _shown(row: SheetRow, live: dict[str, Any]) -> tuple[str, str]:
    """The state and detail a run page shows: its live state, else (runs/live.json has moved on to another run) its
    outcome, or that it was aborted and why, or that it has not started."""
    if "state" in live:
        return str(live["state"]), str(live.get("detail", ""))
    aborted = row.latest(ABORT) if row.status == ABORTED else None
    return (row.outcome, "") if row.outcome else (ABORTED, aborted.detail) if aborted else ("not started", "")


def _number(form: Any, name: str) -> float | None:
    """An optional finite number from a form field (None when blank); ValueError naming the field otherwise."""
    text = form.get(name, "").strip()
    return finite_number(text, name) if text else None


def _percent(share: float) -> str:
    return "-" if math.isnan(share) else f"{100 * share:.0f}%"


def _points(difference: float) -> str:
    return "-" if math.isnan(difference) else f"{100 * difference:+.0f} points"
