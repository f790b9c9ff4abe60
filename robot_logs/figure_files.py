"""Saving figures, the one way every command does it: PNG at a chosen resolution (for pages and slides) and
SVG (for print and editing), off-screen, cropped to what is drawn, byte for byte the same for the same figure.

matplotlib is imported only when a figure is saved, so a command can name `DEFAULT_DPI` in its --help cheaply.
Like `physical`, this module imports nothing of the project: every package saves its figures here (the
dependency rule in docs/architecture.md), NaviGAN's playback figures as well as the report's.
"""

from __future__ import annotations

import io
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from matplotlib.figure import Figure

#: PNG resolution (dots per inch) unless a command's --dpi says otherwise; SVG has none.
DEFAULT_DPI = 100
#: The resolutions --dpi accepts.
MIN_DPI, MAX_DPI = 50, 1200
#: Every saved figure is written in each of these formats, by file suffix.
FORMATS = (".png", ".svg")


@contextmanager
def quiet_glyphs() -> Iterator[None]:
    """A name in a script the font lacks draws as boxes, without matplotlib's warning per missing glyph."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r"Glyph \d+ .*missing from")
        yield


def figure_bytes(figure: Figure, suffix: str, dpi: int = DEFAULT_DPI) -> bytes:
    """`figure` as PNG or SVG bytes at `dpi`, cropped to what is drawn (a legend outside the axes included),
    with no date in the file, so the same figure gives the same bytes."""
    from matplotlib import rc_context
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    if suffix not in FORMATS:
        raise ValueError(f"figures are saved as {', '.join(FORMATS)}, not {suffix}")
    buffer = io.BytesIO()
    metadata = {"Date": None} if suffix == ".svg" else {}
    with quiet_glyphs(), rc_context({"svg.hashsalt": "navtrials"}):  # SVG element ids from a fixed salt, not at random
        FigureCanvasAgg(figure)  # off-screen, whatever pyplot's backend is
        figure.savefig(buffer, format=suffix[1:], dpi=dpi, bbox_inches="tight", pad_inches=0.05, metadata=metadata)
    return buffer.getvalue()


@dataclass(frozen=True)
class Rendered:
    """One drawn figure, saved on demand in every format.

    Its layout is settled once, when it is made, at the default resolution; so every format and every
    --dpi show the same picture, and saving in one never moves what another shows."""

    figure: Figure

    def __post_init__(self) -> None:
        from matplotlib.backends.backend_agg import FigureCanvasAgg

        with quiet_glyphs():
            FigureCanvasAgg(self.figure)
            self.figure.draw_without_rendering()
        self.figure.set_layout_engine("none")

    def png(self, dpi: int = DEFAULT_DPI) -> bytes:
        return figure_bytes(self.figure, ".png", dpi)

    def svg(self) -> bytes:
        return figure_bytes(self.figure, ".svg")

    def files(self, stem: Path, dpi: int = DEFAULT_DPI) -> dict[Path, bytes]:
        """stem.png (at `dpi`) and stem.svg -> their bytes, to write together (`trials.atomic.write_files`)."""
        return {stem.with_name(stem.name + ".png"): self.png(dpi), stem.with_name(stem.name + ".svg"): self.svg()}
