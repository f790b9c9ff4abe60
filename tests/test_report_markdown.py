"""Text people typed, written into the report's Markdown and CSV tables (issue 43): rendered by a CommonMark renderer
with GitHub's tables (markdown-it-py), report.md shows it as literal text, as report.html does, with no HTML, link,
emphasis or block it could inject; a CSV cell a spreadsheet would run as a formula is kept as text."""

from __future__ import annotations

import csv
import io
import re
from html.parser import HTMLParser

import pytest
from markdown_it import MarkdownIt

from analysis.document import Bullets, Heading, Paragraph, Table, to_csv, to_html, to_markdown
from analysis.report import DataTable

HOSTILE = [
    "<img src=x onerror=alert(1)>",
    "<script>alert(1)</script> & &lt;",
    "a | b | c",
    "*em* _em_ __strong__ ~~gone~~ noise_std_m",
    "[link](javascript:alert(1)) ![picture](http://example.com/x.png) <http://example.com>",
    "- a list item",
    "+ another",
    "12. a numbered item",
    "3) another",
    "> a quote",
    "# a heading",
    "---",
    "    indented code",
    "back\\slash and `one backtick",
    "two\nlines\n\n# and a heading",
    "[ref]: http://example.com",
]

#: What literal text may render as: these tags only (the table, paragraphs, the list the report itself makes).
ALLOWED_TAGS = {"h1", "h2", "p", "ul", "li", "table", "thead", "tbody", "tr", "th", "td", "em"}


class Rendered(HTMLParser):
    """The tags of rendered HTML, and the text of each element of the kind asked for."""

    def __init__(self, kind: str) -> None:
        super().__init__()
        self.kind, self.tags, self.texts, self._open = kind, [], [], False

    def handle_starttag(self, tag: str, attrs: list) -> None:
        self.tags.append(tag)
        if tag == self.kind:
            self._open = True
            self.texts.append("")

    def handle_endtag(self, tag: str) -> None:
        if tag == self.kind:
            self._open = False

    def handle_data(self, data: str) -> None:
        if self._open:
            self.texts[-1] += data


def rendered(source: str, kind: str) -> Rendered:
    parser = Rendered(kind)
    parser.feed(source)
    return parser


def visible(text: str) -> str:
    return re.sub(r"\s+", " ", text).strip()


@pytest.mark.parametrize("text", HOSTILE)
def test_typed_text_renders_literally_in_every_markdown_block(text: str) -> None:
    blocks = [Heading(text), Paragraph(text), Bullets([text]), Table(["note", "n"], [[text, "1"]], caption=text)]
    markdown = MarkdownIt("commonmark").enable("table").render(to_markdown(text, blocks))
    tags = set(rendered(markdown, "p").tags)
    assert tags <= ALLOWED_TAGS, tags - ALLOWED_TAGS  # no img, script, a, strong, code, pre, blockquote, ol, hr, h3 ...
    assert rendered(markdown, "em").tags.count("em") == 1  # the table's caption, which the report sets in italics
    literal = visible(text)
    for kind, count in (("h1", 1), ("h2", 1), ("p", 2), ("li", 1), ("td", 2), ("em", 1)):  # p: the paragraph, the caption
        texts = [visible(t) for t in rendered(markdown, kind).texts]
        assert len(texts) == count and texts[0] == literal, (kind, texts)
    html = to_html(text, blocks)  # the HTML page shows the same text
    assert visible(rendered(html, "p").texts[0]) == literal == visible(rendered(html, "td").texts[0])


def test_the_reports_own_markup_stays_markup() -> None:
    blocks = [Paragraph("**Primary result**: `trials report --unblind` | 3 < 4"), Table(["a"], [["`x|y` and **z**"]])]
    markdown = MarkdownIt("commonmark").enable("table").render(to_markdown("Report", blocks))
    assert "<p><strong>Primary result</strong>: <code>trials report --unblind</code> | 3 &lt; 4</p>" in markdown
    assert "<td><code>x|y</code> and <strong>z</strong></td>" in markdown


def test_csv_cells_a_spreadsheet_would_run_are_kept_as_text() -> None:
    cells = ["=HYPERLINK(\"http://example.com\")", "+1+1", "-2+3", "@SUM(A1)", "\tTAB", "-0.52", "+1.5", "1e-3", "-inf",
             "-0.5 (0.1)", "plain", "`=code`"]
    table = Table(["=header", "n"], [[cell, "1"] for cell in cells])
    rows = list(csv.reader(io.StringIO(to_csv(table))))
    assert rows[0] == ["'=header", "n"]
    assert [row[0] for row in rows[1:]] == ["'=HYPERLINK(\"http://example.com\")", "'+1+1", "'-2+3", "'@SUM(A1)", "'\tTAB", "-0.52",
                                            "+1.5", "1e-3", "'-inf", "'-0.5 (0.1)", "plain", "'=code"]


def test_number_tables_keep_numbers_and_formula_like_text_as_text() -> None:
    table = DataTable(["level"], [["=x"]], data_header=["=level", "estimate", "p"], data_rows=[["=HYPERLINK(1)", -0.5, None], ["B", 1.25, 0.01]])
    rows = list(csv.reader(io.StringIO(table.csv())))
    assert rows == [["'=level", "estimate", "p"], ["'=HYPERLINK(1)", "-0.5", ""], ["B", "1.25", "0.01"]]
