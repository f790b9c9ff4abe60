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

#: PNG resolution (dots per inch) unless a command's --dpi says otherwise; SVG has none. 200 keeps 10 pt text
#: sharp on paper and on high-density screens.
DEFAULT_DPI = 200
#: The resolutions --dpi accepts.
MIN_DPI, MAX_DPI = 50, 1200
#: Every saved figure is written in each of these formats, by file suffix.
FORMATS = (".png", ".svg")
#: The width of a report's text column printed on A4 (210 mm less 25 mm margins each side), inches.
PRINT_COLUMN_IN = 160 / 25.4
#: The body text of a printed report, points: no figure's text may print smaller.
BODY_TEXT_PT = 10.0
#: Blank border around a saved figure, inches.
PAD_IN = 0.05
#: The widest a figure may be drawn, inches: saved with its border, it fits the printed column at full size.
FIGURE_WIDTH_IN = PRINT_COLUMN_IN - 2 * PAD_IN


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
        figure.savefig(buffer, format=suffix[1:], dpi=dpi, bbox_inches="tight", pad_inches=PAD_IN, metadata=metadata)
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

    @property
    def width_in(self) -> float:
        """The saved figure's width, inches: what is drawn and its border."""
        return float(self.figure.get_tightbbox().width) + 2 * PAD_IN

    @property
    def smallest_font_pt(self) -> float:
        """The size of the smallest text drawn (tick labels, legends, annotations, titles), points."""
        from matplotlib.text import Text

        sizes = [text.get_fontsize() for text in self.figure.findobj(Text) if text.get_visible() and text.get_text().strip()]
        return float(min(sizes, default=BODY_TEXT_PT))

    @property
    def printed_font_pt(self) -> float:
        """The smallest text's size once the figure is scaled down to fit a report column printed on A4, points."""
        return self.smallest_font_pt * min(1.0, PRINT_COLUMN_IN / self.width_in)

    def png(self, dpi: int = DEFAULT_DPI) -> bytes:
        return figure_bytes(self.figure, ".png", dpi)

    def svg(self) -> bytes:
        return figure_bytes(self.figure, ".svg")

    def files(self, stem: Path, dpi: int = DEFAULT_DPI) -> dict[Path, bytes]:
        """stem.png (at `dpi`) and stem.svg -> their bytes, to write together (`trials.atomic.write_files`)."""
        return {stem.with_name(stem.name + ".png"): self.png(dpi), stem.with_name(stem.name + ".svg"): self.svg()}
