"""`wearbench compare`: score recorded sessions against theory and write a report.

A session whose bench file declares candidate states is identified among them and its five-cycle
windows are judged against the identified state's ensemble windows (``validation.assess``): one
verdict per session. With ``--theory`` (or a bench without states) each session is scored against
that one theory (``validation.compare``) and the summary table printed.
"""

from __future__ import annotations

import argparse
import sys

from wearbench.bench.output_file import check_output, output_folder
from wearbench.cli.compute import (
    add_compute_arguments,
    add_size_arguments,
    compute_options,
    ensemble_size,
)
from wearbench.cli.options import (
    add_force_argument,
    nonnegative_number,
    positive_int,
    positive_number,
)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "compare", help="score session MCAPs against theory; write report.html, scores.json and figures",
        description="When each session's bench file names candidate states, identify the session among them "
        "and judge its five-cycle windows against the identified state's ensemble windows (one verdict per "
        "session, or 'cannot decide'); otherwise, or with --theory, align, filter and score its windows against "
        "one theory (simulated from the bench file at the measured speed, clearances and wear state, or the "
        "--theory table). Writes report.html (self-contained), scores.json and PNG figures.")
    p.add_argument("sessions", nargs="+", metavar="SESSION.mcap", help="recorded session file(s)")
    p.add_argument("--out", default="report", help="output folder (default: report/; one with files in it only "
                   "with --force)")
    add_force_argument(p)
    p.add_argument("--theory", action="append", metavar="RUN.parquet",
                   help="simulation results table to compare with instead of simulating; once for all "
                        "sessions or once per session, in order")
    p.add_argument("--filter", default=None,
                   help="cfc60|cfc180|cfc600|cfc1000, butter:CUTOFF_HZ[:ORDER] or none (default: CFC 180 scaled to "
                   "the session's crank, its kept curves' filter: cfc180 at 1 Hz)")
    p.add_argument("--windows", default="all", help="all | random:COUNT[:SEED] (default all)")
    p.add_argument("--cycles", type=positive_int, default=5, help="crank cycles per window (default 5)")
    p.add_argument("--max-shift", type=nonnegative_number, default=0.2, metavar="CYCLES",
                   help="residual time-shift search, fraction of a crank cycle, < 0.5 (default 0.2)")
    p.add_argument("--max-delay", default="2ms", metavar="TIME",
                   help="without a [sensor.chain] statement in the bench, the sensor chain's delay (accelerometer "
                        "behind the encoder) is fitted from the signal up to this (default 2ms)")
    p.add_argument("--candidates", metavar="STATES.toml|bench",
                   help="identify each session among candidate states ([[state]] tables of a file, or 'bench' "
                        "for those of the session's bench file, the default when it has any and no --theory is "
                        "given) against theory ensembles, and judge its five-cycle windows against the "
                        "identified state's ensemble windows (or say it cannot decide)")
    p.add_argument("--alpha", type=positive_number, default=0.05,
                   help="false-alarm rate of the window verdicts (default 0.05)")
    p.add_argument("--dtw-band", type=nonnegative_number, default=0.05, metavar="CYCLES",
                   help="DTW band half-width, fraction of a crank cycle (default 0.05)")
    p.add_argument("--no-shift", action="store_true", help="report the residual shift but do not remove it")
    p.add_argument("--detrend", action="store_true", help="remove a linear trend before filtering")
    p.add_argument("--keep-bias", action="store_true", help="do not subtract the mean (sensor bias)")
    p.add_argument("--revolutions", type=positive_number, default=3.0,
                   help="revolutions to simulate when theory is simulated (default 3)")
    p.add_argument("--contiguous-theory", action="store_true",
                   help="compare with the theory's last revolutions in a row (simulate at least a window "
                        "plus margins) instead of its last revolution repeated")
    p.add_argument("--label", action="append", help="label per session (default: file name)")
    p.add_argument("--ensembles", metavar="FILE.npz",
                   help="with candidate states: ensembles saved by 'wearbench ensemble' (no simulation); refused, with "
                   "the reason, where their bench, speed or candidates do not fit")
    add_size_arguments(p, design=False)
    add_compute_arguments(p)
    p.set_defaults(func=run)


def _with_states(paths) -> list | None:
    """The sessions, loaded, when every one's recorded bench declares candidate states (then plain
    ``compare`` judges each against its identified state: one verdict per session); else None."""
    from wearbench.validation.measurement.session import load_session

    try:
        sessions = [load_session(p) for p in paths]
    except (OSError, ValueError, KeyError):
        return None  # the classic path reports the unreadable file and scores the others
    return sessions if all(s.bench is not None and s.bench.states for s in sessions) else None


def session_options(session, options, args: argparse.Namespace):
    """``options`` with the filter of ``session``: its kept curves' (CFC 180 scaled to its crank,
    ``measurement.scaling``; the test bed's cfc180 at 1 Hz), from its bench and commanded speed."""
    from dataclasses import replace

    from wearbench.validation.measurement.filters import parse_filter
    from wearbench.validation.measurement.scaling import resolve_analysis

    text = resolve_analysis(session.bench, session.commanded_speed).curve_filter
    return replace(options, filter=parse_filter(text, detrend=args.detrend, remove_bias=not args.keep_bias))


