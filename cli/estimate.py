"""`wearbench estimate`: clearance and wear of each session, with credible intervals.

Thin front of ``wearbench.validation.workflows.measure.estimate_sessions``; prints one line per session and
writes the joint posterior figure and JSON when asked.
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from wearbench.cli.calibrate import add_calibration_arguments, calibration_options
from wearbench.cli.compute import add_compute_arguments, compute_options
from wearbench.cli.estimator import add_design_arguments, design_from_args
from wearbench.cli.options import add_force_argument

if TYPE_CHECKING:
    from wearbench.validation.estimation.estimate import Interval


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "estimate", help="clearance and wear of session MCAPs, with 50 %% and 90 %% credible intervals",
        description="Estimate the clearance (shared by the clearance joints) and the wear (cycles run along the "
        "bench's own wear trajectory, and the wear depth: the clearance growth) of each session from the statistics of its "
        "crank cycles, against theory ensembles over a design of clearances and cycles run (built on the "
        "compute layer and cached, or --estimator). Says 'no parameter value explains it' when none does.")
    p.add_argument("sessions", nargs="+", metavar="SESSION.mcap", help="recorded session file(s)")
    p.add_argument("--estimator", metavar="FILE.npz", help="estimator saved by 'wearbench estimator'")
    add_design_arguments(p)
    add_calibration_arguments(p)
    p.add_argument("--json", metavar="FILE", help="write every estimate as JSON (never over an existing file "
                   "unless --force)")
    p.add_argument("--out", metavar="DIR", help="write each session's joint posterior figure, posterior_SESSION.png, "
                   "and its posterior predictive band against the measured cycles, predictive_SESSION.png, here (a folder "
                   "with files in it only with --force)")
    add_force_argument(p)
    add_compute_arguments(p)
    p.set_defaults(func=run)


def kind_note(interval: Interval) -> str:
    """What a one-sided interval is, after it ("" for a central one)."""
    if interval.kind == "central":
        return ""
    return f" ({interval.kind}: the posterior piles at the edge of the estimator's range)"


def fmt_cycles(v: float) -> str:
    """Cycles as the printout gives them: whole, with thousands separators."""
    return f"{v:,.0f}"


def run(args: argparse.Namespace) -> int:
    import json
    from pathlib import Path

    from wearbench.bench.output_file import check_output, output_file, output_folder
    from wearbench.validation.estimation.estimate import fmt_mm, fmt_um
    from wearbench.validation.workflows.measure import estimate_sessions

    for option, path, folder in (("--json", args.json, False), ("--out", args.out, True)):
        if path:  # refused before the estimator is built
            check_output(path, force=args.force, option=option, folder=folder)
    results = estimate_sessions(args.sessions, design=design_from_args(args), estimator=args.estimator,
                                **calibration_options(args), compute=compute_options(args))
    for e in results:
        print(f"{e.session} ({e.cycles} cycles): {e.verdict}")
        if e.explains and not e.flat:  # a flat estimate's intervals are its prior's: the verdict says so
            c, n, d = e.clearance, e.cycles_run, e.depth
            print(f"  clearance {c.median * 1e3:.3f} mm  50 % {c.text(fmt_mm, 50)}  90 % {c.text(fmt_mm)}{kind_note(c)}")
            print(f"  cycles run {n.median:,.0f}  50 % {n.text(fmt_cycles, 50)}  90 % {n.text(fmt_cycles)}{kind_note(n)}")
            print(f"  wear depth (clearance growth) {d.median * 1e6:.1f} um  90 % {d.text(fmt_um)} um{kind_note(d)};  "
                  f"clearance and wear correlated {e.correlation:+.2f}")
        print(f"  consistency p {e.p_value:.3g}; {100 * e.inside:.0f} % of the measured cycles' features inside "
              f"the 90 % predictive band; sensor path: {e.sensor_path}")
        for note in e.notes:
            print(f"  {note}")
    if args.json:
        with output_file(args.json, force=args.force, option="--json") as tmp, open(tmp, "w", encoding="utf-8") as f:
            json.dump([e.to_dict() for e in results], f, indent=1)
        print(f"results: {args.json}")
    if args.out:
        from wearbench.reports.comparison import slug
        from wearbench.reports.estimate import posterior_figure, predictive_figure

        stems = [slug(e.session) for e in results]  # the same recording given twice: numbered
        stems = [s if stems.count(s) == 1 or stems[:k].count(s) == 0 else f"{s}_{stems[:k].count(s) + 1}"
                 for k, s in enumerate(stems)]
        names = [f"{kind}_{stem}.png" for stem in stems for kind in ("posterior", "predictive")]
        with output_folder(args.out, force=args.force) as tmp:
            for k, e in enumerate(results):
                posterior_figure(e, tmp / names[2 * k])
                predictive_figure(e, tmp / names[2 * k + 1])
        for name in names:
            print(f"figure: {Path(args.out) / name}")
    return 0
