"""Options shared by the commands that run batches of simulations (`sweep`, `study`)."""

from __future__ import annotations

import argparse


def add_compute_arguments(p: argparse.ArgumentParser) -> None:
    """``--scheduler`` and ``--workers`` (see :mod:`wearbench.model.compute`)."""
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="a running Dask scheduler, e.g. tcp://10.0.0.5:8786 (default: $WEARBENCH_SCHEDULER, "
                   "[compute] scheduler in ~/.config/wearbench/config.toml, else a local cluster)")
    p.add_argument("--workers", type=int, default=None,
                   help="local cluster processes (default: the usable cores); 0 runs in this process, serially")


def compute_options(args: argparse.Namespace) -> dict:
    """{"scheduler", "workers"} from the parsed options; a negative worker count is an error."""
    if args.workers is not None and args.workers < 0:
        raise ValueError(f"--workers {args.workers}: expected 0 (in-process) or more")
    return {"scheduler": args.scheduler, "workers": args.workers}
