"""Times as the console shows them: the laptop's local time with its zone (the `local` filter of every template), from
the UTC times the study's files keep. The files stay in UTC; only what a page shows is local."""

from __future__ import annotations

from datetime import UTC, datetime


def _local(utc: str) -> datetime | None:
    """An ISO time from a study file as a local time; None for a blank cell or text that is no time."""
    try:
        moment = datetime.fromisoformat(utc.strip())
    except ValueError:
        return None
    return (moment if moment.tzinfo is not None else moment.replace(tzinfo=UTC)).astimezone()


def local_time(utc: str) -> str:
    """`utc` in local time to the minute with the zone's abbreviation (its offset where it has none), e.g.
    "2026-05-01 12:00 CEST"; a blank cell stays blank and text that is no time is shown as it is."""
    moment = _local(utc)
    if moment is None:
        return utc
    zone = moment.strftime("%Z") or moment.isoformat()[-6:]
    return f"{moment:%Y-%m-%d %H:%M} {zone}"


def local_day(utc: str) -> str:
    """The local date of `utc` (YYYY-MM-DD): the field day a time belongs to; the text itself when it is no time."""
    moment = _local(utc)
    return utc if moment is None else f"{moment:%Y-%m-%d}"
