"""Options shared by the commands that run batches of simulations (`sweep`, `study`, `ensemble`, ...)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from wearbench.bench.schema import Bench
    from wearbench.compute.options import Compute


def add_compute_arguments(p: argparse.ArgumentParser) -> None:
    """``--scheduler`` and ``--workers`` (see :mod:`wearbench.compute`)."""
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="a running Dask scheduler, e.g. tcp://10.0.0.5:8786, or 'local' (default: "
                   "$WEARBENCH_SCHEDULER, [compute] scheduler in the bench file, then in "
                   "~/.config/wearbench/config.toml, else a local cluster)")
    p.add_argument("--workers", type=int, default=None,
                   help="local cluster processes (default: the usable cores); 0 runs in this process, serially")


def compute_options(args: argparse.Namespace, bench: Bench | None = None) -> Compute:
    """The compute record (``wearbench.compute.options.Compute``) from the parsed options and ``bench``'s
    ``[compute]`` table, the scheduler resolved here ("local" when none is set); bad values and
    negative workers are errors."""
    from wearbench.compute import resolve_scheduler
    from wearbench.compute.options import Compute

    if args.workers is not None and args.workers < 0:
        raise ValueError(f"--workers {args.workers}: expected 0 (in-process) or more")
    scheduler = resolve_scheduler(args.scheduler, bench=bench) if args.workers != 0 else None
    return Compute(scheduler=scheduler or "local", workers=args.workers)
