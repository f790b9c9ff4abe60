"""A report as a list of blocks, rendered to Markdown (figures as files), to one self-contained HTML page,
and each table to CSV.

Inline text may mark `code` with backticks and **bold** with double asterisks; both renderers understand them.
"""

from __future__ import annotations

import base64
import csv
import html
import io
import math
import re
from dataclasses import dataclass, field

from PIL import Image

from robot_logs.figure_files import DEFAULT_DPI, Rendered


@dataclass(frozen=True)
class Heading:
    text: str
    level: int = 2


@dataclass(frozen=True)
class Paragraph:
    text: str


@dataclass(frozen=True)
class Bullets:
    items: list[str]


@dataclass(frozen=True)
class Table:
    header: list[str]
    rows: list[list[str]]
    caption: str = ""
    align_right: set[int] = field(default_factory=set)


@dataclass(frozen=True)
class Figure:
    """A figure; `name` is its file stem under report/figures/ (written as .png and .svg)."""

    name: str
    image: Rendered
    caption: str
    #: A few words for the report's table of contents; the file stem when empty.
    title: str = ""


Block = Heading | Paragraph | Bullets | Table | Figure

_CODE = re.compile(r"`([^`]+)`")
_BOLD = re.compile(r"\*\*([^*]+)\*\*")
_NUMBER = ' class="num"'
#: What Markdown (CommonMark, GitHub's tables) may read as markup within a line, escaped in literal text: an
#: underscore only where it could open or close emphasis (not inside a word such as noise_std_m).
_MARKDOWN_PUNCTUATION = re.compile(r"[\\`*\[\]#|~]|(?<![0-9A-Za-z])_|_(?![0-9A-Za-z])")
#: What opens a list, a quote or a thematic break at the start of a block: - + >, or a number and . or ).
_BLOCK_START = re.compile(r"^(\d+(?=[.)])|(?=[-+>]))")
#: First characters that make a spreadsheet read a cell as a formula (OWASP's list).
_FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")

STYLE = """
body { font-family: "DejaVu Sans", Arial, sans-serif; max-width: 1100px; margin: 2em auto; padding: 0 1em; color: #222; line-height: 1.4; }
h1 { border-bottom: 2px solid #444; padding-bottom: .2em; }
h2 { border-bottom: 1px solid #bbb; margin-top: 2em; }
table { border-collapse: collapse; margin: .8em 0 1.2em; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: .25em .6em; vertical-align: top; }
th { background: #f0f0f0; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
caption { caption-side: bottom; font-size: .85em; color: #555; text-align: left; padding-top: .3em; }
figure { margin: 1em 0 2em; }
figure img { max-width: 100%; height: auto; border: 1px solid #ddd; }
figcaption { font-size: .85em; color: #555; }
code { background: #f4f4f4; padding: 0 .2em; }
nav#contents ol { margin: .2em 0; padding-left: 1.4em; }
@page { size: A4; margin: 20mm 25mm; }
@media print {
  body { font-size: 10pt; max-width: none; margin: 0; padding: 0; }
  figure, table, tr { break-inside: avoid; }
  h2, h3, h4 { break-after: avoid; }
}
"""
#: The id of the table of contents; headings never take it.
CONTENTS = "contents"
#: CSS pixels per inch: an image `width` of inches x this shows a figure at the size it was drawn.
CSS_PX_PER_IN = 96


def _inline_html(text: str) -> str:
    escaped = html.escape(text, quote=False)
    return _BOLD.sub(r"<strong>\1</strong>", _CODE.sub(r"<code>\1</code>", escaped))


