"""Render a study's report.html in headless Chromium and save a screenshot, to check it by eye.

    python scripts/screenshot_report.py STUDY/report/report.html shot.png [--width 1280] [--height 6000]

Exits 0 with the screenshot written, 3 when no Chromium is installed (apt-get install chromium).
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable", "headless_shell")
NO_BROWSER = 3


def find_browser() -> str | None:
    """The first Chromium-like browser on PATH."""
    return next((path for name in BROWSERS if (path := shutil.which(name))), None)


def screenshot(html: Path, out: Path, width: int = 1280, height: int = 6000, browser: str | None = None) -> None:
    """Load `html` from disk in headless Chromium (no network) and write a `width` x `height` PNG to `out`."""
    browser = browser or find_browser()
    if browser is None:
        raise FileNotFoundError("no Chromium found (tried " + ", ".join(BROWSERS) + ")")
    with tempfile.TemporaryDirectory() as profile:
        subprocess.run(
            [
                browser, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                f"--user-data-dir={profile}", f"--window-size={width},{height}",
                f"--screenshot={out.resolve()}", html.resolve().as_uri(),
            ],
            check=True, capture_output=True, timeout=120,
        )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("html", type=Path, help="report/report.html of a study")
    parser.add_argument("out", type=Path, help="the PNG to write")
    parser.add_argument("--width", type=int, default=1280)
    parser.add_argument("--height", type=int, default=6000)
    args = parser.parse_args()
    if find_browser() is None:
        print("no Chromium installed: apt-get install chromium (or put chromium on PATH)", file=sys.stderr)
        return NO_BROWSER
    screenshot(args.html, args.out, args.width, args.height)
    print(f"Wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
