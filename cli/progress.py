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


@contextmanager
def compile_note_on() -> Iterator[None]:
    """While the block runs, say :data:`COMPILING` on stderr (once) when the model's numba kernels
    start to compile: the first run after installing or changing the model, minutes of silence
    otherwise. ``wearbench.cli.main`` runs every command in one, so each command that compiles says
    it, whichever and wherever (the sim backend's emulator, an ensemble, a study). A local cluster
    compiles in this process first when the cache is cold (``wearbench.compute.cluster``), so what
    its workers would have compiled is said too."""
    from numba.core import event

    with event.install_listener("numba:compile", compile_note()):
        yield


def compile_note():
    """A numba event listener that prints :data:`COMPILING` on stderr the first time a kernel of
    wearbench starts to compile. numba broadcasts "numba:compile" only when it compiles, never when
    it loads a kernel from its on-disk cache, so a warm run says nothing."""
    from numba.core import event

    class CompileNote(event.Listener):
        said = False

        def on_start(self, ev: event.Event) -> None:
            fn = getattr((ev.data or {}).get("dispatcher"), "py_func", None)
            if not self.said and getattr(fn, "__module__", "").startswith("wearbench."):
                self.said = True
                print(COMPILING, file=sys.stderr, flush=True)

        def on_end(self, ev: event.Event) -> None:
            pass

    return CompileNote()
