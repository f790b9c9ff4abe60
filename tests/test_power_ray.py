"""`trials power --ray`: a local Ray cluster started by the test (`ray start --head`) and `--ray local` give
the very campaigns local processes give for the same power seed; an address that accepts TCP but is not Ray is
refused within seconds; a batch whose actor Ray gave up on runs again on a fresh actor."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from types import SimpleNamespace

import pytest

from tests.test_power_cli import campaigns, small  # noqa: F401 (the module's study fixture)
from trials.cli import main
from trials.power.closed_loop import CampaignBatch
from trials.power.execution import HANDSHAKE_TIMEOUT_S, RAY_RETRIES, _run_on_actors

pytest.importorskip("ray")
pytestmark = pytest.mark.slow  # starts a Ray cluster and runs campaigns on it


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


@pytest.fixture
def ray_cluster():
    """A 2-CPU Ray head on a free port, its files in a short temporary folder; stopped afterwards."""
    ray = shutil.which("ray", path=str(Path(sys.executable).parent)) or "ray"
    port = free_port()
    temp = tempfile.mkdtemp(prefix="ray", dir="/tmp")  # Ray's socket paths must stay short
    env = {**os.environ, "RAY_USAGE_STATS_ENABLED": "0"}
    subprocess.run([ray, "start", "--head", "--port", str(port), "--num-cpus", "2", "--temp-dir", temp,
                    "--include-dashboard", "false", "--disable-usage-stats"], check=True, env=env, capture_output=True)
    try:
        yield f"127.0.0.1:{port}"
    finally:
        subprocess.run([ray, "stop"], env=env, capture_output=True)
        shutil.rmtree(temp, ignore_errors=True)


def test_ray_cluster_and_ray_local_match_local_processes(small, tmp_path, ray_cluster, monkeypatch):  # noqa: F811
    base = ["power", "--study", str(small), "--simulations", "2", "--seed", "21", "--campaigns", "3"]
    assert main([*base, "--workers", "2", "--out", str(tmp_path / "local")]) == 0
    # `--ray local` starts its own instance even where RAY_ADDRESS names a cluster (here one that never answers).
    monkeypatch.setenv("RAY_ADDRESS", "127.0.0.1:9")
    assert main([*base, "--ray", "local", "--workers", "2", "--out", str(tmp_path / "ray_local")]) == 0
    monkeypatch.delenv("RAY_ADDRESS")
    # The cluster is joined from a fresh process, as a user's `trials power --ray HOST:PORT` joins it, not by a
    # driver that has already started and shut down Ray instances above. `ray start` turns on token
    # authentication; a driver sends the token (~/.ray/auth_token) in this mode.
    joined = subprocess.run([sys.executable, "-m", "trials.cli", *base, "--ray", ray_cluster, "--batch", "2",
                             "--out", str(tmp_path / "cluster")], env={**os.environ, "RAY_AUTH_MODE": "token"},
                            capture_output=True, text=True)
    assert joined.returncode == 0, joined.stderr[-2000:]
    assert "on the Ray cluster at 127.0.0.1:" in joined.stdout
    local = campaigns(tmp_path / "local")
    assert len(local) == 3
    assert campaigns(tmp_path / "cluster") == local
    assert campaigns(tmp_path / "ray_local") == local


@pytest.fixture
def silent_listener():
    """A port that accepts TCP connections and never says a word."""
    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen(8)
        yield f"127.0.0.1:{server.getsockname()[1]}"


class QuietHandler(BaseHTTPRequestHandler):
    def log_message(self, *args: object) -> None:
        pass


@pytest.fixture
def http_server():
    """A plain HTTP server in a thread."""
    server = ThreadingHTTPServer(("127.0.0.1", 0), QuietHandler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()


@pytest.mark.parametrize(("listener", "why"), [("silent_listener", f"it did not answer Ray's handshake within {HANDSHAKE_TIMEOUT_S:g} s"),
                                               ("http_server", "it does not speak gRPC as Ray's head node does")])
def test_an_address_that_is_not_ray_is_refused_within_seconds(small, tmp_path, capsys, request, listener, why):  # noqa: F811
    """Before, `ray.init` waited on such an address for 85 s and more."""
    address = request.getfixturevalue(listener)
    capsys.readouterr()
    began = time.monotonic()
    assert main(["power", "--study", str(small), "--simulations", "2", "--campaigns", "1", "--ray", address,
                 "--out", str(tmp_path / "out")]) == 2
    assert time.monotonic() - began < 30.0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"--ray {address}: something listens there, but not a Ray cluster ({why})" in err
    assert not (tmp_path / "out" / "power.csv").exists()


class FakeRay:
    """Enough of Ray for `_run_on_actors`: tasks finish at once, in the order submitted; an actor started while
    `cancelled` is above zero is one Ray gave up on before it ran."""

    exceptions = pytest.importorskip("ray").exceptions

    def __init__(self, cancelled: int) -> None:
        self.cancelled, self.started, self.killed, self.ran = cancelled, 0, 0, []

    def actor(self) -> SimpleNamespace:
        self.started += 1
        dead = self.cancelled > 0
        self.cancelled -= dead

        def run(batch: CampaignBatch) -> tuple[bool, CampaignBatch]:
            return dead, batch
        return SimpleNamespace(run=SimpleNamespace(remote=run))

    def wait(self, refs: list, num_returns: int) -> tuple[list, list]:
        return refs[:num_returns], refs[num_returns:]

    def get(self, ref: tuple[bool, CampaignBatch]) -> list:
        dead, batch = ref
        if dead:
            raise self.exceptions.ActorDiedError()
        self.ran.append(batch)
        return [batch.plan]

    def kill(self, actor: SimpleNamespace, no_restart: bool) -> None:
        self.killed += 1


def test_a_batch_whose_actor_never_started_runs_again_on_a_fresh_actor():
    work = [CampaignBatch(plan, ((plan, plan),)) for plan in range(5)]
    fake, done = FakeRay(cancelled=2), []
    _run_on_actors(fake, fake.actor, 2, work, done.append)
    assert sorted(done) == [[0], [1], [2], [3], [4]] and sorted(fake.ran, key=lambda b: b.plan) == work
    assert (fake.started, fake.killed) == (4, 2)
    stubborn = FakeRay(cancelled=RAY_RETRIES + 1)  # every start of one actor cancelled: the run fails, in Ray's words
    with pytest.raises(FakeRay.exceptions.ActorDiedError):
        _run_on_actors(stubborn, stubborn.actor, 1, work[:1], done.append)
