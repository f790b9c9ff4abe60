"""Tests that need Debian packages outside pip's reach (ROS 1's rosmaster and rospy, Chromium and its driver): on a
machine set up by the README's install command alone they are skipped, each saying what is missing and how to
install it; where NAVTRIALS_REQUIRE_SYSTEM_PACKAGES=1 (`.ci/run`, which installs them) a missing package fails them,
so CI never skips them."""

from __future__ import annotations

import os

import pytest

#: Set to "1" where the packages must be there (CI).
REQUIRED = "NAVTRIALS_REQUIRE_SYSTEM_PACKAGES"


def need(ready: bool, what: str, install: str) -> None:
    """Skip, or in CI fail, the calling test when `what` is not installed (`install` says how to install it)."""
    if ready:
        return
    message = f"{what} is not installed (install it with `{install}`, as .ci/run does)"
    if os.environ.get(REQUIRED) == "1":
        pytest.fail(f"{message}; {REQUIRED}=1 asks for every test to run")
    pytest.skip(message)
