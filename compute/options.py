"""How a batch of simulations runs, as one record that travels from the command line to the builders.

:class:`Compute` holds where a batch runs (a running Dask scheduler's address, or a local cluster of
``workers`` processes; ``workers=0``: in this process, serially) and whether it shows progress. A
builder of theory (ensembles, an estimator, lives) takes one and calls :meth:`Compute.run` with its
batch: inside an active :func:`~wearbench.compute.compute_client` block the block's client is used,
so a command that builds several batches starts its cluster once. Imports the compute layer.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from wearbench.compute.cost import Cost

__all__ = ["DEFAULT", "QUIET", "SERIAL", "Compute"]


@dataclass(frozen=True)
class Compute:
    """Where a batch of simulations runs and whether it shows its progress."""

    scheduler: str | None = None  # a running cluster's address ("tcp://HOST:PORT"); None: local (or the active client)
    workers: int | None = None  # local cluster processes (None: the usable cores); 0: this process, serially
    progress: bool = True  # a progress bar on a terminal, lines in a log file

    def __post_init__(self) -> None:
        if self.workers is not None and self.workers < 0:
            raise ValueError(f"workers = {self.workers}: expected 0 (in-process) or more")

    def run(self, tasks: Sequence, *, label: str, cache: bool = True,
            on_result: Callable[[int, Any], None] | None = None, cost: Cost | None = None) -> list[Any]:
        """Run ``tasks`` (``compute.Task``) on the compute layer: results in task order, a ``TaskFailure``
        where one failed; ``label`` names the batch in its progress. Before anything runs, the batch
        is announced (with ``progress``): how many tasks, how many cached, and the CPU time of the rest
        priced by ``cost`` (``compute.cost``): the one place a batch says what it costs."""
        from wearbench.compute import run_tasks
        from wearbench.compute.cost import describe, estimate, workers_of

        if self.progress:
            self.announce(describe(estimate(tasks, label, cost, workers=workers_of(self.workers, self.scheduler),
                                            cache=cache)))
        return run_tasks(tasks, scheduler=self.scheduler, workers=self.workers, cache=cache,
                         progress=label if self.progress else None, on_result=on_result)

    def announce(self, text: str) -> None:
        """Say ``text`` (what a batch or a plan of batches costs) before it starts, on stderr (with
        ``progress``; quiet otherwise)."""
        if self.progress:
            print(text, file=sys.stderr, flush=True)

    @property
    def workers_known(self) -> int | None:
        """The workers a batch runs on (1 in this process; the usable cores of a local cluster; None on a
        running cluster)."""
        from wearbench.compute.cost import workers_of

        return workers_of(self.workers, self.scheduler)


DEFAULT = Compute()  # the active client, else the configured scheduler, else a local cluster on every core
QUIET = Compute(progress=False)  # as DEFAULT, without progress
SERIAL = Compute(workers=0, progress=False)  # in this process, quietly: tests and small jobs
