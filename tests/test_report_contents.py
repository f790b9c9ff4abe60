"""report.html's table of contents, from the document's blocks: every heading by its level, each figure numbered in
its section, and ids that are unique however the headings repeat."""

from __future__ import annotations

import re
from html.parser import HTMLParser

import numpy as np
from matplotlib.figure import Figure as MplFigure

from analysis.document import Figure, Heading, Paragraph, to_html
from robot_logs.figure_files import Rendered


class Outline(HTMLParser):
    """The contents list as (depth, href, text), and every id on the page."""

    def __init__(self) -> None:
        super().__init__()
        self.entries: list[tuple[int, str, str]] = []
        self.ids: list[str] = []
        self._depth = 0
        self._in_nav = False
        self._href: str | None = None
        self._text = ""

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        values = dict(attrs)
        if values.get("id"):
            self.ids.append(values["id"] or "")
        self._in_nav |= tag == "nav"
        if self._in_nav and tag == "ol":
            self._depth += 1
        if self._in_nav and tag == "a":
            self._href, self._text = values.get("href"), ""

    def handle_endtag(self, tag: str) -> None:
        if self._in_nav and tag == "ol":
            self._depth -= 1
        self._in_nav &= tag != "nav"
        if tag == "a" and self._href is not None:
            self.entries.append((self._depth, self._href, self._text))
            self._href = None

    def handle_data(self, data: str) -> None:
        if self._href is not None:
            self._text += data


def small_figure() -> Rendered:
    figure = MplFigure(figsize=(3.0, 2.0))
    figure.add_subplot().plot(np.arange(3))
    return Rendered(figure)


def test_headings_nest_by_level_and_figures_sit_in_their_section():
    image = small_figure()
    blocks = [Heading("Study"), Paragraph("text"), Heading("Fits"), Heading("Outcome **metrics**", 3), Heading("gap (m)", 4),
              Heading("duration (s)", 4), Figure("residuals", image, "Residuals.", "residuals"), Heading("Fits"),
              Figure("map", image, "Map.")]
    outline = Outline()
    outline.feed(to_html("report", blocks))
    assert outline.entries == [
        (1, "#study", "Study"), (1, "#fits", "Fits"), (2, "#outcome-metrics", "Outcome metrics"), (3, "#gap-m", "gap (m)"),
        (3, "#duration-s", "duration (s)"), (3, "#figure-residuals", "Figure 1: residuals"), (1, "#fits-2", "Fits"),
        (2, "#figure-map", "Figure 2: map"),
    ]
    targets = [href[1:] for _, href, _ in outline.entries]
    assert set(targets) <= set(outline.ids) and len(outline.ids) == len(set(outline.ids))  # every link lands, no id twice
    page = to_html("report", blocks)
    shown = int(re.search(r'<figure id="figure-map"><img [^>]*width="(\d+)"', page).group(1))
    assert abs(shown - image.width_in * 96) <= 1  # shown at the size it was drawn: 96 CSS pixels an inch
    assert "<strong>Figure 2.</strong> Map." in page


def test_a_page_without_headings_has_no_contents():
    assert "<nav" not in to_html("empty", [Paragraph("nothing yet")])
