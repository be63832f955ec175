"""`wearbench demo`: the whole toolkit end to end on the emulated nine-bar test bed, as a lab meets it.

The test bed's four candidate states (its ``[[state]]`` tables: clearance 0.3 and 0.6 mm with new
surfaces; 0.3 mm after the first and the second wear stage) are each given to the bench emulator
as hidden truth, drawn from the bench's ``[tolerances]`` with its own seed (masses, lengths,
friction, speed and start differ from the file: not a twin) and seen through a real sensor chain.
A session of each is recorded through the acquisition drivers (the serial protocol on a
pseudo-terminal, or the in-process device with ``--quick``). The theory of every state is an
ensemble of realisations (shipped precomputed for this bench, or built on the compute layer), and
each session gets the posterior probability of every state, a band comparison and a verdict for
each five-cycle window against every state's ensemble windows, in one report. A fifth bench lies
between the named states (0.45 mm, new surfaces: not a candidate), and every bench's clearance and
wear are estimated with credible intervals beside the identification (the test bed's shipped
estimator when its key matches, else a small design built on the compute layer and cached,
``EstimatorDesign.small()``; saved beside the report, so ``wearbench estimate --estimator`` gives the same
numbers). ``--twin`` plays the nominal model instead (the demo of earlier versions, for comparison).

The demo's output folder follows the output-file policy (``bench.output_file``) with one rule of its
own: the demo marks the folders it writes (``.wearbench-demo``), and a rerun into a marked folder
replaces its four sessions and its report there (files of other names stay). A folder with files in
it that the demo did not mark is refused unless ``--force``; even then, a session file at one of
the demo's session names is never written over (the demo's emulated sessions never replace a
recording).
"""

from __future__ import annotations

import argparse
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from wearbench.bench.output_file import check_output, output_folder
from wearbench.cli.compute import add_compute_arguments, compute_options
from wearbench.cli.options import add_force_argument
from wearbench.synthetic.truths import prepare_truth, record_state, slug, truth_revolutions

BENCH = "ninebar-testbed"
FIFTH = ("0.45 mm new", 0.45e-3)  # a bench between the named states, not a candidate: estimated, not named
TRUTH_SEED = 2026  # truth i is drawn with TRUTH_SEED + i; the ensembles use seeds from 1
MARK = ".wearbench-demo"  # in a folder the demo wrote: a rerun may replace its sessions and report


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "demo", help="record the four states of the emulated nine-bar test bed and a bench between them; identify and "
        "estimate each one",
        description="The whole toolkit on the built-in simulated bench: each of the test bed's four states "
        "(0.3 and 0.6 mm new, 0.3 mm after the first and second wear stage) is the hidden truth of a bench "
        "emulator that differs from the bench file within its tolerances; a session of each is recorded "
        "through the acquisition drivers, and each session gets the probability of every state from theory "
        "ensembles, band comparisons and window scores, in report.html, scores.json and figures.",
        epilog="example: wearbench demo --out demo/   (then open demo/report/report.html)")
    p.add_argument("--out", "-o", type=Path, default=Path("demo"),
                   help="folder for sessions/ (MCAP) and report/ (default: demo/); a rerun replaces the demo's own "
                   "files there, a folder with other files in it is used only with --force")
    add_force_argument(p)
    p.add_argument("--quick", action="store_true",
                   help="record from the in-process emulator as fast as the host can (about a minute)")
    p.add_argument("--backend", choices=["serial", "sim"],
                   help="how sessions are recorded: 'serial' runs the emulator on a pseudo-terminal and "
                   "records in real time through the serial driver; 'sim' uses the in-process emulator "
                   "(default: serial, sim with --quick)")
    p.add_argument("--cycles", type=int, default=20, help="crank cycles per session (default 20)")
    p.add_argument("--seed", type=int, default=TRUTH_SEED, help=f"truth seed of the first state ({TRUTH_SEED})")
    p.add_argument("--twin", action="store_true",
                   help="the emulator plays the nominal model (a twin: earlier versions' demo, for comparison)")
    add_compute_arguments(p)
    p.set_defaults(func=run)


