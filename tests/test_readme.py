"""The README's commands run as shown: its study blocks in a fresh folder, its sample commands from the repository root."""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # two whole simulated studies

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()


def commands(text: str) -> list[list[str]]:
    """The `trials ...` command lines of a text, as argument lists with their comments stripped."""
    found = []
    for line in text.splitlines():
        words = shlex.split(line.split("#", 1)[0])
        if words[:1] == ["trials"]:
            found.append(words)
    return found


def run(words: list[str], cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "trials.cli", *words[1:]], cwd=cwd, capture_output=True, text=True)


def test_the_readme_shows_the_three_commands_and_the_ab_flow():
    blocks = re.findall(r"```bash\n(.*?)```", README, re.S)
    study_blocks = [block for block in blocks if "pip install" not in block]
    assert [words[:2] for words in commands(study_blocks[0])] == [["trials", "design"], ["trials", "run"], ["trials", "report"]]
    assert ["trials", "run", "--blind"] in commands(study_blocks[1])


@pytest.mark.parametrize("block", [0, 1], ids=["three commands", "blinded A/B"])
def test_each_study_block_runs_in_a_fresh_folder(block, tmp_path):
    blocks = [b for b in re.findall(r"```bash\n(.*?)```", README, re.S) if "pip install" not in b]
    printed = ""
    for words in commands(blocks[block]):
        commitment = re.findall(r"\b[0-9a-f]{64}\b", printed)  # HEX stands for the commitment `trials design` printed
        done = run([commitment[-1] if word == "HEX" else word for word in words], tmp_path)
        assert done.returncode == 0, f"{shlex.join(words)}: {done.stderr}"
        printed += done.stdout
    assert (tmp_path / "report" / "report.md").is_file()


def test_the_sample_commands_run_from_the_repository_root():
    table = [line for line in README.splitlines() if line.startswith("| `trials ") and "tests/data/" in line]
    samples = [shlex.split(line.split("`")[1]) for line in table]
    assert len(samples) >= 2
    for words in samples:
        done = run(words, ROOT)
        assert done.returncode == 0, f"{shlex.join(words)}: {done.stderr}"
        assert done.stdout.strip()
