"""Writers in several processes at once (the console's forms and `trials score` / `trials respond`) never lose an
acknowledged row: each read-change-write of a results file holds its writer lock (`trials.atomic.one_writer`)."""

from __future__ import annotations

import subprocess
import sys

import pytest

from tests.support.live_rig import repository_env
from tests.support.synthetic_study import design, run_all
from trials.responses import read_responses
from trials.scores import read_scores
from trials.study import RESPONSES, SCORES

#: Each writer process records this many rows, all at once with the others.
ROWS = 40
WRITER = """
import sys
from pathlib import Path
from trials.responses import record_response
from trials.scores import record_score
from trials.study import StudyFolder
folder, code, kind, name = StudyFolder(Path(sys.argv[1])), sys.argv[2], sys.argv[3], sys.argv[4]
for k in range({rows}):
    if kind == "respond":
        record_response(folder, code, f"{{name}}-{{k}}", "yes" if k % 2 else "no")
    else:
        record_score(folder, code, str(1 + k % 3), name, f"note {{k}}")
"""


@pytest.mark.slow
def test_four_processes_writing_at_once_lose_no_row(tmp_path):
    study = design(tmp_path / "study")
    run_all(study, limit=1)
    code = study.read_plan()[0]["run_code"]
    writers = [subprocess.Popen([sys.executable, "-c", WRITER.format(rows=ROWS), str(study.root), code, kind, name], env=repository_env(),
                                stderr=subprocess.PIPE, text=True)
               for kind, name in (("respond", "P"), ("respond", "Q"), ("score", "ana"), ("score", "ben"))]
    for writer in writers:
        _, err = writer.communicate(timeout=600)
        assert writer.returncode == 0, err
    responses = read_responses(study.path(RESPONSES))
    assert sorted(r.participant for r in responses) == sorted(f"{p}-{k}" for p in "PQ" for k in range(ROWS))
    scores = read_scores(study.path(SCORES))
    assert sorted((s.scorer, s.note) for s in scores) == sorted((n, f"note {k}") for n in ("ana", "ben") for k in range(ROWS))


@pytest.mark.parametrize("make", ["fifo", "folder", "link"])
def test_a_lock_file_that_is_not_a_regular_file_is_refused_in_one_line(tmp_path, make):
    """A FIFO in place of a writer lock would hang every writer (opening it waits for a reader); a folder or a link in
    place of the run lock is refused alike. Each is one line naming the file, exit code 2, and nothing is written."""
    import os

    folder = design(tmp_path / "study")
    run_all(folder, limit=1)
    code = folder.read_plan()[0]["run_code"]
    writer_lock, run_lock = folder.path(f".{RESPONSES}.writing"), folder.path("runs/.lock")
    for lock in (writer_lock, run_lock):
        lock.unlink(missing_ok=True)
        {"fifo": os.mkfifo, "folder": os.mkdir, "link": lambda p: os.symlink(tmp_path / "elsewhere", p)}[make](lock)
    respond = subprocess.run([sys.executable, "-m", "trials.cli", "respond", "--study", str(folder.root), code, "P1", "yes"],
                             env=repository_env(), capture_output=True, text=True, timeout=60)
    assert respond.returncode == 2 and not folder.path(RESPONSES).exists()
    assert respond.stderr.strip().count("\n") == 0 and f"{writer_lock} is not a regular file" in respond.stderr
    status = subprocess.run([sys.executable, "-m", "trials.cli", "status", "--study", str(folder.root)], env=repository_env(),
                            capture_output=True, text=True, timeout=60)
    assert status.returncode == 2 and f"{run_lock} is not a regular file" in status.stderr
    assert not (tmp_path / "elsewhere").exists()
