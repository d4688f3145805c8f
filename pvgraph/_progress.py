"""A one-line text progress bar for long runs (validation, sweeps).

The bar is drawn only when its stream is a terminal, so logs and pipes stay clean; callers
can always call :meth:`ProgressBar.update` without checking.
"""

from __future__ import annotations

import sys
from typing import TextIO

__all__ = ["ProgressBar"]

WIDTH = 30  # characters of the bar itself


class ProgressBar:
    """``label [#####     ] done/total detail`` on one line of ``stream`` (default stderr)."""

    def __init__(self, total: int, label: str, stream: TextIO | None = None):
        self.total = max(int(total), 1)
        self.label = label
        self.stream = stream if stream is not None else sys.stderr
        try:
            self.active = bool(self.stream.isatty())
        except (AttributeError, ValueError):  # no isatty, or a closed stream
            self.active = False

    def update(self, done: int, detail: str = "") -> None:
        """Redraw the bar for ``done`` finished items; ends the line when all are done."""
        if not self.active:
            return
        bar = "#" * int(WIDTH * min(done, self.total) / self.total)
        self.stream.write(f"\r{self.label} [{bar:{WIDTH}s}] {done}/{self.total} {detail:10s}")
        if done >= self.total:
            self.stream.write("\n")
        self.stream.flush()
