"""report.html read in a real browser (Debian's Chromium through Selenium, as the console's tests do): its table of
contents links every section and figure and each link lands on its target, and, printed on A4 as the page's own
@page rule lays it out, no figure's text is smaller than the body text.

A figure's text size and width are read from its SVG beside the report (matplotlib writes each text as glyphs
scaled by font size / 100, in a picture measured in points), independently of what the page claims."""

from __future__ import annotations

import base64
import io
import re
from dataclasses import dataclass
from pathlib import Path

import matplotlib
import pytest
from PIL import Image

from analysis.document import Figure, Heading, Paragraph, to_html
from robot_logs.figure_files import Rendered
from tests.support.console import browser, need_chromium
from tests.support.synthetic_study import design, run_all
from trials.cli import main

pytestmark = pytest.mark.slow


@pytest.fixture(autouse=True)
def _chromium() -> None:
    need_chromium()

#: A4's width, mm; CSS pixels per inch and per point.
A4_MM = 210.0
PX_PER_IN, PX_PER_PT = 96.0, 96.0 / 72.0
#: A text drawn as glyphs: matplotlib's SVG scales each by its font size / 100, flipping y.
GLYPHS = re.compile(r"scale\(([\d.]+) -\1\)")
SVG_WIDTH = re.compile(r'<svg[^>]*\bwidth="([\d.]+)pt"')

CONTENTS = """
const nav = document.getElementById('contents');
const links = [...nav.querySelectorAll('a')].map(a => [a.getAttribute('href'), a.textContent]);
const targets = [...document.querySelectorAll('h2, h3, h4, figure')].filter(e => !nav.contains(e))
    .map(e => [e.tagName, e.id, e.tagName === 'FIGURE' ? '' : e.textContent]);
const resolved = links.map(([href]) => { const e = document.getElementById(href.slice(1)); return e === null ? null : e.id; });
return [links, targets, resolved];
"""
PAGE_RULE = """
for (const sheet of document.styleSheets) for (const rule of sheet.cssRules)
  if (rule instanceof CSSPageRule) return [rule.style.getPropertyValue('size'), rule.style.getPropertyValue('margin-left'),
                                           rule.style.getPropertyValue('margin-right')];
return null;
"""
PRINTED = """
return [parseFloat(getComputedStyle(document.body).fontSize),
        [...document.querySelectorAll('figure')].map(f => { const img = f.querySelector('img');
          return [f.id, img.getBoundingClientRect().width, img.naturalWidth, img.getAttribute('src'), img.dataset.smallestFontPt]; })];
"""


@dataclass(frozen=True)
class Printed:
    """One figure as the printed page shows it: its smallest text, points, after scaling to the width it prints at."""

    figure: str
    smallest_pt: float
    printed_pt: float


def svg_text(svg: str) -> tuple[float, float]:
    """(smallest font size, pt; width, in) of a figure from its SVG."""
    sizes = [100 * float(scale) for scale in GLYPHS.findall(svg)]
    return min(sizes), float(SVG_WIDTH.search(svg).group(1)) / 72


def mm(value: str) -> float:
    assert value.endswith("mm"), value
    return float(value[:-2])


