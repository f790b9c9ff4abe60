"""A test that needs a Debian package the README's install does not bring is skipped where it is missing, saying what
to install, and fails instead where NAVTRIALS_REQUIRE_SYSTEM_PACKAGES=1 (CI), so CI never skips it."""

from __future__ import annotations

import pytest

from tests.support.system_packages import REQUIRED, need


def test_a_missing_package_skips_on_a_newcomers_machine_and_fails_in_ci(monkeypatch):
    monkeypatch.delenv(REQUIRED, raising=False)
    need(True, "ROS 1", "sudo apt-get install python3-rospy")  # installed: nothing happens
    with pytest.raises(pytest.skip.Exception, match=r"^ROS 1 is not installed \(install it with `sudo apt-get install python3-rospy`, as .ci/run does\)$"):
        need(False, "ROS 1", "sudo apt-get install python3-rospy")
    monkeypatch.setenv(REQUIRED, "1")
    with pytest.raises(pytest.fail.Exception, match=f"{REQUIRED}=1 asks for every test to run"):
        need(False, "ROS 1", "sudo apt-get install python3-rospy")