def demo_estimator(bench):
    """The test bed's shipped estimator when its key matches, else ``EstimatorDesign.small()`` (cached)."""
    from wearbench.validation.estimation.estimate import (
        EstimatorDesign,
        build_estimator,
        estimator_key,
        load_estimator,
    )
    from wearbench.validation.inference import artefacts

    shipped = artefacts.shipped_path("estimator", bench.name)
    if shipped.exists():
        found = load_estimator(shipped, key=estimator_key(bench, EstimatorDesign(), bench.speed))
        if found is not None:
            return found
    return build_estimator(bench, EstimatorDesign.small(), shipped=False)


def run(args: argparse.Namespace) -> int:
    from wearbench.bench.load import load_bench, shipped_bench
    from wearbench.bench.schema import WearState
    from wearbench.cli.progress import progress
    from wearbench.compute import Task, TaskFailure, compute_client, run_tasks, task_key
    from wearbench.reports.assessment import write_assessment_report
    from wearbench.validation import load_session
    from wearbench.validation.estimation.estimate import save_estimator, save_estimator_spread
    from wearbench.validation.estimation.spread import spread_path
    from wearbench.validation.inference.ensemble import EnsembleSettings, build_ensembles
    from wearbench.validation.workflows.assess import assess_sessions
    from wearbench.validation.workflows.measure import estimate_assessed

    backend = args.backend or ("sim" if args.quick else "serial")
    if args.cycles < 6:
        raise ValueError(f"--cycles {args.cycles}: expected at least 6 (a five-cycle window after the first index)")
    bench = load_bench(shipped_bench(BENCH))
    candidates = bench.states
    states = (*candidates, WearState(FIFTH[0], {j.name: FIFTH[1] for j in bench.clearance_joints}))
    seeds = {s.name: None if args.twin else args.seed + i for i, s in enumerate(states)}
    sessions_dir, report_dir = args.out / "sessions", args.out / "report"
    paths = [sessions_dir / f"{slug(s.name)}.mcap" for s in states]
    force = claim_folder(args.out, paths, report_dir, force=args.force)
    sessions_dir.mkdir(parents=True, exist_ok=True)
    start = time.monotonic()
    compute = compute_options(args)
    with compute_client(compute.scheduler, compute.workers):
        ensembles = build_ensembles(bench, candidates, settings=EnsembleSettings(), label="theory ensembles")
        estimator = demo_estimator(bench)
        revolutions = truth_revolutions(bench, args.cycles)
        tasks = [Task(prepare_truth, {"bench": bench, "state": s, "seed": seeds[s.name], "revolutions": revolutions},
                      task_key("demo-truth", bench.sha256, s.name, seeds[s.name], time.time_ns()), f"truth {s.name}")
                 for s in states]
        failed = [r for r in run_tasks(tasks, cache=False, progress="emulator truths") if isinstance(r, TaskFailure)]
        if failed:
            raise RuntimeError(f"demo: the emulator's truth failed: {failed[0].error}")
    # the sessions are recorded at once, each from its own emulator: recording runs in real time and
    # costs the host about 1 % of a core, so four take the wall time of one
    with progress() as bar, ThreadPoolExecutor(len(states)) as pool:
        def record(state, path) -> None:
            task = bar.add_task(f"record {state.name:20s}", total=args.cycles, info="")

            def show(p) -> None:
                dropped = f", dropped {p.dropped}" if p.dropped else ""
                bar.update(task, completed=min(p.cycles, args.cycles), info=f"{p.phase}{dropped}")

            record_state(bench, state, seeds[state.name], path, backend=backend, cycles=args.cycles,
                         on_progress=show, recorders=recorders, revolutions=truth_revolutions(bench, args.cycles))

        recorders: list = []
        jobs = [pool.submit(record, s, p) for s, p in zip(states, paths, strict=True)]
        try:
            for job in jobs:
                job.result()
        except BaseException:  # Ctrl-C or a failed session: end the others cleanly (valid files)
            for r in recorders:
                r.stop("interrupted", "interrupt")
            raise
    assessed = assess_sessions([load_session(p, label=s.name) for p, s in zip(paths, states, strict=True)],
                               ensembles=ensembles, calibration=None)  # its own emulated mounts, not a lab's
    estimate_assessed(assessed, estimator, calibration=None)
    with output_folder(report_dir, force=force) as tmp:
        report = write_assessment_report(assessed, tmp, title=f"wearbench demo: {bench.name}, which state explains "
                                         f"each session, clearance and wear ({'twin' if args.twin else 'non-twin truths'})")
        save_estimator(estimator, tmp / "estimator.npz")
        if estimator.spread is not None:  # beside it, so that 'estimate --estimator' gives the same numbers
            save_estimator_spread(estimator, spread_path(tmp / "estimator.npz"))
    report = report.moved_to(report_dir)
    print(summary_text([s.name for s in states], assessed))
    print(f"\n{estimate_text([s.name for s in states], assessed)}")
    print(f"(the same numbers: wearbench estimate {sessions_dir}/SESSION.mcap --estimator {report_dir}/estimator.npz "
          "--calibration none)")
    print(f"\nreport: {report.html}\nscores: {report.scores_json}\nsessions: {sessions_dir}/ "
          f"({len(states)} MCAP files)\n{len(report.figures)} figures; {time.monotonic() - start:.0f} s")
    return 0


