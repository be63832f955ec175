"""A progress bar for long work that stays quiet when output is not a terminal; the note that the
model's kernels are compiling."""

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


COMPILING = "compiling the model's kernels (once per model version, about a minute)..."


def note_compiling() -> bool:
    """Say on stderr (one line) that the model's numba kernels are about to compile, if their on-disk
    cache is cold (first run after installing or changing the model); True if it said so."""
    from wearbench.model import jit_cache

    if any(jit_cache.numba_cache_dir().rglob("integrators.run_loop-*.nbi")):
        return False
    print(COMPILING, file=sys.stderr, flush=True)
    return True
