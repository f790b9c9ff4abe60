"""How the study's CSV files are read and written: columns from a record dataclass, cells as text,
line-numbered rows, and atomic appends.

Each file has its own module (`trials.outcomes`, `trials.scores`, `trials.responses`) that uses
these; a bad file is a StudyError naming the file and line.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, fields
from datetime import datetime
from pathlib import Path
from typing import Any, TypeVar

from trials.atomic import one_writer, write_text
from trials.errors import StudyError
from trials.numbers import shown

Row = TypeVar("Row")

#: Participant and scorer codes: what a person types on a phone and the statistics group by.
MAX_CODE = 40
#: First characters that make a spreadsheet read a cell as a formula.
FORMULA_STARTS = ("=", "+", "-", "@")


def record_columns(record_type: type) -> tuple[str, ...]:
    """A file's columns: the fields of its record dataclass, in order."""
    return tuple(f.name for f in fields(record_type))


def cell(value: Any) -> str:
    """A value as the study's CSV files write it: empty for None, yes / no for a bool, 3 decimals for a float."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{value:.3f}"
    return str(value)


def utc_cell(cell: str, column: str = "recorded_utc", required: bool = False) -> str:
    """A time cell (recorded_utc, finished_utc): an ISO 8601 time with its UTC offset (it orders judgments
    against the unblinding), or empty unless `required`; ValueError naming `column` otherwise."""
    if not cell and not required:
        return cell
    try:
        when = datetime.fromisoformat(cell)
    except ValueError:
        raise ValueError(f"{column} must be an ISO 8601 time such as 2026-05-01T14:03:00+00:00, got {shown(cell)}") from None
    if when.tzinfo is None:
        raise ValueError(f"{column} must give its UTC offset (e.g. +00:00), got {shown(cell)}")
    return cell


def code_cell(cell: str, column: str) -> str:
    """A participant's or scorer's code: 1 to MAX_CODE printable characters, not beginning as a spreadsheet formula
    (FORMULA_STARTS would run as one when the file is opened); ValueError naming `column` otherwise."""
    if not cell:
        raise ValueError(f"{column} is empty")
    if len(cell) > MAX_CODE or not cell.isprintable():
        raise ValueError(f"{column} must be 1 to {MAX_CODE} printable characters, got {shown(cell)}")
    if cell.startswith(FORMULA_STARTS):
        raise ValueError(f"{column} must not begin with =, +, - or @ (a spreadsheet would run it as a formula), got {shown(cell)}")
    return cell


def text_cell(cell: str, column: str, limit: int) -> str:
    """A cell of free text (a note, a name) of at most `limit` characters, line breaks and tabs allowed but no other
    control character; ValueError naming `column` otherwise."""
    if len(cell) > limit or not "".join(" " if c in "\r\n\t" else c for c in cell).isprintable():
        raise ValueError(f"{column} must be at most {limit} characters of text, got {shown(cell)}")
    return cell


def record_cells(record: Any) -> dict[str, str]:
    """A record's fields as cells, by column name."""
    return {f.name: cell(getattr(record, f.name)) for f in fields(record)}


def record_row(record: Any, header: Sequence[str]) -> list[str]:
    """A record's cells in the order of `header` (a subset of its fields)."""
    cells = record_cells(record)
    return [cells[c] for c in header]


@dataclass(frozen=True)
class Table:
    """A CSV file's header and its rows with their line numbers (stripped cells)."""

    header: tuple[str, ...]
    rows: list[tuple[int, dict[str, str]]]


