"""Shared fixtures: the data the tests read, all of it inside the repository (tests/data, navigan/datasets)."""

from __future__ import annotations

from pathlib import Path

import pytest

from navigan.data import SHIPPED_DATA

DATA = Path(__file__).resolve().parent / "data"

#: Fixtures shared by several test files: the lattice controller in its trial scene (`controller`, `fresh`), a ROS 1
#: master (`master`), a robot over either middleware (`middleware`).
pytest_plugins = ["tests.support.lattice_scene", "tests.support.ros1_master", "tests.support.live_rig"]


@pytest.fixture(scope="session")
def eth_ucy_dir() -> Path:
    """The ETH/UCY data shipped with navigan (navigan/datasets/eth_ucy, provenance in its README)."""
    return SHIPPED_DATA


@pytest.fixture(scope="session")
def robot_logs_dir() -> Path:
    """Real lidar recordings from angusleigh/leg_tracker (tests/data/robot_logs, provenance in its README)."""
    return DATA / "robot_logs"


@pytest.fixture(scope="session")
def sbpl_dir() -> Path:
    """SBPL problems, primitives and SBPL's own answers (tests/data/sbpl, provenance in its README)."""
    return DATA / "sbpl"


@pytest.fixture(scope="module")
def one_torch_thread():
    """Tiny tensors run fastest on one torch thread, and a shared 2-core machine thrashes with more."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)
