"""`wearbench estimator`: simulate the design of a bench's clearance-and-wear estimator and save it.

``estimate`` builds the estimator on demand (cached by content); this command builds it ahead of time
(e.g. on a cluster, ``--scheduler``) and saves it to one file that ``estimate --estimator`` reads, or
where a shipped bench's precomputed estimator lives (``--ship``, maintainers). ``--lives N`` also
measures the benches' move from new to worn beyond the estimator's on N simulated lives and stores
it beside the file (``validation/track_move.py``), which ``track`` uses by default: here, because the
move belongs to one estimator (keyed to it) and is built, like it, once per bench on the compute layer.
"""

from __future__ import annotations

import argparse

from wearbench.cli.compute import add_compute_arguments, add_size_arguments, compute_options
from wearbench.cli.options import add_force_argument, positive_int


def add_design_arguments(p: argparse.ArgumentParser) -> None:
    """The estimator's design: its clearances and cycles run (default: the bench's own), and its size
    (``--realisations``, ``--ensemble-cycles``, ``--small``: ``cli.compute.add_size_arguments``)."""
    p.add_argument("--design-clearances", default=None, metavar="C1,C2,...",
                   help="design clearances, shared by the clearance joints (default: five over the bench's nominal "
                   "and candidate clearances, 0.25mm,0.35mm,0.45mm,0.55mm,0.65mm for the test bed)")
    p.add_argument("--design-cycles", default=None, metavar="0,N1,...",
                   help="design cycles run, equally spaced from 0 (default: 0 and three of the bench's [wear] "
                   "stages, 0,200000,400000,600000 for the test bed)")
    add_size_arguments(p, design=True)


def design_from_args(args: argparse.Namespace):
    """The design a command asks for (``estimate.DesignRequest``; resolved for each bench and speed),
    its sizes checked before anything is built (one ValueError naming the option)."""
    from wearbench.validation.estimation.estimate import DesignRequest

    if args.realisations is not None and args.realisations < 3:
        raise ValueError(f"--realisations {args.realisations}: expected at least 3 realisations per design point "
                         "(an ensemble's least)")
    if args.ensemble_cycles is not None and args.ensemble_cycles < 2:
        raise ValueError(f"--ensemble-cycles {args.ensemble_cycles}: expected at least 2 settled cycles per "
                         "realisation (two cycles to tell a cycle's spread)")
    return DesignRequest.parse(args.design_clearances, args.design_cycles, realisations=args.realisations,
                               ensemble_cycles=args.ensemble_cycles, small=args.small)