def _inline_markdown(text: str, cell: bool = False, block: bool = False) -> str:
    """Inline text as Markdown that shows what `_inline_html` shows: `code` and **bold** stay markup, the rest is
    literal (& and < as entities, so no HTML; Markdown's punctuation backslash-escaped; line breaks as spaces), so
    text people typed (a scorer's note, a study's name, a level) neither injects HTML nor restyles the report. In a
    table `cell` a code span's | is escaped too; a `block` (heading, paragraph, list item, caption) loses the spaces
    around it and has what would open a list, a quote or a code block at its start escaped."""
    text = " ".join(text.splitlines())
    parts = []
    for k, piece in enumerate(_CODE.split(text.strip() if block else text)):
        if k % 2:  # a code span: literal to Markdown already
            parts.append("`" + (piece.replace("|", "\\|") if cell else piece) + "`")
            continue
        for j, plain in enumerate(_BOLD.split(piece)):
            plain = _MARKDOWN_PUNCTUATION.sub(r"\\\g<0>", plain.replace("&", "&amp;").replace("<", "&lt;"))
            parts.append(f"**{plain}**" if j % 2 else plain)
    written = "".join(parts)
    return _BLOCK_START.sub(r"\1\\", written, count=1) if block else written


def to_markdown(title: str, blocks: list[Block], figure_dir: str = "figures") -> str:
    """The report as Markdown; figures are linked as `figure_dir/name`."""
    lines = [f"# {_inline_markdown(title, block=True)}", ""]
    for block in blocks:
        if isinstance(block, Heading):
            lines += ["#" * block.level + " " + _inline_markdown(block.text, block=True), ""]
        elif isinstance(block, Paragraph):
            lines += [_inline_markdown(block.text, block=True), ""]
        elif isinstance(block, Bullets):
            lines += [f"- {_inline_markdown(item, block=True)}" for item in block.items] + [""]
        elif isinstance(block, Table):
            rule = ["---:" if i in block.align_right else "---" for i in range(len(block.header))]
            lines.append("| " + " | ".join(_inline_markdown(h, cell=True) for h in block.header) + " |")
            lines.append("| " + " | ".join(rule) + " |")
            lines += ["| " + " | ".join(_inline_markdown(c, cell=True) for c in row) + " |" for row in block.rows]
            lines += ([""] + [f"*{_inline_markdown(block.caption, block=True)}*"] if block.caption else []) + [""]
        else:
            caption = _inline_markdown(block.caption, block=True)
            lines += [f"![{caption}]({figure_dir}/{block.name}.png)", "", f"*{caption}*", ""]
    return "\n".join(lines).rstrip() + "\n"


def _anchors(blocks: list[Block]) -> dict[int, str]:
    """An id for each heading (from its text, unique on the page) and each figure (`figure-<name>`), by block index."""
    taken = {CONTENTS}
    anchors: dict[int, str] = {}
    for index, block in enumerate(blocks):
        if isinstance(block, Heading | Figure):
            base = f"figure-{block.name}" if isinstance(block, Figure) else re.sub(r"[^a-z0-9]+", "-", _plain(block.text).lower()).strip("-")
            anchor, count = base or "section", 1
            while anchor in taken:
                count += 1
                anchor = f"{base}-{count}"
            taken.add(anchor)
            anchors[index] = anchor
    return anchors


def _contents(blocks: list[Block], anchors: dict[int, str], numbers: dict[int, int]) -> str:
    """The table of contents: every heading nested by level, each figure under the section (h2 or h3) it is in,
    after that section's own subsections."""
    entries: list[tuple[int, str, str]] = []
    section = 2
    for index, block in enumerate(blocks):
        if isinstance(block, Heading):
            section = min(block.level, 3)
            entries.append((block.level, anchors[index], _inline_html(block.text)))
        elif isinstance(block, Figure):
            entries.append((section + 1, anchors[index], f"Figure {numbers[index]}: {_inline_html(block.title or block.name)}"))
    if not entries:
        return ""
    top = min(level for level, _, _ in entries)
    parts, depth = [], 0
    for level, anchor, text in entries:
        level = min(level - top + 1, depth + 1)  # a level skipped nests one step, not an empty list
        if level > depth:
            parts.append("<ol>")
        else:
            parts.append("</li>" + "</ol></li>" * (depth - level))
        depth = level
        parts.append(f'<li><a href="#{anchor}">{text}</a>')
    parts.append("</li></ol>" * depth)
    return f'<nav id="{CONTENTS}"><h2>Contents</h2>{"".join(parts)}</nav>'