def claim_folder(out: Path, sessions: list[Path], report: Path, *, force: bool) -> bool:
    """Refuse (before anything runs) an ``out`` folder the demo may not write into: one with files
    in it that the demo did not mark, unless ``force``; a file at one of the demo's ``sessions``
    names that holds a session, in a folder the demo did not mark, even with ``force``. Marks ``out``
    as the demo's and returns whether its files may be replaced."""
    owned = (out / MARK).is_file()
    if not owned:
        check_output(out, force=force, option="--out", folder=True)
    force = force or owned
    for path in sessions:
        check_output(path, force=force, option="--out", session=owned)
    check_output(report, force=force, option="--out", folder=True)
    out.mkdir(parents=True, exist_ok=True)
    if not owned:
        (out / MARK).write_text("written by 'wearbench demo': a rerun of the demo into this folder replaces its "
                                "sessions/ and report/ files\n", encoding="utf-8")
    return force


def summary_text(truths, assessed) -> str:
    """Per session: its true state, the posterior of every state, the verdict, how many of its
    five-cycle windows are consistent with each state's ensemble windows, the fitted sensor delay and
    the peaks, as a plain-text table."""
    import numpy as np

    states = list(assessed[0].identification.posterior)
    rows = [("true state", *(f"p({s})" for s in states), "verdict", *(f"windows ok ({s})" for s in states),
             "delay ms", "peak |a| CFC180 meas./theory")]
    for truth, a in zip(truths, assessed, strict=True):
        r, b = a.identification, a.bands.summary()
        verdict = r.verdict + (f" ({r.cycles_needed} cycles would decide)" if r.verdict == "undecided"
                               and r.cycles_needed else "")
        own = a.windows[a.state].windows
        delay = f"{1e3 * float(np.median([w.delay_s for w in own])):.2f}" if own else "-"
        rows.append((truth, *(f"{r.posterior[s]:.3f}" for s in states), verdict,
                     *(f"{a.windows[s].consistent}/{len(a.windows[s].windows)}" for s in states), delay,
                     f"{b['peak_acc_measured_median']:.0f} / {b['peak_acc_theory_p5_p50_p95'][1]:.0f} m/s^2"))
    return _columns(rows)


def estimate_text(truths, assessed) -> str:
    """Per session: its true state, the estimate's medians and 90 % intervals of clearance, cycles run
    and wear depth, and whether a parameter value explains it, beside the identification's verdict."""
    from wearbench.validation.estimation.estimate import fmt_kcycles, fmt_mm, fmt_um
    from wearbench.validation.workflows.measure import named_outside

    rows = [("true bench", "identified", "clearance mm [90 %]", "cycles run [90 %]", "wear depth um [90 %]",
             "a value explains it")]
    for truth, a in zip(truths, assessed, strict=True):
        e = a.estimate
        if e is None or not e.explains:
            rows.append((truth, a.identification.verdict, "-", "-", "-", f"no (p {e.p_value:.2g})" if e else "-"))
            continue
        c, n, d = e.clearance, e.cycles_run, e.depth
        rows.append((truth, a.identification.verdict, f"{c.median * 1e3:.3f} [{c.text(fmt_mm)}]",
                     f"{n.median / 1e3:.0f}k [{n.text(fmt_kcycles)}]", f"{d.median * 1e6:.1f} [{d.text(fmt_um)}]",
                     f"yes (p {e.p_value:.2g})"))
    notes = [f"{truth}: {n}" for truth, a in zip(truths, assessed, strict=True) if (n := named_outside(a, a.estimate))]
    return "\n".join([_columns(rows), *notes])


def _columns(rows) -> str:
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in rows)
