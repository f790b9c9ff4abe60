"""What the blinding tests look for: a controller's name, in any file or in an MCAP's decompressed content."""

from __future__ import annotations

import json
import re
import subprocess
from pathlib import Path

from mcap.reader import make_reader

from robot_logs import run_log as fmt
from tests.support.live_rig import TRIALS
from trials.sealed_runs import read_sealed_run
from trials.study import StudyFolder

NAMES = re.compile(rb"navigan|lattice|sbpl", re.IGNORECASE)


def mcap_text(path: Path) -> bytes:
    """Everything an MCAP holds, decompressed: header, metadata, schemas, topics and every message."""
    parts = []
    with path.open("rb") as stream:
        reader = make_reader(stream)
        header = reader.get_header()
        parts += [header.library.encode(), header.profile.encode()]
        parts += [json.dumps(m.metadata).encode() + m.name.encode() for m in reader.iter_metadata()]
        summary = reader.get_summary()
        parts += [s.name.encode() + s.data for s in summary.schemas.values()]
        parts += [c.topic.encode() + json.dumps(c.metadata).encode() for c in summary.channels.values()]
        parts += [message.data for _, _, message in reader.iter_messages()]
    return b"\n".join(parts)


def trials(env: dict[str, str], *args: str) -> subprocess.CompletedProcess:
    """`trials ARGS` in `env`, which must succeed."""
    done = subprocess.run([*TRIALS, *args], capture_output=True, env=env, timeout=900)
    assert done.returncode == 0, done.stdout.decode() + done.stderr.decode()
    return done


def public_files(study: StudyFolder) -> list[Path]:
    """Every file of the study outside sealed/."""
    return [p for p in study.root.rglob("*") if p.is_file() and "sealed" not in p.relative_to(study.root).parts]


def assert_names_nothing(study: StudyFolder, consoles: list[subprocess.CompletedProcess], named: re.Pattern[bytes]) -> None:
    """Neither a console's output nor any public file of `study` (its name or what it says) matches `named`."""
    for console in consoles:
        assert not named.search(console.stdout + console.stderr), console.stdout + console.stderr
    for path in public_files(study):
        assert not named.search(readable(path)) and not named.search(path.name.encode()), path


def readable(path) -> bytes:
    """What a file says: an MCAP's every record, a PNG's text chunks, any other file's bytes with embedded base64 images
    left out (compressed pixels spell anything by chance)."""
    if path.suffix == ".mcap":
        return mcap_text(path)
    if path.suffix == ".png":
        from PIL import Image

        with Image.open(path) as image:
            return json.dumps(image.text).encode()
    return re.sub(rb"base64,[A-Za-z0-9+/=]+", b"", path.read_bytes())


def assert_the_key_unblinds_to_what_drove(study: StudyFolder, codes: list[str], own_record: dict[str, str]) -> None:
    """Each run's sealed record names the arm of its row and the controller the key gives that arm, and holds that
    controller's own record every step (`own_record`: controller -> a key only its records have): the evidence of who drove."""
    arms = study.read_sealed().arms
    assert sorted(arms.values()) == sorted(own_record)
    labels = {row["run_code"]: row["Controller"] for row in study.read_plan()}
    for code in codes:
        sealed = read_sealed_run(study, code)
        driver = arms[labels[code]]
        assert sealed["arm"] == labels[code] and sealed["controller"] == driver
        records = [step["record"] for step in sealed["topics"][fmt.CONTROLLER_RECORD.name]]
        assert records and all(own_record[driver] in record for record in records), (driver, records[0])
