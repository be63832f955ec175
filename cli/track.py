"""`wearbench track`: a bench's wear over its life from sessions at several cycles run.

Thin front of ``wearbench.validation.workflows.measure.track_sessions``: the wear coefficient fitted to all
sessions jointly, the wear at each session, the cycles until a clearance limit, and the figure.
"""

from __future__ import annotations

import argparse

from wearbench.cli.calibrate import add_calibration_arguments, calibration_options
from wearbench.cli.compute import add_compute_arguments, compute_options
from wearbench.cli.estimator import add_design_arguments, design_from_args
from wearbench.cli.options import add_force_argument


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "track", help="wear coefficient and cycles to a clearance limit from sessions over a bench's life",
        description="Sessions of ONE bench recorded after different numbers of cycles run: the initial clearance "
        "and the Archard wear coefficient (as a factor on the bench file's) fitted to all of them jointly with "
        "credible intervals, the wear depth at each, and the clearance limit (--limit) seen from the last session: "
        "the probability that it is reached, the cycles that remain otherwise, whether it lies beyond the design.")
    p.add_argument("sessions", nargs="+", metavar="SESSION.mcap", help="sessions of one bench")
    p.add_argument("--cycles-run", metavar="N1,N2,...",
                   help="cycles the bench had run at each session, in the sessions' order (e.g. 0,100000,200000); "
                   "default: as each session records it ('wearbench record --cycles-run N')")
    p.add_argument("--limit", help="clearance limit, e.g. 0.5mm: print whether the clearance has reached it by the last "
                   "session (its probability) and the cycles that remain otherwise")
    p.add_argument("--estimator", metavar="FILE.npz", help="estimator saved by 'wearbench estimator'")
    p.add_argument("--no-move", action="store_true",
                   help="do not use the move from new to worn measured on simulated lives and stored with the "
                   "estimator (FILE.move.npz beside it; the shipped test bed's has one): with fewer than three worn "
                   "sessions the wear coefficient then comes out biased low")
    add_design_arguments(p)
    add_calibration_arguments(p)
    p.add_argument("--json", metavar="FILE", help="write the result as JSON (never over an existing file unless "
                   "--force)")
    p.add_argument("--figure", metavar="FILE.png", help="write the wear-over-life figure (never over an existing "
                   "file unless --force)")
    add_force_argument(p)
    add_compute_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import json

    from wearbench.bench.output_file import check_output, output_file
    from wearbench.cli.options import check_figure_name, positive_quantity
    from wearbench.cli.record import cycles_run_value
    from wearbench.reports.track import track_figure
    from wearbench.validation.workflows.measure import track_sessions

    runs = None
    if args.cycles_run is not None:
        runs = [cycles_run_value(v, option="--cycles-run") for v in args.cycles_run.split(",")]
        if len(runs) != len(args.sessions):
            raise ValueError(f"--cycles-run {args.cycles_run!r}: {len(runs)} values for {len(args.sessions)} "
                             "sessions; expected one per session")
    for option, path in (("--json", args.json), ("--figure", args.figure)):
        if path:  # refused before the estimator is built
            check_output(path, force=args.force, option=option)
    if args.figure:
        check_figure_name(args.figure, "--figure")
    limit = positive_quantity(args.limit, "length", "--limit", bare_unit="mm") if args.limit else None
    t = track_sessions(args.sessions, runs, limit=limit, design=design_from_args(args), estimator=args.estimator,
                       move=not args.no_move, **calibration_options(args), compute=compute_options(args))
    if t.explains:
        _print_life(t, limit)
    else:
        print(t.verdict)  # no numbers where no bench's life explains the sessions
    print(f"move from new to worn {t.move['described']}" if t.move else
          "no measured move from new to worn used" + (" (--no-move)" if args.no_move else ""))
    for note in t.notes:
        print(note)
    if args.json:
        with output_file(args.json, force=args.force, option="--json") as tmp, open(tmp, "w", encoding="utf-8") as f:
            json.dump(t.to_dict(), f, indent=1)
        print(f"results: {args.json}")
    if args.figure and t.explains:
        with output_file(args.figure, force=args.force, option="--figure") as tmp:
            track_figure(t, tmp)
        print(f"figure: {args.figure}")
    elif args.figure:
        print(f"no figure: {t.verdict}")
    return 0 if t.explains else 1


def _print_life(t, limit: float | None) -> None:
    """The life's numbers: each session's wear depth, the initial clearance, the wear coefficient and
    the clearance limit seen from the last session (reached, the cycles that remain, beyond the design)."""
    for label, n, d in zip(t.sessions, t.cycles_run, t.depth, strict=True):
        print(f"{label}: {n:,.0f} cycles run, wear depth {d.median * 1e6:.1f} um (90 % {d.lo90 * 1e6:.1f}-"
              f"{d.hi90 * 1e6:.1f})")
    c, k = t.clearance, t.factor
    print(f"initial clearance {c.median * 1e3:.3f} mm (90 % {c.lo90 * 1e3:.3f}-{c.hi90 * 1e3:.3f})")
    print(f"wear coefficient {t.coefficient.median:.3g} 1/Pa = {k.median:.2f} x the bench file's "
          f"(50 % {k.lo50:.2f}-{k.hi50:.2f}, 90 % {k.lo90:.2f}-{k.hi90:.2f})")
    if limit is not None and t.ahead is not None:
        print(f"clearance limit {limit * 1e3:g} mm: {t.ahead.verdict}")
