"""Pictures of finished runs for their pages: the figure `trials log show` draws (`trials.run_figure.log_figure`) from
runs/<code>.mcap, as PNG bytes kept in memory, drawn when first asked for and again only when the log is replaced."""

from __future__ import annotations

import threading

from robot_logs.run_log import read_run
from trials.run_figure import log_figure
from trials.study import StudyFolder

#: The picture's resolution on a run page: about 750 pixels across, its 10 pt text about 17 pixels high
#: (`trials log show` writes its PNG at --dpi, 200 by default, for print).
PAGE_DPI = 120


class RunPictures:
    """The run pictures of one study, each drawn once per version of its log."""

    def __init__(self, folder: StudyFolder) -> None:
        self.folder = folder
        self._drawn: dict[str, tuple[tuple[int, int, int], bytes]] = {}
        self._lock = threading.Lock()

    def png(self, code: str) -> bytes | None:
        """Run `code`'s picture as PNG; None when it has no log. LogError for a log that cannot be read."""
        path = self.folder.run_log(code)
        try:
            stat = path.stat()
        except FileNotFoundError:
            return None
        version = (stat.st_ino, stat.st_mtime_ns, stat.st_size)  # a replaced log is a new file (written, then renamed)
        with self._lock:  # one drawing at a time: the figures are large, and a page asks once
            drawn = self._drawn.get(code)
            if drawn is None or drawn[0] != version:
                drawn = (version, log_figure(read_run(path), code).png(PAGE_DPI))
                self._drawn[code] = drawn
        return drawn[1]
