"""Shared fixtures: where the shared data and samples live (never inside the project)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"


def _existing(path: Path, what: str) -> Path:
    if not path.exists():
        pytest.fail(f"{what} not found at {path}; CI and the dev machine keep it there")
    return path


@pytest.fixture(scope="session")
def eth_ucy_dir() -> Path:
    """The ETH/UCY data: $TRIALS_DATA if set, else ../shared/datasets/eth_ucy."""
    env = os.environ.get("TRIALS_DATA")
    return _existing(Path(env) if env else SHARED / "datasets" / "eth_ucy", "ETH/UCY data")


@pytest.fixture(scope="session")
def robot_logs_dir() -> Path:
    """Real lidar recordings: ../shared/samples/robot_logs."""
    return _existing(SHARED / "samples" / "robot_logs", "robot log samples")


@pytest.fixture(scope="session")
def sbpl_dir() -> Path:
    """SBPL problems, primitives and answers: ../shared/samples/sbpl."""
    return _existing(SHARED / "samples" / "sbpl", "SBPL samples")


@pytest.fixture(scope="module")
def one_torch_thread():
    """Tiny tensors run fastest on one torch thread, and a shared 2-core machine thrashes with more."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)
