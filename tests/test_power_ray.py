"""`trials power --ray`: a local Ray cluster started by the test (`ray start --head`) and `--ray local` give
the very campaigns local processes give for the same power seed."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from tests.test_power_cli import campaigns, small  # noqa: F401 (the module's study fixture)
from trials.cli import main

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