def print_on_a4(driver, page: Path, svgs: dict[str, str]) -> tuple[float, list[Printed]]:
    """Lay `page` out as printed on A4 (print media, the column its @page margins leave), and measure the body text
    (pt) and each figure's smallest text as printed; `svgs` maps each figure's id to its SVG."""
    driver.get(page.as_uri())
    size, left, right = driver.execute_script(PAGE_RULE)
    assert size.lower() == "a4"
    column_px = (A4_MM - mm(left) - mm(right)) / 25.4 * PX_PER_IN
    driver.execute_cdp_cmd("Emulation.setEmulatedMedia", {"media": "print"})
    driver.execute_cdp_cmd("Emulation.setDeviceMetricsOverride", {"width": round(column_px), "height": 1000, "deviceScaleFactor": 1, "mobile": False})
    body_px, figures = driver.execute_script(PRINTED)
    printed = []
    for anchor, shown_px, natural_px, source, claimed in figures:
        smallest, width_in = svg_text(svgs[anchor])
        png = Image.open(io.BytesIO(base64.b64decode(source.split(",", 1)[1])))
        assert natural_px / png.info["dpi"][0] == pytest.approx(width_in, rel=0.01)  # the PNG shown is the SVG's drawing
        assert float(claimed) == pytest.approx(smallest, abs=0.01)  # the page's own record of the figure is true
        printed.append(Printed(anchor, smallest, smallest * shown_px / (width_in * PX_PER_IN)))
    driver.execute_cdp_cmd("Emulation.clearDeviceMetricsOverride", {})
    driver.execute_cdp_cmd("Emulation.setEmulatedMedia", {"media": ""})
    return body_px / PX_PER_PT, printed


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """report/ of the blinded 18-run A/B plan, every run synthesised, simulated judgments (seed 5)."""
    root = tmp_path_factory.mktemp("report") / "study"
    run_all(design(root))
    assert main(["respond", "--simulate", "--seed", "5", "--study", str(root)]) == 0
    assert main(["report", "--study", str(root)]) == 0
    return root / "report"


@pytest.fixture(scope="module")
def chromium():
    with browser((1280, 900)) as driver:
        yield driver


def test_the_contents_link_every_section_and_figure_and_each_link_lands(report: Path, chromium) -> None:
    chromium.get((report / "report.html").as_uri())
    links, targets, resolved = chromium.execute_script(CONTENTS)
    assert len(targets) > 20 and sum(tag == "FIGURE" for tag, _, _ in targets) == 6
    assert all(anchor for _, anchor, _ in targets) and len({anchor for _, anchor, _ in targets}) == len(targets)
    assert [href for href, _ in links] == [f"#{anchor}" for _, anchor, _ in targets]  # every one, in the page's order
    assert resolved == [anchor for _, anchor, _ in targets]
    headings = [(href, text) for (href, text), (tag, _, _) in zip(links, targets) if tag != "FIGURE"]
    assert [text for _, text in headings] == [text for tag, _, text in targets if tag != "FIGURE"]
    assert [text for (_, text), (tag, _, _) in zip(links, targets) if tag == "FIGURE"][:2] == ["Figure 1: correlation map", "Figure 2: score distribution"]
    middle = links[len(links) // 2][0]
    chromium.find_element("css selector", f'#contents a[href="{middle}"]').click()
    scrolled, top = chromium.execute_script(f"return [window.scrollY, document.getElementById('{middle[1:]}').getBoundingClientRect().top];")
    assert scrolled > 2000 and abs(top) < 2  # the page scrolled to put the section at the top


def test_no_figure_prints_smaller_than_the_body_text_on_a4(report: Path, chromium) -> None:
    svgs = {f"figure-{path.stem}": path.read_text() for path in (report / "figures").glob("*.svg")}
    body_pt, printed = print_on_a4(chromium, report / "report.html", svgs)
    assert body_pt == pytest.approx(10.0, abs=0.01)
    assert len(printed) == 6
    assert [p for p in printed if p.printed_pt < body_pt - 0.01] == []


def test_a_figure_drawn_wide_with_small_text_is_caught(tmp_path: Path, chromium) -> None:
    """The same measurement on a page with one figure drawn 9 in wide with 7 pt text: it prints at about 4.7 pt."""
    matplotlib.use("Agg")
    from matplotlib.figure import Figure as MplFigure

    drawn = MplFigure(figsize=(9.0, 3.0))
    axes = drawn.add_subplot()
    axes.plot([0, 1], [0, 1])
    axes.tick_params(labelsize=7)
    axes.set_title("wide", fontsize=7)
    image = Rendered(drawn)
    page = tmp_path / "page.html"
    page.write_text(to_html("wide", [Heading("One"), Paragraph("text"), Figure("wide", image, "a wide figure")]), encoding="utf-8")
    body_pt, (printed,) = print_on_a4(chromium, page, {"figure-wide": image.svg().decode()})
    assert printed.smallest_pt == pytest.approx(7.0)
    assert printed.printed_pt == pytest.approx(7.0 * 6.3 / image.width_in, rel=0.02) and printed.printed_pt < body_pt
