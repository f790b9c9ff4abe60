"""Running closed-loop campaigns in batches: in local worker processes (`trials.pool`) or on a Ray
cluster (one actor per CPU, each building its controllers once), handing each finished batch back
as soon as it arrives so the caller can append it to power.csv.

Only the driver reads the study folder and writes power/: the workers get the plans and options
with their task and send results back, so on a cluster the study's files stay on the driver's machine.
"""

from __future__ import annotations

import logging
import socket
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from trials.errors import USER_ERRORS, StudyError
from trials.pool import Failure, PoolError, WorkerPool
from trials.power.closed_loop import CampaignBatch, CampaignResult, setup_worker

#: `--ray local`: start a Ray instance on this machine instead of joining a cluster.
LOCAL = "local"
#: How long to wait for a Ray cluster's address to answer before calling it unreachable.
CONNECT_TIMEOUT_S = 3.0


@dataclass(frozen=True)
class Where:
    """Where campaigns run: `workers` local processes, or Ray (`ray` is `local` or the cluster's address)."""

    workers: int = 1
    ray: str | None = None

    def describe(self) -> str:
        if self.ray is None:
            return f"{self.workers} local worker process{'es' if self.workers > 1 else ''}"
        return f"a local Ray instance ({self.workers} CPUs)" if self.ray == LOCAL else f"the Ray cluster at {self.ray}"


def batches(pending: Sequence[tuple[int, int, int]], size: int) -> list[CampaignBatch]:
    """(plan, campaign, seed) triples in batches of at most `size` campaigns of one plan each."""
    out: list[CampaignBatch] = []
    for plan in dict.fromkeys(p for p, _, _ in pending):
        mine = [(c, s) for p, c, s in pending if p == plan]
        out += [CampaignBatch(plan, tuple(mine[i:i + size])) for i in range(0, len(mine), size)]
    return out


def run_batches(work: list[CampaignBatch], setup: tuple[Any, ...], where: Where, on_batch: Callable[[list[CampaignResult]], None]) -> None:
    """Run every batch where `where` says; `on_batch` gets each batch's results as it finishes.

    Raises:
        StudyError: a worker's user error (bad weights, a row the simulator cannot run), Ray missing or unreachable.
    """
    if not work:
        return
    if where.ray is None:
        _local(work, setup, where.workers, on_batch)
    else:
        _on_ray(work, setup, where, on_batch)


def _local(work: list[CampaignBatch], setup: tuple[Any, ...], workers: int, on_batch: Callable[[list[CampaignResult]], None]) -> None:
    with WorkerPool(min(workers, len(work)), setup_worker, setup, USER_ERRORS) as pool:
        try:
            pool.ready()
            for _, answer in pool.run(enumerate(work)):
                if isinstance(answer, Failure):
                    _raise(answer)
                on_batch(answer)
        except PoolError as exc:
            if exc.failure is not None:
                _raise(exc.failure)
            raise StudyError(f"{exc}; the finished campaigns are kept, run `trials power` again to continue") from None


def _raise(failure: Failure) -> None:
    if failure.user_error:
        raise StudyError(failure.message.splitlines()[0])
    raise RuntimeError(f"a campaign failed: {failure.kind}: {failure.message}\n{failure.details}")


#: How long a Ray cluster's address may take to answer the handshake of its gRPC server before it is called not Ray.
HANDSHAKE_TIMEOUT_S = 5.0
#: HTTP/2's client connection preface and an empty SETTINGS frame (RFC 9113, section 3.4). Ray's GCS (and its client
#: server, `ray://`) speak gRPC over HTTP/2 and answer with a SETTINGS frame of their own; a silent listener or an
#: HTTP/1 server does not, where `ray.init` would wait minutes. Plain `ray` ships no gRPC client for Python, so the
#: nine bytes of the answer are read here.
_PREFACE = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + bytes([0, 0, 0, 4, 0, 0, 0, 0, 0])
_SETTINGS = 4


