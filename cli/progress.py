"""A progress bar for long work that stays quiet when output is not a terminal."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager

from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn


@contextmanager
def progress(enabled: bool | None = None) -> Iterator[Progress]:
    """A rich ``Progress``; disabled (prints nothing) unless stderr is a terminal or ``enabled``."""
    if enabled is None:
        enabled = sys.stderr.isatty()
    bar = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                   TextColumn("{task.fields[info]}"), TimeElapsedColumn(), disable=not enabled,
                   transient=False)
    with bar:
        yield bar
