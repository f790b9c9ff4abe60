"""docs/results.md stays true: scripts/results.py recomputes its cheap, deterministic sections and finds them unchanged."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "results.py"


@pytest.mark.slow
def test_the_results_page_matches_the_designs_and_the_qualitative_study():
    # The A/B study (the lattice plans against the clock) and Table I (about a minute) are left to a
    # full `python scripts/results.py --check`.
    done = subprocess.run([sys.executable, str(SCRIPT), "--check", "--only", "designs,qualitative"],
                          capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 0, done.stdout + done.stderr