def check_reachable(address: str) -> None:
    """Fail fast, in one line, when nothing answers at a Ray cluster's HOST:PORT, or what answers does not speak gRPC
    as Ray does (Ray itself waits long).

    Raises:
        StudyError: a malformed address, no answer within CONNECT_TIMEOUT_S, or no HTTP/2 answer within
            HANDSHAKE_TIMEOUT_S.
    """
    host, _, port = address.removeprefix("ray://").rpartition(":")
    if not host or not port.isdigit():
        raise StudyError(f"--ray: expected HOST:PORT of a Ray cluster (or `local`), got {address!r}")
    try:
        connection = socket.create_connection((host, int(port)), timeout=CONNECT_TIMEOUT_S)
    except OSError as exc:
        raise StudyError(f"--ray {address}: no Ray cluster answers there ({exc.strerror or exc}); start one with "
                         "`ray start --head` or check the address") from None
    with connection:
        connection.settimeout(HANDSHAKE_TIMEOUT_S)
        answer = b""
        try:
            connection.sendall(_PREFACE)
            while len(answer) < 9 and (chunk := connection.recv(9 - len(answer))):
                answer += chunk
        except TimeoutError:
            why = f"it did not answer Ray's handshake within {HANDSHAKE_TIMEOUT_S:g} s"
        except OSError as exc:
            why = f"it broke off Ray's handshake ({exc.strerror or exc})"
        else:
            why = "" if len(answer) == 9 and answer[3] == _SETTINGS else "it does not speak gRPC as Ray's head node does"
    if why:
        raise StudyError(f"--ray {address}: something listens there, but not a Ray cluster ({why}); give the head node's "
                         "GCS address (`ray start --head` prints it; port 6379 by default)")


#: How many times Ray restarts a dead actor and reruns the batches it lost.
RAY_RETRIES = 2


class RayWorker:
    """A Ray actor's state: the campaign handler, built once when the actor starts."""

    def __init__(self, *setup: Any) -> None:
        self.handler = setup_worker(*setup)

    def run(self, batch: CampaignBatch) -> list[CampaignResult]:
        return self.handler(batch)


def check_ray(address: str) -> None:
    """Ray is installed and, unless `local`, something answers at `address`; checked before any work starts.

    Raises:
        StudyError: Ray missing, a malformed address or an unreachable cluster.
    """
    try:
        import ray  # noqa: F401
    except ImportError:
        raise StudyError("--ray needs Ray, an optional extra: pip install 'navtrials[ray]'") from None
    if address != LOCAL:
        check_reachable(address)


def _on_ray(work: list[CampaignBatch], setup: tuple[Any, ...], where: Where, on_batch: Callable[[list[CampaignResult]], None]) -> None:
    import ray

    assert where.ray is not None
    check_ray(where.ray)
    # Ray's "local" always starts a new instance; None would join a cluster named by RAY_ADDRESS or `ray start`.
    address = "local" if where.ray == LOCAL else where.ray
    ray.init(address=address, num_cpus=where.workers if where.ray == LOCAL else None, include_dashboard=False,
             logging_level=logging.ERROR, log_to_driver=False, configure_logging=True)
    try:
        cpus = max(int(ray.cluster_resources().get("CPU", 1)), 1)
        # A batch is a pure function of its seeds, so one whose actor died (a worker lost on a busy or failing node)
        # is safely run again on the actor Ray restarts; errors the batch itself raises are never retried.
        actor = ray.remote(num_cpus=1, max_restarts=RAY_RETRIES, max_task_retries=RAY_RETRIES)(RayWorker)
        _run_on_actors(ray, lambda: actor.remote(*setup), min(cpus, len(work)), work, on_batch)
    finally:
        ray.shutdown()


def _run_on_actors(ray: Any, start: Callable[[], Any], count: int, work: list[CampaignBatch],
                   on_batch: Callable[[list[CampaignResult]], None]) -> None:
    """Each batch on one of `count` actors made by `start`, a batch at a time each, results handed on as they come.

    An actor Ray gave up on (one whose start was cancelled on a busy node, or that died past its restarts) is
    replaced by a fresh one, and its batch run again, up to RAY_RETRIES times a batch, so one slow start on a busy
    cluster does not end the whole run.
    """
    actors = [start() for _ in range(count)]
    waiting = list(range(len(work)))
    lost = [0] * len(work)
    running: dict[Any, tuple[int, int]] = {}  # the task's reference -> (actor, batch)

    def submit(slot: int) -> None:
        index = waiting.pop(0)
        running[actors[slot].run.remote(work[index])] = (slot, index)

    for slot in range(min(count, len(waiting))):
        submit(slot)
    while running:
        (done,), _ = ray.wait(list(running), num_returns=1)
        slot, index = running.pop(done)
        try:
            results = ray.get(done)
        except ray.exceptions.RayTaskError as exc:
            cause = exc.cause if isinstance(exc.cause, BaseException) else None
            if isinstance(cause, USER_ERRORS):
                raise StudyError(str(cause).splitlines()[0]) from None
            raise
        except ray.exceptions.RayActorError as exc:
            lost[index] += 1
            if exc.actor_init_failed or lost[index] > RAY_RETRIES:
                raise
            ray.kill(actors[slot], no_restart=True)
            actors[slot] = start()
            waiting.insert(0, index)
        else:
            on_batch(results)
        if waiting:
            submit(slot)
