"""A blinded run's sealed record: gzip padded to whole blocks, owner-only, read back (older plain records too)."""

from __future__ import annotations

import gzip
import json
import stat

import numpy as np
import pytest

from trials.errors import StudyError
from trials.sealed_runs import SEALED_BLOCK, padded, read_sealed_run, write_sealed
from trials.study import StudyFolder


def test_records_of_any_size_list_alike_and_read_back(tmp_path):
    folder = StudyFolder(tmp_path)
    small, large = {"controller": "x", "steps": [1]}, {"controller": "y", "steps": list(range(20000))}
    for code, record in (("SMALL", small), ("LARGE", large)):
        write_sealed(folder, folder.sealed_run(code), json.dumps(record).encode())
    sizes = {p.name: p.stat().st_size for p in (tmp_path / "sealed" / "runs").iterdir()}
    assert sizes == {"SMALL.json.gz": SEALED_BLOCK, "LARGE.json.gz": SEALED_BLOCK}
    assert read_sealed_run(folder, "SMALL") == small and read_sealed_run(folder, "LARGE") == large
    assert all(stat.S_IMODE(p.stat().st_mode) == 0o600 for p in (tmp_path / "sealed" / "runs").iterdir())
    assert stat.S_IMODE((tmp_path / "sealed").stat().st_mode) == stat.S_IMODE((tmp_path / "sealed" / "runs").stat().st_mode) == 0o700


def test_a_record_beyond_one_block_takes_whole_blocks():
    noise = np.random.default_rng(3).bytes(SEALED_BLOCK + 10)  # incompressible: more than one block
    assert len(padded(noise)) == 2 * SEALED_BLOCK and gzip.decompress(padded(noise)) == noise
    assert len(padded(bytes(range(256)) * 2000)) == SEALED_BLOCK


def test_an_older_release_record_and_a_damaged_one(tmp_path):
    folder = StudyFolder(tmp_path)
    folder.older_sealed_run("OLD").parent.mkdir(parents=True)
    folder.older_sealed_run("OLD").write_text(json.dumps({"controller": "x", "steps": []}))
    assert read_sealed_run(folder, "OLD")["controller"] == "x"
    folder.sealed_run("BAD").write_bytes(b"not gzip")
    with pytest.raises(StudyError, match=r"the sealed record .*BAD\.json\.gz is damaged"):
        read_sealed_run(folder, "BAD")
    with pytest.raises(StudyError, match="run NONE has no sealed record"):
        read_sealed_run(folder, "NONE")
