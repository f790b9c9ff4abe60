"""The example plug-in package (examples/lab_planner) installed as a lab installs it: by pip, into a folder of its own
that only the processes given its environment see, so the toolkit has never seen it before."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "lab_planner"
#: What the package offers, and how its entry point reads.
NAME = "GapKeeper"
SOURCE = "entry point navtrials-lab-planner 0.1.0 (lab_planner:make_controller)"


def install_example(target: Path) -> dict[str, str]:
    """pip-install the example into `target` (offline: no dependencies, this interpreter's setuptools); the environment
    that puts it on the path, the repository's tests.support included."""
    source = target.with_name(f"{target.name}-source")  # built from a copy: nothing is left in the checkout's example
    shutil.copytree(EXAMPLE, source, ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__"))
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation", "--target", str(target),
                    str(source)], check=True, capture_output=True)
    root = str(Path(__file__).resolve().parents[2])
    return {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, (str(target), root, os.environ.get("PYTHONPATH"))))}