MIN_LIVES = 3  # estimation.move.life_move: the move's mean and covariance over at least three benches


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
                   help="save where wearbench looks for a shipped bench's precomputed estimator (maintainers: only "
                   "in a source checkout, and replacing the shipped file only with --force)")
    p.add_argument("--wear-runs", type=int, default=None, metavar="K",
                   help="wear runs of drawn benches per design clearance beside the reference run, whose spread "
                   "widens the intervals of cycles run and wear depth where wear realisations disagree; saved "
                   "beside the estimator (FILE.spread.npz; default 3 for designs of 12 or more realisations, else 0)")
    p.add_argument("--lives", type=positive_int, metavar="N",
                   help="also simulate N lives of the bench (known truth, sessions at five cycles-run values) on the "
                   "compute layer and store the benches' move from new to worn beyond the estimator's beside it "
                   "(FILE.move.npz), which 'wearbench track' then uses; an --out that already holds this design's "
                   "estimator is kept as it is (about 90 s of CPU per life; 20 or more)")
    p.add_argument("--life-factor", type=float, default=1.3, metavar="FACTOR",
                   help="the lives' wear coefficient / the bench file's (1.3; up to 1.5)")
    p.add_argument("--life-sensor-paths", action="store_true",
                   help="draw each life's sensor path (a mount or carriage mode and sensitivity) instead of the "
                   "bench file's emulated one")
    p.add_argument("--life-cycles", type=positive_int, default=20,
                   help="cycles per session of a life (20; as many as the lab's sessions hold)")
    p.add_argument("--life-seed", type=int, default=100_000, help="first life's seed (100000)")
    add_compute_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from wearbench.bench.load import load_bench, resolve_bench
    from wearbench.bench.output_file import check_output, output_file
    from wearbench.validation.estimation.estimate import (
        build_estimator,
        check_spread,
        default_spread,
        estimator_key,
        load_estimator,
        save_estimator,
        save_estimator_spread,
        with_spread,
    )
    from wearbench.validation.estimation.move import move_path, save_move
    from wearbench.validation.estimation.spread import SpreadDesign, spread_path
    from wearbench.validation.inference import artefacts

    bench = load_bench(resolve_bench(args.bench))
    design = design_from_args(args).resolve(bench)  # every value checked against the bench before any work
    spread = default_spread(design) if args.wear_runs is None else SpreadDesign(args.wear_runs)
    check_spread(design, spread)
    if args.lives is not None and args.lives < MIN_LIVES:
        raise ValueError(f"--lives {args.lives}: expected at least {MIN_LIVES} lives (the move's mean and its error "
                         "need three independent benches; 20 or more)")
    if not 0 < args.life_factor <= 1.5:
        raise ValueError(f"--life-factor {args.life_factor:g}: expected a wear factor in (0, 1.5] (the lives' last "
                         "session must stay inside the design's cycles run)")
    if args.life_seed <= design.settings.realisations:
        raise ValueError(f"--life-seed {args.life_seed}: expected above the design's seeds "
                         f"1..{design.settings.realisations}")
    out = artefacts.shipped_path("estimator", bench.name) if args.ship else Path(args.out or f"{bench.name}-estimator.npz")
    option = "--ship" if args.ship else "--out"
    key = estimator_key(bench, design, bench.speed)
    # --lives, --ship: a file that already holds this design's estimator is kept, what it lacks added
    kept = load_estimator(out, key=key) if (args.lives or args.ship) and out.is_file() else None
    replaced = None
    if kept is None:  # refused before the design is simulated
        if args.ship:
            out, replaced = artefacts.ship_target("estimator", bench.name, force=args.force)
        else:
            check_output(out, force=args.force)
    if args.lives:
        if args.ship:
            artefacts.check_shipping(move_path(out))
        check_output(move_path(out), force=args.force, option="--lives")
    if spread.runs:
        if args.ship:
            artefacts.check_shipping(spread_path(out))
        check_output(spread_path(out), force=args.force, option="--wear-runs")
    compute = compute_options(args, bench)
    if args.lives:  # the lives' cost said before anything starts, with the estimator's own plan
        from wearbench.compute.cost import plan_line
        from wearbench.synthetic.lives import life_cost, life_revolutions

        compute.announce(plan_line("lives", [("lives", args.lives, life_revolutions(args.life_cycles))],
                                   life_cost(bench, design, bench.speed), workers=compute.workers_known))
    est = (with_spread(bench, kept, spread, speed=bench.speed, compute=compute) if kept is not None
           else build_estimator(bench, design, compute=compute, spread=spread))  # grows a shipped smaller one
    if kept is None:
        with output_file(out, force=args.force, option=option) as tmp:
            save_estimator(est, tmp)
    print(f"{len(design.clearances)} clearances x {len(design.cycles)} cycles-run values, "
          f"{est.features.shape[2]} realisations x {est.features.shape[3]} cycles each; largest wear depth "
          f"{est.depth.max() * 1e6:.1f} um")
    print(f"{'kept (this design, key matches)' if kept is not None else 'saved'}: {out}"
          + (f" (replaced the shipped {replaced.describe()}, key {replaced.key[:12]})" if replaced else ""))
    if est.spread is not None and (kept is None or kept.spread is None or kept.spread.key != est.spread.key):
        with output_file(spread_path(out), force=args.force, option="--wear-runs") as tmp:
            save_estimator_spread(est, tmp)
        print(f"wear spread: {est.spread.describe()}\nsaved: {spread_path(out)}")
    if args.lives:
        from wearbench.synthetic.lives import measure_move

        move = measure_move(bench, est, lives=args.lives, factor=args.life_factor, spread=args.life_sensor_paths,
                            cycles=args.life_cycles, seed=args.life_seed, compute=compute)
        with output_file(move_path(out), force=args.force, option="--lives") as tmp:
            save_move(move, tmp)
        print(f"move from new to worn {move.describe()}: largest |mean| / its standard error "
              f"{float((abs(move.mean) / move.covariance.diagonal() ** 0.5).max()):.1f}")
        print(f"saved: {move_path(out)}")
    return 0