def _assess(args: argparse.Namespace, options, sessions) -> int:
    from wearbench.reports.assessment import write_assessment_report
    from wearbench.validation.comparison.windows import WindowOptions
    from wearbench.validation.workflows.assess import assess_sessions

    windows = WindowOptions(cycles=args.cycles, alpha=args.alpha, max_delay=options.max_delay)
    assessed = assess_sessions(sessions, candidates=None if args.candidates in (None, "bench") else args.candidates,
                               window_options=windows, settings=ensemble_size(args, window=args.cycles),
                               ensembles=args.ensembles, compute=compute_options(args))
    with output_folder(args.out, force=args.force) as tmp:
        report = write_assessment_report(assessed, tmp)
    report = report.moved_to(args.out)
    for a in assessed:
        r = a.identification
        line = f"{r.session}: {r.verdict} (" + ", ".join(f"{s} {p:.3f}" for s, p in r.posterior.items()) + "); "
        if a.decided:
            own = a.windows[a.state]
            line += f"windows against {a.state}: {own.label}" + (
                f"; sensor delay {own.delay.describe()}" if own.delay else "")
        else:
            line += "windows: cannot decide which state to judge them against"
        print(line)
    print(f"report: {report.html}  scores: {report.scores_json}")
    return 0


def run(args: argparse.Namespace) -> int:
    from rich.console import Console
    from rich.table import Table
    from wearbench.bench.units import parse_quantity
    from wearbench.cli.progress import progress
    from wearbench.reports.comparison import write_report
    from wearbench.validation.comparison.compare import CompareOptions, compare_session
    from wearbench.validation.comparison.metrics import grade
    from wearbench.validation.measurement.cycles import parse_windows
    from wearbench.validation.measurement.filters import parse_filter
    from wearbench.validation.measurement.session import load_session

    if args.cycles < 1:
        raise ValueError(f"--cycles {args.cycles}: expected at least 1")
    options = CompareOptions(
        filter=parse_filter(args.filter or "cfc180", detrend=args.detrend, remove_bias=not args.keep_bias),
        windows=parse_windows(args.windows, cycles=args.cycles), max_shift_cycles=args.max_shift,
        dtw_band_cycles=args.dtw_band, apply_shift=not args.no_shift, revolutions=args.revolutions,
        periodic_theory=not args.contiguous_theory, max_delay=parse_quantity(args.max_delay, "time"))
    if args.candidates and args.theory:
        raise ValueError("--candidates and --theory exclude each other: the theory is the candidates' ensembles")
    if args.ensembles and args.theory:
        raise ValueError("--ensembles and --theory exclude each other: ensembles are the candidates' theory")
    check_output(args.out, force=args.force, folder=True)  # refused before anything is simulated
    if args.candidates or args.ensembles:
        return _assess(args, options, args.sessions)
    if not args.theory and (loaded := _with_states(args.sessions)) is not None:
        return _assess(args, options, loaded)
    theories = args.theory or [None]
    if len(theories) == 1:
        theories = theories * len(args.sessions)
    if len(theories) != len(args.sessions):
        raise ValueError(f"--theory given {len(args.theory)} times for {len(args.sessions)} sessions; "
                         "give it once or once per session")
    if args.label and len(args.label) != len(args.sessions):
        raise ValueError(f"--label given {len(args.label)} times for {len(args.sessions)} sessions")
    comparisons, failed = [], []
    with progress() as bar:
        task = bar.add_task("compare", total=len(args.sessions), info="")
        for i, (path, theory) in enumerate(zip(args.sessions, theories)):
            bar.update(task, info=str(path))
            try:
                session = load_session(path, label=args.label[i] if args.label else None)
                own = options if args.filter else session_options(session, options, args)
                comparisons.append(compare_session(session, theory, options=own))
            except ValueError as exc:  # one session that cannot be scored does not cost the others
                if len(args.sessions) == 1:
                    raise
                failed.append(f"{path}: {exc}")
            bar.advance(task)
    for line in failed:
        print(f"wearbench compare: not scored: {line}", file=sys.stderr)
    if not comparisons:
        raise ValueError(f"none of the {len(args.sessions)} sessions could be scored")
    for c in comparisons:
        if not c.session.finished:
            print(f"wearbench compare: {c.session.path}: unfinished session ({c.session.problem}); scored up "
                  "to its last complete chunk", file=sys.stderr)
    with output_folder(args.out, force=args.force) as tmp:
        report = write_report(comparisons, tmp)
    report = report.moved_to(args.out)
    filters = sorted({c.options.filter.label for c in comparisons})
    table = Table(title=f"{', '.join(filters)}; {options.windows.label}")
    for col in ("session", "windows", "ISO R", "grade", "shift ms", "NRMSE", "corr", "S&G C"):
        table.add_column(col, justify="left" if col == "session" else "right")
    for c in comparisons:
        s = c.summary
        table.add_row(c.label, str(len(c.windows)),
                      f"{s.loc['iso_rating', 'mean']:.3f} ± {s.loc['iso_rating', 'std']:.3f}",
                      grade(s.loc["iso_rating", "mean"]),
                      f"{1e3 * sum(w.shift_s for w in c.windows) / len(c.windows):+.2f}",
                      f"{s.loc['nrmse', 'mean']:.3f}", f"{s.loc['correlation', 'mean']:.3f}",
                      f"{s.loc['sg_comprehensive', 'mean']:.3f}")
    console = Console()
    console.print(table)
    console.print(f"report: {report.html}  scores: {report.scores_json}")
    return 1 if failed else 0
