"""Screenshots of `trials serve`'s main pages for docs/console/: a blinded two-run study worked through in
headless Chromium (tests/support/console.py's field day, with the sample bag), each page saved as PNG.

    python scripts/console_screenshots.py docs/console

Exits 0 with run_sheet.png, run_page.png, score_form.png, questionnaire_phone.png and progress.png written,
3 when Debian's chromium and chromium-driver are not installed (apt-get install chromium chromium-driver).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.support.console import chromium_ready, design_study, field_day, served  # noqa: E402

NO_BROWSER = 3
SAMPLE_LOG = ROOT / "tests" / "data" / "robot_logs" / "stationary_ros1.bag"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, help="the folder to write the PNGs to")
    args = parser.parse_args()
    if not chromium_ready():
        print("no chromium and chromium-driver: apt-get install chromium chromium-driver", file=sys.stderr)
        return NO_BROWSER
    args.out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as work:
        study = design_study(Path(work) / "study")
        with served(study) as url:
            field_day(url, study, SAMPLE_LOG, shots=args.out)
    print(f"Wrote the console's screenshots to {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
