"""`wearbench estimator`: simulate the design of a bench's clearance-and-wear estimator and save it.

``estimate`` builds the estimator on demand (cached by content); this command builds it ahead of time
(e.g. on a cluster, ``--scheduler``) and saves it to one file that ``estimate --estimator`` reads, or
where a shipped bench's precomputed estimator lives (``--ship``, maintainers).
"""

from __future__ import annotations

import argparse

from wearbench.cli.compute import add_compute_arguments, compute_options
from wearbench.cli.options import add_force_argument, positive_int


def add_design_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--design-clearances", default="0.25mm,0.35mm,0.45mm,0.55mm,0.65mm", metavar="C1,C2,...",
                   help="design clearances, shared by the clearance joints (0.25mm,0.35mm,0.45mm,0.55mm,0.65mm)")
    p.add_argument("--design-cycles", default="0,200000,400000,600000", metavar="0,N1,...",
                   help="design cycles run, equally spaced from 0 (0,200000,400000,600000)")
    p.add_argument("--realisations", type=positive_int, default=16, help="realisations per design point (16)")
    p.add_argument("--ensemble-cycles", type=positive_int, default=8, help="settled cycles per realisation (8)")


def design_from_args(args: argparse.Namespace):
    from wearbench.validation.estimate import EstimatorDesign

    try:
        return EstimatorDesign.parse(args.design_clearances, args.design_cycles, realisations=args.realisations,
                                     ensemble_cycles=args.ensemble_cycles)
    except ValueError as exc:
        raise ValueError(f"--design-clearances / --design-cycles: {exc}") from None


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "estimator", help="simulate a bench's clearance-and-wear estimator (design ensembles) and save it",
        description="Wear the bench from every design clearance through the design's cycles (one wear run per "
        "clearance), simulate a theory ensemble at every design point, and save them: the estimator that "
        "'wearbench estimate' uses.")
    p.add_argument("bench", metavar="BENCH.toml", help="bench file (or the name of a shipped bench)")
    add_design_arguments(p)
    p.add_argument("--out", metavar="FILE.npz", help="where to save (default: BENCHNAME-estimator.npz)")
    add_force_argument(p)
    p.add_argument("--ship", action="store_true",
                   help="save where wearbench looks for a shipped bench's precomputed estimator, replacing it "
                   "(maintainers)")
    add_compute_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from wearbench.bench.load import load_bench, resolve_bench
    from wearbench.bench.output_file import check_output, output_file
    from wearbench.validation.estimate import (
        build_estimator,
        save_estimator,
        shipped_estimator_path,
    )

    bench = load_bench(resolve_bench(args.bench))
    design = design_from_args(args)
    out = shipped_estimator_path(bench) if args.ship else Path(args.out or f"{bench.name}-estimator.npz")
    force = args.force or args.ship  # --ship refreshes the package's own file
    check_output(out, force=force)  # refused before the design is simulated
    est = build_estimator(bench, design, shipped=False, **compute_options(args, bench))
    with output_file(out, force=force) as tmp:
        save_estimator(est, tmp)
    print(f"{len(design.clearances)} clearances x {len(design.cycles)} cycles-run values, "
          f"{est.features.shape[2]} realisations x {est.features.shape[3]} cycles each; largest wear depth "
          f"{est.depth.max() * 1e6:.1f} um")
    print(f"saved: {out}")
    return 0
