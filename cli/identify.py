"""`wearbench identify`: which candidate wear state explains each recorded session, with probabilities.

Thin front of ``wearbench.validation.inference.identify.identify_sessions``; prints one line per session.
"""

from __future__ import annotations

import argparse

from wearbench.cli.calibrate import add_calibration_arguments, calibration_options
from wearbench.cli.compute import (
    add_compute_arguments,
    add_size_arguments,
    compute_options,
    ensemble_size,
)
from wearbench.cli.options import add_force_argument


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "identify", help="posterior probability of each candidate wear state for session MCAPs",
        description="Simulate an ensemble of every candidate state (benches drawn within the bench file's "
        "[tolerances], random start states; cached), compare the statistics of the session's crank cycles "
        "with each ensemble, and print the posterior probability of each state. The top state is named only "
        "above --threshold, otherwise 'undecided' with the cycles that would decide it; 'none of the "
        "candidates' when no state explains the session.")
    p.add_argument("sessions", nargs="+", metavar="SESSION.mcap", help="recorded session file(s)")
    p.add_argument("--candidates", metavar="STATES.toml",
                   help="file of [[state]] tables (name, clearances, wear); default: the [[state]] tables of the "
                        "bench file recorded in the session")
    p.add_argument("--ensembles", metavar="FILE.npz",
                   help="ensembles saved by 'wearbench ensemble' (no simulation); refused, with the reason, where "
                   "their bench, speed or candidates (--candidates, else the session's bench's) do not fit")
    p.add_argument("--threshold", type=float, default=0.9, help="name the top state at this probability (0.9)")
    add_size_arguments(p, design=False)
    p.add_argument("--estimate", action="store_true",
                   help="also estimate each session's clearance and wear with credible intervals, as 'wearbench "
                   "estimate' does (the bench's shipped estimator when its key matches, else its default design, "
                   "or with --small the small design, built on the compute layer and cached: slow the first time)")
    p.add_argument("--estimator", metavar="FILE.npz", help="estimate with this estimator (saved by 'wearbench "
                   "estimator'; implies --estimate)")
    add_calibration_arguments(p)
    add_compute_arguments(p)
    p.add_argument("--json", metavar="FILE", help="write every result as JSON (never over an existing file "
                   "unless --force, never over a session)")
    p.add_argument("--out", metavar="DIR", help="also write the report (report.html, scores.json, figures) here")
    add_force_argument(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import json

    from rich.table import Table
    from wearbench.bench.output_file import check_output, output_file, output_folder
    from wearbench.cli.progress import console as progress_console
    from wearbench.reports.assessment import write_assessment_report
    from wearbench.validation.estimation.estimate import DesignRequest, Estimator, load_estimator
    from wearbench.validation.inference.identify import IdentifyOptions
    from wearbench.validation.workflows.assess import assess_sessions
    from wearbench.validation.workflows.measure import estimate_assessed
    from wearbench.validation.workflows.session_set import SessionSet

    for option, path, folder in (("--json", args.json, False), ("--out", args.out, True)):
        if path:  # refused before the ensembles are built
            check_output(path, force=args.force, option=option, folder=folder)
    settings = ensemble_size(args)
    estimator = (load_estimator(args.estimator) if args.estimator
                 else DesignRequest(small=args.small) if args.estimate else None)
    options = IdentifyOptions(threshold=args.threshold)
    sessions = SessionSet(args.sessions, **calibration_options(args))
    # ready-made theory is checked against every session, and the theory to build resolved for each
    # bench and speed, before any is built
    sessions.check_artefacts(ensembles=args.ensembles, candidates=args.candidates, settings=settings,
                             estimator=estimator if isinstance(estimator, Estimator) else None,
                             design=estimator if isinstance(estimator, DesignRequest) else None,
                             theory=("ensembles",) + (("estimator",) if estimator is not None else ()))
    compute = compute_options(args)
    assessed = assess_sessions(sessions, candidates=args.candidates, settings=settings, ensembles=args.ensembles,
                               options=options, compute=compute)
    if estimator is not None:
        estimate_assessed(assessed, estimator, options=options, **calibration_options(args), compute=compute)
    results = [a.identification for a in assessed]
    states = list(results[0].posterior)
    table = Table(title=f"posterior probability of each state (named at p >= {args.threshold:g})")
    table.add_column("session")
    table.add_column("cycles", justify="right")
    for s in states:
        table.add_column(s, justify="right")
    table.add_column("verdict")
    table.add_column("explains it")
    for r in results:
        needed = f" (about {r.cycles_needed} cycles would decide)" if r.verdict == "undecided" and r.cycles_needed else ""
        table.add_row(r.session, str(r.cycles), *(f"{r.posterior[s]:.3f}" for s in states), r.verdict + needed,
                      ", ".join(s for s in states if r.explains[s]) or "none")
    console = progress_console()
    console.print(table)
    for r in results:
        for note in r.notes:
            console.print(f"{r.session}: {note}")
    for a in assessed:
        if a.estimate is not None:
            console.print(f"{a.estimate.session}: estimate {a.estimate.line()} (consistency p "
                          f"{a.estimate.p_value:.2g})", highlight=False)
    if args.json:
        with output_file(args.json, force=args.force, option="--json") as tmp, open(tmp, "w", encoding="utf-8") as f:
            json.dump([{**a.identification.to_dict(), **({"estimate": a.estimate.to_dict()} if a.estimate else {})}
                       for a in assessed], f, indent=1)
        console.print(f"results: {args.json}")
    if args.out:
        with output_folder(args.out, force=args.force) as tmp:
            report = write_assessment_report(assessed, tmp, threshold=args.threshold)
        console.print(f"report: {report.moved_to(args.out).html}")
    return 0
