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


ENSEMBLE_REALISATIONS = 64  # EnsembleSettings' (the shipped ensembles'); tests/test_cli.py checks they agree
DESIGN_REALISATIONS = 48  # EstimatorDesign's
SMALL_ENSEMBLES = (8, 6)  # --small: realisations x cycles of a first look at identification


def add_size_arguments(p: argparse.ArgumentParser, *, design: bool) -> None:
    """``--realisations``, ``--ensemble-cycles`` and ``--small``: how much theory a command builds, the
    same options on every command that builds it (``design``: the estimator's design points, else the
    candidate states' ensembles)."""
    from wearbench.cli.options import positive_int

    what = "design point" if design else "candidate state"
    default = DESIGN_REALISATIONS if design else ENSEMBLE_REALISATIONS
    p.add_argument("--realisations", type=positive_int, default=None,
                   help=f"realisations per {what} ({default}; {3 if design else SMALL_ENSEMBLES[0]} with --small)")
    p.add_argument("--ensemble-cycles", type=positive_int, default=None,
                   help=f"settled cycles per realisation (8; {4 if design else SMALL_ENSEMBLES[1]} with --small)")
    p.add_argument("--small", action="store_true",
                   help=("a small design for a first look: the default design's lowest, middle and highest clearance "
                         "x 0, one and two wear stages, 3 realisations x 4 cycles" if design else
                         f"small ensembles for a first look: {SMALL_ENSEMBLES[0]} realisations x {SMALL_ENSEMBLES[1]} "
                         "cycles per state (coarse: fewer sessions are named)"))


def ensemble_size(args: argparse.Namespace, *, window: int | None = 5):
    """The ensembles' size from ``--realisations``, ``--ensemble-cycles`` and ``--small``, checked
    before anything is built: at least ``MIN_REALISATIONS`` realisations and, where five-cycle
    ``window``s are judged, a cycle more than a window (one ValueError naming the option)."""
    from wearbench.cli.options import check_realisations
    from wearbench.validation.inference.ensemble import EnsembleSize

    small = getattr(args, "small", False)
    realisations = args.realisations or (SMALL_ENSEMBLES[0] if small else ENSEMBLE_REALISATIONS)
    cycles = args.ensemble_cycles or (SMALL_ENSEMBLES[1] if small else 8)
    check_realisations(realisations)
    least = 2 if window is None else window + 1
    if cycles < least:
        why = (f"a {window}-cycle window and a cycle to spare (a realisation may end a cycle short)" if window else
               "two cycles to tell a cycle's spread")
        raise ValueError(f"--ensemble-cycles {cycles}: expected at least {least} settled cycles per realisation: {why}")
    return EnsembleSize(realisations, cycles)
