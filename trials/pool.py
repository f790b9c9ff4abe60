"""A small pool of spawned worker processes that build their state once and die with their parent.

`concurrent.futures` cannot stop a worker in the middle of a task; trial runs need that (Ctrl-C
must not wait for a minute-long run, and a killed `trials run` must not leave workers writing
into the study). Each worker ignores Ctrl-C (the parent decides), asks Linux to kill it when
the parent dies, builds its state with `setup(*args)` (reporting any error as the first thing it
sends), then answers each task with the handler `setup` returned until told to stop.
"""

from __future__ import annotations

import ctypes
import multiprocessing as mp
import os
import queue
import signal
import sys
import time
import traceback
from collections.abc import Callable, Iterable, Iterator
from contextlib import suppress
from dataclasses import dataclass
from types import TracebackType
from typing import Any

#: prctl option: the signal a process gets when its parent dies (Linux).
PR_SET_PDEATHSIG = 1
READY = "ready"


@dataclass(frozen=True)
class Failure:
    """A task or a worker's setup raised: the exception's type, message and traceback."""

    kind: str
    message: str
    details: str
    user_error: bool


class PoolError(RuntimeError):
    """A worker could not be set up or died; `failure` says why when the worker could tell."""

    def __init__(self, message: str, failure: Failure | None = None, exitcode: int | None = None) -> None:
        super().__init__(message)
        self.failure, self.exitcode = failure, exitcode

    @property
    def death(self) -> str:
        """How the worker died: the signal that killed it, or its exit code."""
        code = self.exitcode
        if code is not None and code < 0:
            with suppress(ValueError):
                return signal.Signals(-code).name
        return f"exit code {code}"


def _die_with_parent(parent: int, death: int) -> None:
    if sys.platform.startswith("linux"):
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, death)
    if os.getppid() != parent:  # the parent died before prctl took effect
        os._exit(1)


def _failure(exc: BaseException, user_errors: tuple[type[BaseException], ...]) -> Failure:
    return Failure(type(exc).__name__, str(exc), traceback.format_exc(), isinstance(exc, user_errors))


def _serve(tasks: Any, results: Any, parent: int, setup: Callable[..., Callable[[Any], Any]], args: tuple[Any, ...],
           user_errors: tuple[type[BaseException], ...], death: int) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _die_with_parent(parent, death)
    try:
        handler = setup(*args)
    except Exception as exc:
        results.put((None, _failure(exc, user_errors)))
        return
    results.put((None, READY))
    while (item := tasks.get()) is not None:
        key, task = item
        try:
            answer = handler(task)
        except Exception as exc:
            answer = _failure(exc, user_errors)
        results.put((key, answer))


class WorkerPool:
    """`workers` processes, each set up by `setup(*args)`; use as a context manager.

    Leaving the block normally lets idle workers exit; leaving it by an exception (Ctrl-C
    included) kills them at once, wherever they are. With `graceful` (seconds), workers that must
    finish something first (a live run stopping its robot) are sent SIGTERM instead, also when the
    parent dies, and killed only if they have not exited after that many seconds.
    """

    def __init__(self, workers: int, setup: Callable[..., Callable[[Any], Any]], args: tuple[Any, ...] = (),
                 user_errors: tuple[type[BaseException], ...] = (), graceful: float | None = None) -> None:
        context = mp.get_context("spawn")
        self._graceful = graceful
        death = signal.SIGKILL if graceful is None else signal.SIGTERM
        self._tasks = context.Queue()
        self._results = context.Queue()
        self._processes = [
            context.Process(target=_serve, args=(self._tasks, self._results, os.getpid(), setup, args, user_errors, death), daemon=True)
            for _ in range(workers)
        ]
        for process in self._processes:
            process.start()

    def ready(self) -> None:
        """Wait until every worker is set up.

        Raises:
            PoolError: a worker's setup failed (the first failure) or it died.
        """
        for _ in self._processes:
            _, answer = self._receive()
            if isinstance(answer, Failure):
                raise PoolError(f"{answer.kind}: {answer.message}", answer)

    def run(self, tasks: Iterable[tuple[Any, Any]]) -> Iterator[tuple[Any, Any]]:
        """Hand out (key, task) pairs; yield (key, answer or Failure) as tasks finish."""
        pending = 0
        for item in tasks:
            self._tasks.put(item)
            pending += 1
        for _ in range(pending):
            yield self._receive()

    def _receive(self) -> tuple[Any, Any]:
        while True:
            try:
                return self._results.get(timeout=0.5)
            except queue.Empty:
                dead = [p for p in self._processes if not p.is_alive()]
                if dead:
                    raise PoolError(f"a worker process died (exit code {dead[0].exitcode})", exitcode=dead[0].exitcode) from None

    def __enter__(self) -> WorkerPool:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        if exc_type is None:
            for _ in self._processes:
                self._tasks.put(None)
            for process in self._processes:
                process.join()
        else:
            if self._graceful is not None:
                for process in self._processes:
                    process.terminate()
                deadline = time.monotonic() + self._graceful
                for process in self._processes:
                    process.join(max(deadline - time.monotonic(), 0.0))
            for process in self._processes:
                process.kill()
            for process in self._processes:
                process.join()
        self._tasks.close()
        self._results.close()