def _figure_html(block: Figure, anchor: str, number: int) -> str:
    """A figure as an embedded PNG shown at the width it was drawn (at most the column's), with its smallest font
    size in `data-smallest-font-pt`, so a reader or a test can tell how large its text prints."""
    png = block.image.png()
    width, height = (round(size / DEFAULT_DPI * CSS_PX_PER_IN) for size in Image.open(io.BytesIO(png)).size)
    data = base64.b64encode(png).decode("ascii")
    return (f'<figure id="{anchor}"><img src="data:image/png;base64,{data}" width="{width}" height="{height}" '
            f'data-smallest-font-pt="{block.image.smallest_font_pt:g}" alt="{html.escape(_plain(block.caption))}">'
            f"<figcaption><strong>Figure {number}.</strong> {_inline_html(block.caption)}</figcaption></figure>")


def to_html(title: str, blocks: list[Block]) -> str:
    """The report as one HTML page with a table of contents linked to every heading and figure, its figures
    embedded as base64 PNG (no outside references)."""
    anchors = _anchors(blocks)
    numbers = {index: n for n, index in enumerate((i for i, b in enumerate(blocks) if isinstance(b, Figure)), start=1)}
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{html.escape(title)}</title>",
        f"<style>{STYLE}</style></head><body>",
        f"<h1>{html.escape(title)}</h1>",
        _contents(blocks, anchors, numbers),
    ]
    for index, block in enumerate(blocks):
        if isinstance(block, Heading):
            parts.append(f'<h{block.level} id="{anchors[index]}">{_inline_html(block.text)}</h{block.level}>')
        elif isinstance(block, Paragraph):
            parts.append(f"<p>{_inline_html(block.text)}</p>")
        elif isinstance(block, Bullets):
            parts.append("<ul>" + "".join(f"<li>{_inline_html(item)}</li>" for item in block.items) + "</ul>")
        elif isinstance(block, Table):
            head = "".join(f"<th>{_inline_html(h)}</th>" for h in block.header)
            body = "".join(
                "<tr>" + "".join(f"<td{_NUMBER if i in block.align_right else ''}>{_inline_html(c)}</td>" for i, c in enumerate(row)) + "</tr>"
                for row in block.rows
            )
            caption = f"<caption>{_inline_html(block.caption)}</caption>" if block.caption else ""
            parts.append(f"<table>{caption}<thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>")
        else:
            parts.append(_figure_html(block, anchors[index], numbers[index]))
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"


def _plain(text: str) -> str:
    """Inline markup removed, for CSV cells."""
    return _BOLD.sub(r"\1", _CODE.sub(r"\1", text))


def csv_cell(text: str) -> str:
    """A CSV cell: markup removed, and text a spreadsheet would run as a formula (a leading =, +, -, @, tab or
    carriage return, not a number) shown as text by a leading apostrophe, as OWASP advises."""
    cell = _plain(text)
    if cell.startswith(_FORMULA_STARTS):
        try:
            if math.isfinite(float(cell)):
                return cell
        except ValueError:
            pass
        return "'" + cell
    return cell


def to_csv(table: Table) -> str:
    """A table as CSV: its header and rows, markup removed and safe for spreadsheets (the caption stays in the
    report)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow([csv_cell(h) for h in table.header])
    writer.writerows([[csv_cell(c) for c in row] for row in table.rows])
    return buffer.getvalue()


def table_names(blocks: list[Block]) -> list[tuple[str, Table]]:
    """Each table with a file stem from the heading above it (numbered when a heading has several):
    stable names for report/tables/."""
    named: list[tuple[str, Table]] = []
    heading, count = "report", 0
    for block in blocks:
        if isinstance(block, Heading):
            heading, count = re.sub(r"[^a-z0-9]+", "_", block.text.lower()).strip("_") or "section", 0
        elif isinstance(block, Table):
            count += 1
            named.append((heading if count == 1 else f"{heading}_{count}", block))
    return named
