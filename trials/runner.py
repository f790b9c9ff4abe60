"""`trials run`'s engine: pending plan rows to simulated or logged runs, in worker processes, resumable and blind.

The parent process checks the plan, decides which rows are pending (a row of outcomes.csv marks a
finished run), starts the workers and appends each finished run's outcome row. The workers build
their controllers once, and in a blinded study only they open the sealed key, to map a row's arm
label to its controller; the parent never learns the mapping, and nothing public names it. A row
that plays a robot log (`--from-log`, or the plan's `Log` column) has its log read and tracked by
the parent before any run starts (once per log), and is played open loop (`trials.log_trial`).

Order of writes for one run, so an interruption anywhere loses and duplicates nothing: the MCAP
is written under a hidden partial name; the sealed record (blinded studies, `trials.sealed_runs`)
is written; the MCAP is renamed into place; the outcome row is appended (outcomes.csv rewritten
through a temporary name). A run without a row is pending and runs again (with the same seed);
partial files of interrupted runs are deleted when the next `trials run` starts. In a blinded
study every public file a run writes, and its folder, gets its modification time rounded down to
the minute, as `finished_utc` is. A run that fails leaves runs/<code>.failed.txt (its one-line
reason; removed when the run later finishes), so `trials status` can tell failed from pending runs.

With a robot (`trials run --robot`, `trials.robot`), one worker drives each row live: it opens the sealed key and
its node on the robot's middleware once, and is stopped by SIGTERM (Ctrl-C, kill, or its parent dying) with time to
stop the robot and keep the run's log; a run aborted so keeps its log in runs/aborted/ and stays pending.

Every run records the settings it was made with (`trials.run_settings`); runs are not mixed with
finished runs made with other settings unless the command says so (`settings_differ`). A full disk
(`DiskFullError`, in the parent or a worker) stops the command at its first failed write, since
every later run would fail alike; the partial files are deleted as it stops.
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from analysis.records import Outcome, RunMetrics
from trials.atomic import no_space, open_lock, write_files, write_text, writing
from trials.controllers import registry
from trials.controllers.base import Controller
from trials.controllers.checked import OFFLINE_PLAN_LIMIT_S
from trials.controllers.nav_stack import is_nav_stack
from trials.controllers.plugins import study_controllers
from trials.errors import USER_ERRORS, DiskFullError, EStopped, RunAborted, StudyError
from trials.field_study import refuse_simulation
from trials.live_checks import ABORTED as RUN_ABORTED
from trials.log_trial import LOG_COLUMN, LoggedScene, ReplayOptions, log_of, play, prepare
from trials.metrics import measure
from trials.outcomes import Outcomes, outcome_cells, outcomes_text, read_outcomes
from trials.pool import Failure, PoolError, WorkerPool
from trials.robot.one_driver import new_session
from trials.robot.settings import RobotSettings
from trials.run_log import RunLog, jsonable
from trials.run_settings import LIVE, LOGGED, PERCEPTIONS, RunSettings, differences
from trials.scenario import CONTROLLER, DEFAULTS, PEDESTRIANS, settings_from_row
from trials.sealed_runs import SEALED_RUN_FORMAT, write_sealed
from trials.sim.perception import PositionNoise
from trials.study import (
    DESIGN,
    OUTCOMES,
    PLAN,
    RESPONSES,
    RUN_LOCK,
    RUNS,
    SEALED,
    SEALED_RUNS,
    SPEC,
    SUPERSEDED,
    StudyFolder,
    minute_ns,
    private_folder,
    to_the_minute,
    utc_now,
)

#: Seconds a live run's worker has to stop the robot and keep its log after SIGTERM, before it is killed.
LIVE_GRACE_S = 10.0
#: Header stamps from 2000-01-01 on are real times (a log's recording), kept in its run's log; earlier ones count from 0.
REAL_TIME_NS = 946_684_800 * 1_000_000_000
#: Run seeds stay below 2^53, so that a spreadsheet, R or JMP (which read numbers as doubles) keeps them exact.
SEED_BITS = 53

if TYPE_CHECKING:
    from trials.robot.guard import Guard
    from trials.robot.live_log import LiveLog
    from trials.scenario import Scenario
    from trials.sim.closed_loop import SimConfig
    from trials.sim.perception import Perception



@dataclass(frozen=True)
class RunOptions:
    """How runs are simulated (perception, noise, timeout, NaviGAN-R's weights) or played from logs, and
    whether they may be mixed with finished runs made with other settings."""

    settings: RunSettings = RunSettings()
    replay: ReplayOptions = ReplayOptions()
    settings_differ: bool = False
    #: Stamp logs with the wall-clock start (blinded runs: to the minute) instead of from 1970-01-01.
    wall_clock: bool = False
    #: Drive every run live on this robot (`trials run --robot`) instead of simulating or playing logs.
    robot: RobotSettings | None = None
    #: Simulate rows even in a field study (`trials.field_study`).
    allow_simulated: bool = False
    #: The tag the nodes of this `trials run` session share on the robot (`trials.robot.one_driver`).
    robot_session: str = ""

    @property
    def noise(self) -> PositionNoise:
        return PositionNoise(self.settings.noise_std_m, self.settings.dropout)


@dataclass(frozen=True)
class RunTask:
    """One plan row to run: its code, the plan's columns (arm label when blind), its seed, and the
    prepared log when the row plays one."""

    code: str
    row: dict[str, str]
    seed: int
    scene: LoggedScene | None = None


@dataclass(frozen=True)
class RunDone:
    """A finished run as the parent sees it: its public outcome (no controller when blind), whether it
    played a log, and a logged trial's `replay` summary (none when blind: it figures the plans)."""

    code: str
    outcome: Outcome
    logged: bool = False
    replay: dict[str, str] = field(default_factory=dict)
    live: bool = False

    @property
    def row(self) -> dict[str, str]:
        """The outcome's cells as outcomes.csv holds them."""
        return outcome_cells(self.outcome)


@dataclass
class Summary:
    """What one `trials run` did."""

    finished: list[RunDone] = field(default_factory=list)
    failed: list[tuple[str, str]] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    superseded: Path | None = None
    done: int = 0
    #: The pid a stale runs/.lock recorded (a `trials run` that was killed), when one was taken over.
    stale_lock: str | None = None
    #: A live run was e-stopped: the session ended there, the later rows pending.
    estopped: bool = False


def run_seed(study_seed: int, code: str) -> int:
    """The seed of run `code`: a 53-bit hash of the study's seed and the run code (exact as a double).

    Studies run before seeds were shortened recorded 63-bit seeds; their reruns take the seed recorded
    in outcomes.csv (`StudyRun.task`), so every recorded run still reproduces.
    """
    digest = hashlib.sha256(f"navtrials-run:{study_seed}:{code}".encode()).digest()
    return int.from_bytes(digest[:8], "big") >> (64 - SEED_BITS)


def utc_stamp(blind: bool) -> str:
    """Now as ISO 8601 UTC; to the minute in a blinded study, whose run times differ by controller."""
    return utc_now(to_the_minute=blind)


# --- the parent: what to run ---------------------------------------------------------------------

@dataclass(frozen=True)
class StudyRun:
    """A checked study folder, ready to run: its plan, blinding and the controller levels it names."""

    folder: StudyFolder
    name: str
    seed: int
    blind: bool
    plan: list[dict[str, str]]
    levels: tuple[str, ...]

    @classmethod
    def open(cls, folder: StudyFolder, blind_flag: bool, from_log: bool = False) -> StudyRun:
        """Check the plan row by row (factor values the simulator can run, known controllers or arms);
        rows that play a log (all of them with `from_log`) may have factors the simulator does not know.

        Raises:
            StudyError: no plan, `--blind` on an open study, a row it cannot run, or a damaged outcomes.csv.
        """
        design = folder.read_design()
        blinding = design.get("blinding")
        if blind_flag and not blinding:
            raise StudyError(f"--blind: the study in {folder.root} is not blinded (design.json has no sealed allocation); run it without --blind")
        plan = folder.read_plan()
        arms = tuple(blinding["arms"]) if blinding else registry.names(study_controllers(folder, blind=False))
        for line, row in enumerate(plan, start=2):
            where = f"{folder.path(PLAN)} line {line} (run {row.get('run_code', '?')})"
            if not (from_log or (row.get(LOG_COLUMN) or "").strip()):
                settings_from_row({k: v for k, v in row.items() if k != LOG_COLUMN}, where)
            level = row.get(CONTROLLER)
            if level is not None and level not in arms:
                kind = "arm" if blinding else "controller"
                raise StudyError(f"{where}: {CONTROLLER} {level!r} is not a known {kind} ({', '.join(arms)})")
        read_outcomes(folder.path(OUTCOMES), bool(blinding))  # a damaged file is refused before the lock is written
        seed = design.get("seed")
        if not isinstance(seed, int):
            raise StudyError(f"{folder.path(DESIGN)}: no integer study seed to derive the run seeds from")
        levels = () if blinding else tuple(dict.fromkeys(row.get(CONTROLLER, registry.DEFAULT) for row in plan))
        return cls(folder, str(design.get("study", "")), seed, bool(blinding), plan, levels)

    @property
    def codes(self) -> list[str]:
        return [row["run_code"] for row in self.plan]

    def task(self, code: str, recorded_seed: int | None = None) -> RunTask:
        """Row `code` to run, with the seed its finished run recorded (a rerun) or its derived one."""
        row = next(r for r in self.plan if r["run_code"] == code)
        return RunTask(code, dict(row), run_seed(self.seed, code) if recorded_seed is None else recorded_seed)


@dataclass(frozen=True)
class LockState:
    """runs/.lock as found: absent, held by a running `trials run` (its pid), or stale (left by a
    `trials run` that was killed, with the pid it recorded)."""

    held: bool
    stale: bool
    pid: str


def lock_state(folder: StudyFolder) -> LockState:
    """Whether runs/.lock is there, and held or stale; tries the lock without taking it for long."""
    lock = folder.path(RUN_LOCK)
    try:
        handle = open_lock(lock, "r")
    except FileNotFoundError:
        return LockState(False, False, "")
    with handle:
        pid = handle.read().strip() or "?"
        try:
            fcntl.flock(handle, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return LockState(True, False, pid)
        fcntl.flock(handle, fcntl.LOCK_UN)
    return LockState(False, True, pid)


@contextmanager
def study_lock(folder: StudyFolder) -> Iterator[LockState]:
    """Hold the study's run lock (one `trials run` per study at a time); yields what was found before
    (a stale lock of a killed run is taken over). The lock file is removed when the block is left."""
    lock = folder.path(RUN_LOCK)
    lock.parent.mkdir(parents=True, exist_ok=True)
    found = lock_state(folder)
    while True:
        handle = open_lock(lock, "a+")
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            handle.seek(0)
            pid = handle.read().strip() or "?"
            handle.close()
            raise StudyError(f"another `trials run` is running on {folder.root} (pid {pid}); wait for it or stop it") from None
        # Another run may have removed the file between our open and our lock: then lock the new one.
        if lock.exists() and os.path.samestat(os.fstat(handle.fileno()), lock.stat()):
            break
        handle.close()
    try:
        with writing(lock):
            handle.seek(0)
            handle.truncate()
            handle.write(str(os.getpid()))
            handle.flush()
        yield found
    finally:
        lock.unlink(missing_ok=True)
        with suppress(OSError):  # a pid that could not be flushed fails again here; the error above is the one to tell
            handle.close()


def clean_partials(folder: StudyFolder) -> list[Path]:
    """Delete what interrupted runs left half-written (hidden `.…partial` and `.…tmp` files in runs/
    and sealed/runs/, and staged copies of outcomes.csv and responses.csv); returns them."""
    stale = [p for name in (OUTCOMES, RESPONSES) for p in folder.root.glob(f".{name}.*.tmp") if p.is_file()]
    for where in (folder.path(RUNS), folder.path(SEALED_RUNS)):
        if where.is_dir():
            stale += [p for p in where.glob(".*") if p.is_file() and p.name.endswith((".partial", ".tmp"))]
    for path in stale:
        path.unlink(missing_ok=True)
    return stale


def supersede_runs(folder: StudyFolder, outcomes: Outcomes, codes: list[str], stamp: str) -> Path:
    """Move finished runs aside for --rerun: their rows, logs (and PNGs) to superseded/<stamp>/, their
    sealed records to sealed/superseded/<stamp>/. Copies are made before the rows are removed, so an
    interruption never loses a run."""
    target = folder.path(SUPERSEDED) / stamp
    secret = folder.path(SEALED) / SUPERSEDED / stamp
    moved = [row for row in outcomes.rows if row.run_code in codes]
    old = target / OUTCOMES
    files: dict[Path, bytes] = {old: outcomes_text(read_outcomes(old, outcomes.blind) + moved, outcomes.blind).encode()}
    originals, private = [], set()
    for code in codes:
        for source, base in ((folder.run_log(code), target / RUNS), *((figure, target / RUNS) for figure in folder.run_figures(code)),
                             (folder.sealed_run(code), secret / RUNS), (folder.older_sealed_run(code), secret / RUNS)):
            if source.exists():
                files[base / source.name] = source.read_bytes()
                originals.append(source)
                if base != target / RUNS:
                    private.add(base / source.name)
    try:
        if private:
            private_folder(folder, secret / RUNS)
        write_files(files, private)
        outcomes.remove(codes)
    except BaseException:  # the runs are still in place: copies left aside would pass for superseded runs
        for copy in files:
            copy.unlink(missing_ok=True)
        for made in (target / RUNS, target, secret / RUNS, secret):
            with suppress(OSError):
                made.rmdir()  # only when empty
        raise
    for source in originals:
        source.unlink()
    return target


def run_study(study: StudyRun, workers: int, only: list[str], rerun: list[str], options: RunOptions,
              on_start: Callable[[int], None], on_done: Callable[[RunDone], None],
              on_failed: Callable[[str, str], None], between: Callable[[str], bool] = lambda code: True,
              on_end: Callable[[], None] = lambda: None) -> Summary:
    """Run the pending rows (or the `only` / `rerun` ones) with `workers` processes.

    `on_start(n)` is called once the workers are ready and n runs are about to start;
    `on_done` / `on_failed` after each run; `on_end()` once the runs have ended however (none to run, an interruption),
    still holding the study's lock. Rows driven live go one at a time, and before each `between(code)` is asked
    whether to go on (the operator stages the row; False ends the command, the rest pending).
    Ctrl-C (KeyboardInterrupt) stops the workers at once; finished runs are kept.

    Raises:
        StudyError: unknown codes, a --rerun of an unfinished run, outcomes.csv of another study
            kind, runs to be made with other settings than the finished ones (without
            `options.settings_differ`), a broken sealed key, unreadable weights or a controller
            that cannot be built.
    """
    folder = study.folder
    if workers < 1:
        raise StudyError(f"--workers must be at least 1, got {workers}")
    if options.settings.perception not in PERCEPTIONS:
        raise StudyError(f"--perception must be one of {', '.join(PERCEPTIONS)}, got {options.settings.perception!r}")
    unknown = [code for code in only + rerun if code not in study.codes]
    if unknown:
        raise StudyError(f"run {unknown[0]} is not in {folder.path(PLAN)}")
    summary = Summary()
    with study_lock(folder) as found, _finally(on_end):
        summary.stale_lock = found.pid if found.stale else None
        clean_partials(folder)
        outcomes = Outcomes(folder, study.blind)
        finished = outcomes.finished
        unfinished = [code for code in rerun if code not in finished]
        if unfinished:
            raise StudyError(f"--rerun {unfinished[0]}: the run has not finished yet; `trials run --only {unfinished[0]}` runs it")
        wanted = [c for c in study.codes if c in set(only) | set(rerun)] if only or rerun else study.codes
        summary.skipped = [c for c in wanted if c in finished and c not in rerun]
        todo = [c for c in wanted if c not in finished or c in rerun]
        summary.done = len(finished & set(study.codes))
        if not todo:
            return summary
        simulated = [c for c in todo if options.robot is None and log_of(study.task(c).row, folder.root, options.replay) is None]
        if simulated and not options.allow_simulated:
            refuse_simulation(folder, study.blind, f"simulate run {simulated[0]}")
        if simulated and not options.settings_differ:
            _same_settings(outcomes, set(rerun), options.settings, folder.path(SPEC))
        recorded = {row.run_code: row.seed for row in outcomes.rows}
        chosen = [study.task(code, recorded.get(code) if code in rerun else None) for code in todo]
        tasks = chosen if options.robot is not None else with_scenes(chosen, folder.root, options.replay)
        # One robot, one run at a time; a live worker is told to stop by SIGTERM and given time to stop the robot, and the
        # parent's guard stops the robot itself if that worker dies.
        live = options.robot is not None
        if options.robot is not None:
            options = replace(options, robot_session=new_session())
        guard = _guard(folder, options.robot, study.blind, options.robot_session) if options.robot is not None else None
        answered: set[str] = set()

        def worker_died(why: str) -> None:
            if guard is None:
                return
            code = next((task.code for task in tasks if task.code not in answered), None)
            message = guard.worker_died(code, why)
            if code is not None and message is not None:
                summary.failed.append((code, message))
                _record_failure(folder, code, message, study.blind)
                on_failed(code, message)

        try:
            setup = (str(folder.root), study.name, study.blind, study.levels, options)
            with WorkerPool(1 if live else min(workers, len(todo)), setup_worker, setup, USER_ERRORS,
                            graceful=LIVE_GRACE_S if live else None) as pool:
                try:
                    pool.ready()
                except PoolError as exc:
                    if exc.failure is None or not exc.failure.user_error:
                        raise RuntimeError(f"a worker could not start: {exc}\n{exc.failure.details if exc.failure else ''}") from None
                    raise StudyError(exc.failure.message.splitlines()[0]) from None
                if rerun:
                    summary.superseded = supersede_runs(folder, outcomes, rerun, folder.aside_stamp())
                on_start(len(todo))
                # Live rows go one at a time, the operator asked before each (to stage it).
                for batch in [[task] for task in tasks] if live else [tasks]:
                    if summary.estopped or live and not between(batch[0].code):
                        break
                    for code, answer in _answers(pool, ((task.code, task) for task in batch), worker_died):
                        answered.add(code)
                        if isinstance(answer, Failure) and answer.kind == DiskFullError.__name__:
                            raise DiskFullError(answer.message)  # every later run would fail alike: stop now
                        if isinstance(answer, Failure):
                            summary.estopped = summary.estopped or answer.kind == EStopped.__name__  # no later row starts
                            message = answer.message if answer.user_error else f"{answer.kind}: {answer.message}"
                            summary.failed.append((code, message))
                            _record_failure(folder, code, message, study.blind)
                            on_failed(code, message)
                            continue
                        outcomes.append(answer.outcome)
                        folder.run_failure(code).unlink(missing_ok=True)
                        if study.blind:
                            to_the_minute(folder.path(OUTCOMES), folder.root)
                        summary.finished.append(answer)
                        on_done(answer)
        finally:
            if guard is not None:
                guard.halt()
                guard.close()
            clean_partials(folder)
            summary.done = len(outcomes.finished & set(study.codes))
    return summary


@contextmanager
def _finally(then: Callable[[], None]) -> Iterator[None]:
    try:
        yield
    finally:
        then()


def _guard(folder: StudyFolder, robot: RobotSettings, blind: bool, session: str) -> Guard:
    from trials.robot.guard import Guard

    return Guard(folder, robot, blind, session)


def _same_settings(outcomes: Outcomes, rerun: set[str], settings: RunSettings, spec: Path) -> None:
    """StudyError when a kept finished run was simulated with other settings than these (`spec`: where they are set)."""
    for row in outcomes.rows:
        changed = [] if row.run_code in rerun else differences(outcome_cells(row), settings)
        if changed:
            raise StudyError(f"run {row.run_code} ran with other settings ({'; '.join(changed)}); set them in the [run] "
                             f"table of {spec} to match, or pass --settings-differ to mix them (the report flags it)")


def _record_failure(folder: StudyFolder, code: str, message: str, blind: bool) -> None:
    """runs/<code>.failed.txt: why the run failed (one line), until it finishes; to the minute when blind."""
    path = folder.run_failure(code)
    write_text(path, message.splitlines()[0] + "\n" if message else "failed\n")
    if blind:
        to_the_minute(path, path.parent)


def with_scenes(tasks: list[RunTask], root: Path, options: ReplayOptions) -> list[RunTask]:
    """The tasks, those that play a log with it read and tracked (each log once).

    Raises:
        LogError: a log that cannot be played (missing, damaged, no scans, too short).
    """
    scenes: dict[Path, LoggedScene] = {}
    ready = []
    for task in tasks:
        path = log_of(task.row, root, options)
        if path is not None and path not in scenes:
            scenes[path] = prepare(path, options)
        ready.append(replace(task, scene=scenes[path]) if path is not None else task)
    return ready


def _answers(pool: WorkerPool, tasks: Iterator[tuple[str, RunTask]], worker_died: Callable[[str], None]) -> Iterator[tuple[str, Any]]:
    """The pool's answers; a worker's death is told to `worker_died` (with how it died) and ends the command."""
    try:
        yield from pool.run(tasks)
    except PoolError as exc:
        worker_died(exc.death)
        raise StudyError(f"{exc}; the finished runs are kept, run `trials run` again to continue") from None


# --- the workers: running one row ----------------------------------------------------------------

def row_seeds(seed: int) -> list[int]:
    """A run's four seeds from its seed: scenario, crowd, perception and controller."""
    return [int(s.generate_state(1)[0]) for s in np.random.SeedSequence(seed).spawn(4)]


def scene_of(factors: dict[str, str], where: str, options: RunOptions, seeds: list[int]) -> tuple[Scenario, Perception, SimConfig]:
    """A simulated row's scene, perception and simulation settings, seeded by `row_seeds`.

    Raises:
        StudyError: factor values the simulator cannot run (`where` names the row).
    """
    from trials.scenario import build_scenario
    from trials.sim.closed_loop import SimConfig
    from trials.sim.perception import LidarPerception, PositionPerception

    scenario_seed, _, perception_seed, _ = seeds
    scenario = build_scenario(settings_from_row(factors, where), scenario_seed)
    perception: Perception = (LidarPerception(perception_seed) if options.settings.perception == "lidar"
                              else PositionPerception(options.noise, perception_seed))
    return scenario, perception, SimConfig(timeout_s=options.settings.timeout_s)


def setup_worker(root: str, name: str, blind: bool, levels: tuple[str, ...], options: RunOptions) -> Callable[[RunTask], RunDone]:
    """Build a worker's controllers once (opening the sealed key when blind); returns its task handler."""
    import warnings

    import torch

    torch.set_num_threads(1)
    if blind:
        warnings.simplefilter("ignore")  # a warning naming a module would name the controller
        _silence()  # and so would whatever a controller prints; the worker reports through its pool only
    return TrialWorker(StudyFolder(Path(root)), name, blind, levels, options)


def _silence() -> None:
    """Point this process's standard output and error (the file descriptors, so C libraries' writes too) at /dev/null."""
    sys.stdout.flush()
    sys.stderr.flush()
    null = os.open(os.devnull, os.O_WRONLY)
    for descriptor in (1, 2):
        os.dup2(null, descriptor)
    os.close(null)


class TrialWorker:
    """Runs plan rows in one worker process with controllers built once."""

    def __init__(self, folder: StudyFolder, name: str, blind: bool, levels: tuple[str, ...], options: RunOptions) -> None:
        self.folder, self.name, self.blind, self.options = folder, name, blind, options
        self._arms: dict[str, str] = folder.read_sealed().arms if blind else {}
        wanted = tuple(dict.fromkeys(self._arms.values())) if blind else levels
        # A live run times each plan itself: there a late plan stops the robot while the controller is still planning.
        built = registry.ControllerOptions(weights=options.settings.weights, study=tuple(study_controllers(folder, blind).items()),
                                           folder=str(folder.root), plan_limit_s=None if options.robot is not None else OFFLINE_PLAN_LIMIT_S)
        self._controllers = {level: registry.build(level, built) for level in sorted(wanted)}
        nav_stack = any(is_nav_stack(controller) for controller in self._controllers.values())
        if nav_stack and options.robot is None:
            raise StudyError("one of this study's controllers plans on the robot: the study runs live only (trials run --robot URI)")
        self._driver = None
        if options.robot is not None:
            from trials.robot.live import warm_up
            from trials.robot.live_trial import LiveDriver

            warm_up(self._controllers.values())
            self._driver = LiveDriver(folder, options.robot, options.robot_session, nav_stack)

    def _level(self, row: dict[str, str]) -> tuple[str, str | None]:
        label = row.get(CONTROLLER)
        if self.blind:
            return self._arms[label], label
        return label or registry.DEFAULT, None

    def __call__(self, task: RunTask) -> RunDone:
        """Run one row. In a blinded study a failure's details go to the sealed part (a traceback
        names the controller's modules); the error says only where they are."""
        try:
            with no_space(self.folder.run_log(task.code)):
                return self._run(task)
        except (DiskFullError, RunAborted):
            raise  # their messages name no controller
        except Exception:
            if not self.blind:
                raise
            import traceback

            details = self.folder.sealed_failure(task.code)
            write_sealed(self.folder, details, traceback.format_exc().encode())
            raise RuntimeError(f"the run failed; what went wrong is in {details} (reading it may unblind)") from None

    def _run(self, task: RunTask) -> RunDone:
        level, arm = self._level(task.row)
        controller = self._controllers[level]
        seeds = row_seeds(task.seed)
        controller.reset(seeds[3])
        try:
            status, done = self._drive(task, level, arm, controller, seeds)
        except BaseException as exc:
            with suppress(Exception):  # the run's own failure is the one reported
                controller.end(RUN_ABORTED if isinstance(exc, RunAborted) else "failed")
            raise
        controller.end(status)
        return done

    def _drive(self, task: RunTask, level: str, arm: str | None, controller: Controller, seeds: list[int]) -> tuple[str, RunDone]:
        """Run row `task` with its reset controller; returns how it ended and what the parent records."""
        path = self.folder.run_log(task.code)
        replay: dict[str, str] = {}
        settings = self.options.settings
        if self.options.robot is not None:
            status, metrics, perception = self._live(task, level, arm, controller, path)
            recorded = {"perception": perception, "timeout_s": self.options.robot.timeout}
        elif task.scene is None:
            status, metrics = self._simulate(task, level, arm, controller, seeds, path)
            recorded: dict[str, Any] = {"perception": settings.perception, "noise_std_m": settings.noise_std_m,
                                        "dropout": settings.dropout, "timeout_s": settings.timeout_s}
        else:
            recorded = {"perception": LOGGED}
            metadata = self._metadata(task, level, {"perception": LOGGED, "weights": settings.recorded()["weights"],
                                                    **self._factors(task), **task.scene.metadata()})
            with RunLog(path, metadata, tuple(task.scene.goal), None, self.blind, start_ns=self._start_ns(task.scene)) as log:
                played = play(task.scene, controller, log)
                self._seal(task, level, arm, log)
            status, metrics = played.status, played.outcome
            replay = {} if self.blind else played.summary()
        if self.blind:
            to_the_minute(path, path.parent)
        outcome = Outcome(run_code=task.code, status=status, seed=task.seed, **recorded, **asdict(metrics),
                          controller=None if self.blind else level, finished_utc=utc_stamp(self.blind),
                          weights=settings.recorded()["weights"])
        return status, RunDone(task.code, outcome, task.scene is not None, replay, live=self.options.robot is not None)

    def _start_ns(self, scene: LoggedScene | None = None) -> int:
        """The log time of a run's start: a played log's own header stamp there (when it was recorded) when its stamps
        are real times (from 2000 on) or with --wall-clock; a simulated run's 0, or with --wall-clock now (to the minute
        when blind, as every time a blinded study records, so run times cannot tell the arms apart)."""
        if scene is not None and (self.options.wall_clock or scene.scan_ns[0] >= REAL_TIME_NS):
            return int(scene.scan_ns[0])
        if not self.options.wall_clock:
            return 0
        now = time.time_ns()
        return minute_ns(now) if self.blind else now

    def _simulate(self, task: RunTask, level: str, arm: str | None, controller: Controller, seeds: list[int],
                  path: Path) -> tuple[str, RunMetrics]:
        """Simulate a row in closed loop, writing its log; returns how it ended and its metrics."""
        from trials.sim.closed_loop import simulate

        options = self.options
        scenario, perception, config = scene_of(self._factors(task), f"run {task.code}", options, seeds)
        crowd_seed = seeds[1]
        entries = {"perception": options.settings.perception, "timeout_s": f"{options.settings.timeout_s:g}",
                   "weights": options.settings.recorded()["weights"], **self._factors(task),
                   "variation": json.dumps(scenario.variation())}
        if options.settings.perception == "positions":
            noise = options.noise
            entries.update(noise_std_m=f"{noise.std_m:g}", dropout=f"{noise.dropout:g}", range_m=f"{noise.range_m:g}")
        with RunLog(path, self._metadata(task, level, entries), scenario.goal, scenario.cone, self.blind, config.limits,
                    self._start_ns()) as log:
            result = simulate(scenario, controller, perception, log, config, crowd_seed)
            self._seal(task, level, arm, log)
        trace = result.trace
        return result.status, measure(result.status, np.array(trace.time), np.array(trace.pose), np.array(trace.velocity),
                                      np.array(trace.pedestrians).reshape(len(trace.time), len(scenario.walkers), 2),
                                      config.limits, config.pedestrian_radius_m)

    def _live(self, task: RunTask, level: str, arm: str | None, controller: Controller, path: Path) -> tuple[str, RunMetrics, str]:
        """Drive a row live on the robot (`trials.robot.live_trial`), writing its log; returns how it ended, its metrics and
        its perception (`live`, or `software-robot`). A run stopped before its own ending keeps its log (and sealed record) in runs/aborted/, records why
        in runs/<code>.failed.txt and raises RunAborted; after SIGTERM the worker exits once the run's files are kept."""
        from trials.live_checks import record_check
        from trials.robot.live import ABORTED, estopped
        from trials.robot.live_log import LiveLog
        from trials.robot.live_trial import aborted_stamp

        robot, driver = self.options.robot, self._driver
        assert robot is not None and driver is not None
        entries = {"perception": LIVE, "weights": self.options.settings.recorded()["weights"], **robot.recorded(), **self._factors(task)}
        log = LiveLog(path, self._metadata(task, level, entries), self.blind, robot.limits)
        with driver.task():
            try:
                end = driver.drive(task.code, task.row, controller, log)
            except RunAborted as exc:
                _record_failure(self.folder, task.code, str(exc), self.blind)
                raise
            except BaseException:
                if log.log is not None:  # whatever stopped the run, what it recorded is kept
                    self._keep_aborted(task, level, arm, log, aborted_stamp())
                    record_check(self.folder, task.code, ABORTED, "an exception stopped the run", None, self.blind)
                raise
            people = end.people.check(int(float(task.row.get(PEDESTRIANS, DEFAULTS[PEDESTRIANS]))), robot.min_people_share)
            if end.status == ABORTED or driver.terminated:
                # A run stopped as it ended cannot hand its row to a parent that is stopping: it is kept aside, pending.
                why = end.detail if end.status == ABORTED else f"stopped by SIGTERM as it ended ({end.status})"
                message = f"run {task.code} aborted: {why}; its log is {self._keep_aborted(task, level, arm, log, aborted_stamp())}"
                _record_failure(self.folder, task.code, message, self.blind)
                record_check(self.folder, task.code, ABORTED, why, people, self.blind)
                raise (EStopped if estopped(why) else RunAborted)(message)
            self._seal(task, level, arm, log.log)
            log.close()
            record_check(self.folder, task.code, end.status, end.detail, people, self.blind)
        return end.status, end.metrics, end.perception

    def _keep_aborted(self, task: RunTask, level: str, arm: str | None, log: LiveLog, stamp: str) -> Path | None:
        """Close an aborted run's log and move it (and its sealed record) to where aborted runs are kept."""
        from trials.robot.live_trial import move_aside

        if log.log is None:
            return None
        self._seal(task, level, arm, log.log, self.folder.aborted_sealed_run(task.code, stamp))
        log.close()
        kept = move_aside(self.folder.run_log(task.code), self.folder.aborted_log(task.code, stamp))
        if kept is not None and self.blind:
            to_the_minute(kept, kept.parent)
        return kept

    def _seal(self, task: RunTask, level: str, arm: str | None, log: RunLog, path: Path | None = None) -> None:
        """Blinded studies: what the controller computed goes to sealed/runs/<code>.json.gz (before
        its log is renamed): its plans and own records by topic, a logged trial's plans against the log."""
        if self.blind:
            record = {**self._controllers[level].details(), "format": SEALED_RUN_FORMAT, "run_code": task.code, "arm": arm,
                      "controller": level, "seed": task.seed, "topics": log.withheld, "metadata": log.withheld_metadata,
                      "commands": log.withheld_commands}
            write_sealed(self.folder, path or self.folder.sealed_run(task.code), (json.dumps(jsonable(record)) + "\n").encode())

    @staticmethod
    def _factors(task: RunTask) -> dict[str, str]:
        """The row's factor settings (its plan columns but order, run code and log)."""
        return {k: v for k, v in task.row.items() if k not in ("order", "run_code", LOG_COLUMN)}

    def _metadata(self, task: RunTask, level: str, entries: dict[str, str]) -> dict[str, str]:
        """The `run` metadata record: code, study and seed, the run's own entries, and (when open) the controller."""
        meta = {"run_code": task.code, "study": self.name, "seed": str(task.seed), **entries}
        # A controller's details never replace the run's own entries (a plug-in may call a detail anything).
        return meta if self.blind else {**self._controllers[level].details(), **meta, "controller": level}