def read_rows(path: Path, same_width: bool) -> tuple[list[str], list[tuple[int, list[str]]]]:
    """A comma-separated UTF-8 file's header and its (line number, cells) rows, cells stripped.

    A byte order mark and CRLF line ends (spreadsheet re-saves) are read; blank lines are skipped.

    Raises:
        FileNotFoundError: no file.
        StudyError: binary or non-UTF-8 content, `;` separators, no header, or (with `same_width`)
            a row whose number of cells differs from the header's, naming the file and line.
    """
    data = path.read_bytes()
    nul = data.find(b"\x00")
    if nul >= 0:
        raise StudyError(f"{path} holds binary data (a NUL byte at byte {nul}), not CSV text")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise StudyError(f"{path} is not UTF-8 text ({exc.reason} at byte {exc.start}); save it as UTF-8 CSV") from None
    reader = csv.reader(io.StringIO(text, newline=""))
    rows: list[tuple[int, list[str]]] = []
    try:
        for cells in reader:
            if any(c.strip() for c in cells):
                rows.append((reader.line_num, [c.strip() for c in cells]))
    except csv.Error as exc:
        raise StudyError(f"{path} line {reader.line_num}: {exc}") from None
    if not rows:
        raise StudyError(f"{path} is empty: it has no header line")
    (_, header), body = rows[0], rows[1:]
    if len(header) == 1 and ";" in header[0]:
        raise StudyError(f"{path} is separated by ';', not ',' (a spreadsheet's re-save?); save it as comma-separated CSV")
    for line, cells in body:
        if same_width and len(cells) != len(header):
            raise StudyError(f"{path} line {line}: {len(cells)} cells, but the header has {len(header)} ({','.join(header)})")
    return header, body


def read_table(path: Path, required: Sequence[str]) -> Table:
    """A CSV file with a header (an empty table when there is no file); StudyError when a required column
    is missing. A short row's missing cells read as empty, and cells beyond the header are ignored."""
    try:
        header, rows = read_rows(path, same_width=False)
    except FileNotFoundError:
        return Table((), [])
    missing = [c for c in required if c not in header]
    if missing:
        raise StudyError(f"{path}: missing column(s) {', '.join(missing)} (expected {', '.join(required)})")
    return Table(tuple(header), [(line, {name: cells[i] if i < len(cells) else "" for i, name in enumerate(header)}) for line, cells in rows])


def parse_rows(path: Path, table: Table, parse: Callable[[dict[str, str]], Row]) -> list[Row]:
    """Parse each row with `parse(row)`; a ValueError from it becomes a StudyError naming the line."""
    records = []
    for line, row in table.rows:
        try:
            records.append(parse(row))
        except ValueError as exc:
            raise StudyError(f"line {line} of {path.name}: {exc}") from None
    return records


def table_text(header: Sequence[str], rows: Iterable[Sequence[str]], with_header: bool = True) -> str:
    """CSV text: the header line (unless left out), then one line per row."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    if with_header:
        writer.writerow(header)
    writer.writerows(rows)
    return buffer.getvalue()


def append_rows(path: Path, header: Sequence[str], rows: Iterable[Sequence[str]], widen: bool = False) -> None:
    """Add rows to a CSV file (creating it with `header`), rewriting it atomically. With `widen`, a file
    whose columns are the first ones of `header` gets the new columns, empty in its earlier rows. A file a spreadsheet
    re-saved (a byte-order mark, CRLF line ends) is taken as it reads and rewritten plainly. One process at a time
    (`trials.atomic.one_writer`), so concurrent writers never lose each other's rows."""
    with one_writer(path):
        _append_rows(path, header, list(rows), widen)


def _append_rows(path: Path, header: Sequence[str], rows: Sequence[Sequence[str]], widen: bool) -> None:
    existing = path.read_bytes().decode("utf-8-sig") if path.exists() else ""
    if "\r" in existing:  # re-saved by a spreadsheet (CRLF line ends): rewritten with this module's line ends
        found, earlier = read_rows(path, same_width=False)
        existing = table_text(found, (cells for _, cells in earlier))
    if existing:
        found = next(csv.reader(io.StringIO(existing)), [])
        if widen and len(found) < len(header) and tuple(found) == tuple(header[:len(found)]):
            _, earlier = read_rows(path, same_width=False)
            padding = [""] * (len(header) - len(found))
            existing = table_text(header, (cells + padding for _, cells in earlier))
        elif tuple(found) != tuple(header):
            raise StudyError(f"{path} has columns {', '.join(found)}; expected {', '.join(header)}")
    separator = "" if not existing or existing.endswith("\n") else "\n"
    write_text(path, existing + separator + table_text(header, rows, with_header=not existing))
