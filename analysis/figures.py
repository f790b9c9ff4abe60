"""Figures shared by `trials design` and `trials report`, rendered off-screen to PNG bytes."""

from __future__ import annotations

import io

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure


def correlation_map_png(columns: list[str], correlations: np.ndarray, title: str) -> bytes:
    """JMP's colour map on correlations: |r| between model columns, white 0 to dark red 1."""
    size = 2.5 + 0.45 * len(columns)
    figure = Figure(figsize=(size + 1.5, size))
    axes = figure.add_subplot()
    image = axes.imshow(np.abs(correlations), cmap="Reds", vmin=0.0, vmax=1.0)
    axes.set_xticks(range(len(columns)), columns, rotation=60, ha="right", fontsize=8)
    axes.set_yticks(range(len(columns)), columns, fontsize=8)
    for (i, j), value in np.ndenumerate(correlations):
        if not np.isnan(value):
            axes.text(j, i, f"{abs(value):.2f}", ha="center", va="center", fontsize=6, color="white" if abs(value) > 0.6 else "black")
    figure.colorbar(image, ax=axes, label="|correlation|")
    axes.set_title(title)
    figure.tight_layout()
    buffer = io.BytesIO()
    FigureCanvasAgg(figure).print_png(buffer)
    return buffer.getvalue()
