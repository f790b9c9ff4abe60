"""The sealed record of a blinded run (`sealed/runs/<code>.json.gz`) and of a failed one
(`<code>.error.txt.gz`): written private, padded so that a listing does not tell the arms apart, and
read back for unblinding.

A record's size follows its controller (NaviGAN-R's forces are larger than the lattice's search
figures), so each is gzip-compressed and padded with zero bytes to a whole number of
`SEALED_BLOCK`s; gzip readers skip trailing zeros. Every run's record fits one block unless its run
is far longer than the study's usual ones. sealed/ is 0700 and its files 0600, so other users of
the machine cannot list or read them at all.
"""

from __future__ import annotations

import gzip
import json
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from robot_logs.run_log import CONTROLLER_RECORD, PLAN, REPLAY_METADATA
from trials.atomic import write_files
from trials.errors import StudyError
from trials.study import StudyFolder, private_folder

#: The size every sealed record is padded to (or a multiple of it).
SEALED_BLOCK = 256 * 1024
#: Format of a run's sealed record (its keys: docs/run_logs.md).
SEALED_RUN_FORMAT = "navtrials.sealed-run/2"


def padded(content: bytes) -> bytes:
    """`content` gzip-compressed (a fixed mtime, so no time is stored) and zero-padded to whole blocks."""
    packed = gzip.compress(content, mtime=0)
    return packed + bytes(-len(packed) % SEALED_BLOCK)


def write_sealed(folder: StudyFolder, path: Path, content: bytes) -> None:
    """Write a sealed file of `folder` padded, readable by its owner only."""
    private_folder(folder, path.parent)
    write_files({path: padded(content)}, private={path})


def read_sealed_run(folder: StudyFolder, code: str) -> dict[str, Any]:
    """A run's sealed record (padded, or the plain `<code>.json` an older release wrote).

    Raises:
        StudyError: no record for the run, or a damaged one.
    """
    path, older = folder.sealed_run(code), folder.older_sealed_run(code)
    try:
        content = gzip.decompress(path.read_bytes()) if path.exists() else older.read_bytes()
        return json.loads(content)
    except FileNotFoundError:
        raise StudyError(f"run {code} has no sealed record ({path}): was it run blind by this study?") from None
    except (OSError, EOFError, zlib.error, json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise StudyError(f"the sealed record {path if path.exists() else older} is damaged: {exc}") from None



@dataclass(frozen=True)
class Unsealed:
    """What `trials log show --unblind` adds to a blinded run: lines to print, and a logged trial's
    `replay` figures (its plans against the log)."""

    lines: list[str]
    replay: dict[str, str]


def unsealed_lines(folder: StudyFolder, code: str, commitment: str | None) -> Unsealed:
    """Open the key (checked as `StudyFolder.open_sealed` does) and a run's sealed record: its
    arm, controller and plans.

    Raises:
        StudyError: a key that fails its check, or no readable sealed record for the run.
    """
    sealed, check = folder.open_sealed(commitment)
    record = read_sealed_run(folder, code)
    topics = record.get("topics", {})
    # An older release's record holds only the controller's own records, one per plan, as "steps".
    plans = len(topics[PLAN.name]) if PLAN.name in topics else len(record.get("steps", []))
    records = len(topics.get(CONTROLLER_RECORD.name, record.get("steps", [])))
    arm = record.get("arm")
    lines = [f"unblinded: {check}",
             f"arm {arm} is {sealed.arms.get(str(arm), '?')}; controller: {record.get('controller', '?')}"
             + (f" ({record['weights']})" if "weights" in record else ""),
             f"{plans} plans and {records} controller records in {folder.sealed_run(code)}"]
    return Unsealed(lines, dict(record.get("metadata", {}).get(REPLAY_METADATA, {})))
