"""Render a study's report.html in headless Chromium and save a screenshot of the whole page, to check it by eye.

    python scripts/screenshot_report.py STUDY/report/report.html shot.png [--width 1280] [--height N]

The page's height is measured first (the report is self-contained, so a copy with a measuring script
renders the same), and the screenshot is that tall unless --height says otherwise. Exits 0 with the
screenshot written, 3 when no Chromium is installed (Debian: apt-get install chromium, or
chromium-headless-shell).
"""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

#: Chromium-like browsers, by the name on PATH: Debian's chromium and chromium-headless-shell, Ubuntu's
#: chromium-browser, Google Chrome, and the headless_shell of Chrome for Testing.
BROWSERS = ("chromium", "chromium-headless-shell", "chromium-browser", "google-chrome", "google-chrome-stable", "headless_shell")
#: Where Debian installs the headless shell when it is not linked onto PATH.
INSTALLED = (Path("/usr/lib/chromium/chromium-headless-shell"), Path("/usr/lib/chromium/headless_shell"))
NO_BROWSER = 3
#: Chromium cannot capture taller than this in one screenshot (its largest texture).
MAX_HEIGHT = 16384
MEASURE = ("<script>window.addEventListener('load', () => document.body.setAttribute('data-page-height', "
           "Math.ceil(document.documentElement.getBoundingClientRect().height)));</script>")


def find_browser() -> str | None:
    """The first Chromium-like browser on PATH, else Debian's headless shell where it installs it."""
    found = next((path for name in BROWSERS if (path := shutil.which(name))), None)
    return found or next((str(path) for path in INSTALLED if path.is_file()), None)


def _chromium(browser: str, width: int, height: int, *arguments: str) -> subprocess.CompletedProcess[str]:
    headless = [] if Path(browser).name in ("chromium-headless-shell", "headless_shell") else ["--headless"]
    with tempfile.TemporaryDirectory() as profile:
        return subprocess.run(
            [browser, *headless, "--no-sandbox", "--disable-gpu", "--hide-scrollbars", f"--user-data-dir={profile}",
             f"--window-size={width},{height}", "--virtual-time-budget=5000", *arguments],
            check=True, capture_output=True, text=True, timeout=120,
        )


def page_height(html: Path, width: int, browser: str) -> int:
    """The rendered height of `html` (px) at `width`, measured by a script in a copy of the page."""
    text = html.read_text(encoding="utf-8")
    with tempfile.TemporaryDirectory() as folder:
        copy = Path(folder) / html.name
        copy.write_text(text.replace("</body>", MEASURE + "</body>", 1) if "</body>" in text else text + MEASURE, encoding="utf-8")
        dom = _chromium(browser, width, 1000, "--dump-dom", copy.as_uri()).stdout
    found = re.search(r'data-page-height="(\d+)"', dom)
    if found is None:
        raise RuntimeError(f"could not measure the height of {html} in {browser}")
    return int(found.group(1))


def screenshot(html: Path, out: Path, width: int = 1280, height: int | None = None, browser: str | None = None) -> int:
    """Load `html` from disk in headless Chromium (no network) and write a `width`-wide PNG of the whole page (or
    `height` px of it) to `out`; returns the height captured."""
    browser = browser or find_browser()
    if browser is None:
        raise FileNotFoundError("no Chromium found (tried " + ", ".join(BROWSERS) + ")")
    tall = min(height or page_height(html, width, browser), MAX_HEIGHT)
    _chromium(browser, width, tall, f"--screenshot={out.resolve()}", html.resolve().as_uri())
    return tall


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("html", type=Path, help="report/report.html of a study")
    parser.add_argument("out", type=Path, help="the PNG to write")
    parser.add_argument("--width", type=int, default=1280)
    parser.add_argument("--height", type=int, help=f"capture this many pixels (default: the whole page, at most {MAX_HEIGHT})")
    args = parser.parse_args()
    if find_browser() is None:
        print("no Chromium installed: apt-get install chromium (or chromium-headless-shell, or put one on PATH)", file=sys.stderr)
        return NO_BROWSER
    tall = screenshot(args.html, args.out, args.width, args.height)
    print(f"Wrote {args.out} ({args.width} x {tall} px)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
