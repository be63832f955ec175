"""Progress of long work (a bar on a terminal, lines in a log file), tables that a log file holds
uncut, and the note that the model's kernels are compiling."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn


@contextmanager
def progress(enabled: bool | None = None) -> Iterator[Progress]:
    """A rich ``Progress`` bar when stderr is a terminal (or ``enabled``); otherwise lines a log file
    can hold (``ProgressLines``: a line at the start, each tenth and the end), the same calls."""
    if enabled is None:
        enabled = sys.stderr.isatty()
    if not enabled:
        from wearbench.compute import ProgressLines

        with ProgressLines() as lines:
            yield lines
        return
    bar = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                   TextColumn("{task.fields[info]}"), TimeElapsedColumn(), transient=False)
    with bar:
        yield bar


def console() -> Console:
    """A rich console for tables on stdout that never cuts a table to 80 columns off a terminal."""
    return Console() if sys.stdout.isatty() else Console(width=100_000, soft_wrap=True)


COMPILING = "compiling the model's kernels (once per model version, about a minute)..."


def note_compiling() -> bool:
    """Say on stderr (one line) that the model's numba kernels are about to compile, if their on-disk
    cache is cold (first run after installing or changing the model); True if it said so."""
    from wearbench.model import jit_cache

    if any(jit_cache.numba_cache_dir().rglob("integrators.run_loop-*.nbi")):
        return False
    print(COMPILING, file=sys.stderr, flush=True)
    return True
