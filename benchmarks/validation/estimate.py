"""Clearance-and-wear estimates on non-twin truths drawn from the prior: calibration, widths, cost.

Truths are never the estimator's training draws: each truth draws a clearance uniformly over the
design's range and a cycles-run value uniformly over [0, the design's last], draws its bench from
the bench file's [tolerances] with its own seed (20000 + k; the design uses 1..M, its wear spread
30000 + 100 i + k) and a random start, wears that bench from that clearance through those cycles in
its own wear run (one stage: a wear realisation no design ran; ``--truth-wear nominal``: the nominal
bench wears, as truths did before this option), and is seen through the emulator's sensor chain
(the bench file's [emulator.accelerometer]: mount resonance, anti-alias filter at 4x oversampling, noise, 16-bit ADC; with --sensor-paths a
mount/carriage mode drawn per truth in 0.3-3 kHz, damping 0.02-0.1, sensitivity +/-5 %; with
--cross-axis also a cross-axis sensitivity of 1-5 % to the carriage's lateral mode, 0.3-3 kHz), applied
in-process to the model's acceleration (no MCAP round trip: benchmarks/validation/identify.py covers that).
``--at 200000 --at-truths 10`` adds truths at that many cycles run (clearance from the prior).
``--lives L`` adds simulated lives for ``wearbench track``: one bench per life (clearance from the
prior, its own seed) worn with a coefficient ``--life-factor`` (1.3) times the file's, recorded
(``--life-cycles`` cycles each) after 0, 100k, 200k, 300k and 400k cycles (``--life-step``); the
fitted factor's 90 % interval against the truth, and the cycles until a clearance limit the truth
reaches at 500k cycles (its wear run goes one step further) against the track's cycles-to-limit
interval; ``--life-sessions 0,200k`` (repeatable) tracks that subset of each life's sessions. Each
subset is tracked without a move, with the bench's move from new to worn beyond the estimator's
(``track_move.life_move``) measured on the other half of the lives (never on the life scored), and
with the move stored beside the shipped estimator (``--shipped``; or ``--move FILE``), which ``track``
uses by default (the table says whether it was measured on the lives scored).
``--store-move FILE --move-from default,drawn`` measures the move on the lives of those path kinds
(this run's seeds), with the features' rate along the lives against clearance (``track.life_rate``),
and stores it: how the shipped one was made (``--cached-only``: from the cache). When the stored move
carries a rate, a row "stored, sd 0.2" tracks with the constant spread instead (``--life-rows``: only
the rows named).

Prints: estimator build and fit times, time per estimate; per parameter (clearance, cycles run,
wear depth) the coverage of the 50 % and 90 % intervals with its binomial standard error, the
rank histogram (posterior CDF at the truth, 10 bins; flat when calibrated); median 90 % widths at
5, 10 and 20 cycles; the clearance median absolute error; "no parameter value explains it" rates;
for the --at truths, how often the 90 % cycles-run interval excludes 0 and twice the truth; for
the lives, the coverage of the wear factor and of the cycles to the limit (also with the bench's
offset constant over the life, ``track(drift=False)``); for the --at truths, what limits their
interval (Fisher information) and what a lab must record (cycles per session, sessions of one bench)
for it to exclude 0 and twice the truth.

    .venv/bin/python -m benchmarks.validation.estimate [--truths 100] [--cycles 20] [--realisations 16]
    .venv/bin/python -m benchmarks.validation.estimate --design-clearances 0.25mm,0.45mm,0.65mm \\
        --design-cycles 0,300000,600000 --realisations 8 --truths 12        # a small run
    .venv/bin/python -m benchmarks.validation.estimate --shipped --truths 40 --json docs/results/data/estimator-coverage.json
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from dataclasses import replace

import numpy as np
from wearbench.synthetic.lives import (
    life_features,
    life_means,
    move_with_rate,
    state_session,
    surfaces_wear,
    truth_features,
)

from benchmarks.result_json import Run, column, table, write_result


def parse_cycles(text: str) -> float:
    """'200k', '200000' or '2e5' -> 200000.0"""
    text = text.strip().lower()
    return float(text[:-1]) * 1e3 if text.endswith("k") else float(text)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--truths", type=int, default=100, help="truths drawn from the prior (100)")
    ap.add_argument("--cycles", type=int, default=20, help="cycles per truth session (20)")
    ap.add_argument("--design-clearances", default="0.25mm,0.35mm,0.45mm,0.55mm,0.65mm")
    ap.add_argument("--design-cycles", default="0,200000,400000,600000")
    ap.add_argument("--realisations", type=lambda v: [int(m) for m in v.split(",")], default=[48],
                    help="realisations per design point (48, as shipped); a list (16,48) builds one estimator per size and "
                    "reports each on the same truths (the lives and --store-move use the first)")
    ap.add_argument("--small", action="store_true", help="EstimatorDesign.small() (the demo's) instead of the "
                    "--design-* options")
    ap.add_argument("--ensemble-cycles", type=int, default=8)
    ap.add_argument("--sensor-paths", action="store_true", help="draw each truth's sensor path (see above)")
    ap.add_argument("--cross-axis", action="store_true", help="with --sensor-paths: draw the cross-axis part too "
                    "(SensorSpread's whole draw; the cached drawn lives and the shipped move are axial only)")
    ap.add_argument("--truth-wear", choices=("drawn", "nominal"), default="drawn",
                    help="who wears a truth through its cycles run: its own drawn bench from its random start (drawn, "
                    "a wear realisation no design ran) or the bench file's nominal bench (nominal, as truths wore before this option)")
    ap.add_argument("--at", type=float, default=200_000.0, help="cycles run of the --at-truths (200000)")
    ap.add_argument("--at-truths", type=int, default=0, help="extra truths at --at cycles run (0)")
    ap.add_argument("--states", type=int, default=0, help="sessions per worn state of the bench file, on the state's "
                    "own surface files (0)")
    ap.add_argument("--lives", type=int, default=0, help="simulated lives for track (0)")
    ap.add_argument("--life-factor", type=float, default=1.3, help="the lives' wear coefficient / the file's (1.3)")
    ap.add_argument("--life-cycles", type=int, default=20, help="cycles per session of a life (20)")
    ap.add_argument("--life-step", type=float, default=100_000.0,
                    help="cycles between a life's sessions (100000); the sessions' effective cycles (x the factor) "
                    "must lie inside the design")
    ap.add_argument("--life-sessions", action="append", type=lambda v: [parse_cycles(x) for x in v.split(",")],
                    help="a subset of each life's sessions to track, e.g. 0,200k (repeatable; default all five)")
    ap.add_argument("--verbose-lives", action="store_true", help="print every life's track")
    ap.add_argument("--life-rows", help="only these of the lives' rows, separated by ';' (e.g. 'stored move;stored, sd "
                    "0.2'; names as printed; default all)")
    ap.add_argument("--move", metavar="FILE.move.npz", help="score this stored move on the lives (default: the one "
                    "stored beside the shipped estimator, with --shipped)")
    ap.add_argument("--store-move", metavar="FILE.move.npz", help="measure the move on the lives of --move-from "
                    "(this run's seeds; with --cached-only, those in the cache) and store it (never over a file)")
    ap.add_argument("--move-from", default="default,drawn", help="path kinds whose lives --store-move pools: "
                    "default, drawn or default,drawn (default,drawn)")
    ap.add_argument("--shipped", action="store_true", help="use the shipped estimator when its key matches the design")
    ap.add_argument("--cached-only", action="store_true",
                    help="use only the truths and lives an earlier (interrupted) run left in --cache; say how many")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--cache", help="cache folder (default: a fresh one: the estimator is built cold)")
    ap.add_argument("--seed", type=int, default=20000)
    ap.add_argument("--json", metavar="PATH", help="also write the truths' calibration and widths as a result for "
                    "the documentation (docs/results/data/)")
    args = ap.parse_args()
    run_clock = Run()
    if args.cross_axis and not args.sensor_paths:
        ap.error("--cross-axis: expected with --sensor-paths (it draws the cross-axis part of a drawn path)")
    args.sensor_paths = "cross-axis" if args.cross_axis else args.sensor_paths  # truth_features' spread
    args.life_sessions = args.life_sessions or [[k * args.life_step for k in range(5)]]
    for subset in args.life_sessions:
        if any(abs(n / args.life_step - round(n / args.life_step)) > 1e-9 or not 0 <= n <= 4 * args.life_step
               for n in subset) or len(set(subset)) < 2:
            ap.error(f"--life-sessions {subset}: expected two or more of the lives' sessions, 0 to "
                     f"{4 * args.life_step:,.0f} in steps of {args.life_step:,.0f}")
    if args.store_move and os.path.exists(args.store_move):
        ap.error(f"--store-move {args.store_move}: exists; expected a new file (remove it to measure again)")
    os.environ["WEARBENCH_CACHE"] = args.cache or tempfile.mkdtemp(prefix="wearbench-estimate-")

    from wearbench.bench.load import load_bench, shipped_bench
    from wearbench.compute import Task, TaskFailure, compute_client, run_tasks, task_key
    from wearbench.compute.task_cache import MISSING, cache_load
    from wearbench.validation.estimation.estimate import EstimatorDesign, build_estimator
    from wearbench.validation.estimation.move import load_move, stored_move

    bench = load_bench(shipped_bench("ninebar-testbed"))
    designs = [EstimatorDesign.small()] if args.small else [EstimatorDesign.parse(
        args.design_clearances, args.design_cycles, realisations=m, ensemble_cycles=args.ensemble_cycles)
        for m in args.realisations]
    design = designs[0]
    rng = np.random.default_rng(args.seed)
    lo, hi, n_max = design.clearances[0], design.clearances[-1], design.cycles[-1]
    truths = [(float(rng.uniform(lo, hi)), float(rng.uniform(0, n_max)), args.seed + k) for k in range(args.truths)]
    at_rng = np.random.default_rng(args.seed + 1)  # its own stream: the same --at truths whatever --truths
    at_truths = [(float(at_rng.uniform(lo, hi)), args.at, args.seed + 5000 + k) for k in range(args.at_truths)]
    life_rng = np.random.default_rng(args.seed + 2)
    lives = [(float(life_rng.uniform(0.3e-3, 0.55e-3)), args.seed + 8000 + k) for k in range(args.lives)]
    worn = [st for st in bench.states if st.surfaces]
    state_truths = [(st, args.seed + 7000 + 100 * i + k) for i, st in enumerate(worn) for k in range(args.states)]

    def truth_key(c, n, s):
        return task_key("estimate-truth", c, n, s, args.cycles, args.sensor_paths, args.truth_wear)

    def life_key(c, s, spread=args.sensor_paths):
        return task_key("estimate-life", c, args.life_factor, args.life_step, s, args.life_cycles, spread)

    lives_asked = list(lives)
    if args.cached_only:  # what an interrupted run finished (the draws are the same for every size)
        asked = (len(truths), len(at_truths), len(lives))
        truths = [t for t in truths if cache_load(truth_key(*t)) is not MISSING]
        at_truths = [t for t in at_truths if cache_load(truth_key(*t)) is not MISSING]
        lives = [t for t in lives if cache_load(life_key(*t)) is not MISSING]
        print(f"cached only: {len(truths)} of {asked[0]} truths from the prior, {len(at_truths)} of {asked[1]} at "
              f"--at, {len(lives)} of {asked[2]} lives")
    with compute_client(workers=args.workers):
        t0 = time.perf_counter()

        def run(batch, name):
            return run_tasks([Task(truth_features, {"bench": bench, "clearance": c, "cycles_run": n, "seed": s,
                                                    "cycles": args.cycles, "spread": args.sensor_paths,
                                                    "wear": args.truth_wear},
                                   truth_key(c, n, s), f"truth {s}")
                              for c, n, s in batch], progress=name)

        done = run(at_truths, "truths at --at") + run(truths, "truths from the prior")  # the shorter batch first
        truths = at_truths + truths
        state_tasks = [state_session(bench, st, s, args.cycles, args.sensor_paths) for st, s in state_truths]
        state_done = run_tasks(state_tasks, progress="sessions of the worn states")
        t_truth = time.perf_counter() - t0
        t0 = time.perf_counter()
        life_runs = run_tasks([Task(life_features, {"bench": bench, "clearance": c, "factor": args.life_factor,
                                                    "step": args.life_step, "stages": 5, "seed": s,
                                                    "cycles": args.life_cycles, "spread": args.sensor_paths},
                                    life_key(c, s), f"life {s}")
                               for c, s in lives], progress="lives") if lives else []
        t_lives = time.perf_counter() - t0
        built = []  # after the truths, which never depend on it
        for d in designs:  # a larger one reuses a shipped smaller one's realisations (build_estimator)
            t0 = time.perf_counter()
            built.append((build_estimator(bench, d, label=f"estimator ({d.settings.realisations})",
                                          shipped=args.shipped), time.perf_counter() - t0))
    ok = [(t, d) for t, d in zip(truths, done, strict=True) if not isinstance(d, TaskFailure)]
    failed = [d for d in done if isinstance(d, TaskFailure)]
    reported = [report_truths(est, t_build, ok, failed, t_truth, args) for est, t_build in built]
    est, (model, tables) = built[0][0], reported[0]
    if est.spread is not None:  # the same truths judged by the estimator without its wear spread
        print("\nthe same estimator without its wear spread (one wear run per design clearance):")
        _, alone = report_truths(replace(est, spread=None), 0.0, ok, failed, t_truth, args)
        tables["without spread"] = {**alone["calibration"], "title": alone["calibration"]["title"] + ", without the "
                                    "estimator's wear spread (one wear run per design clearance)"}
        tables["findings"].append("Without its wear spread the same estimator's 90 % intervals hold the truth in "
                                  + ", ".join(f"{r[1]:.2f} ({r[0]})" for r in alone["calibration"]["rows"]) + ".")
    if state_truths:
        tables["states"] = report_states(model, state_truths, state_tasks, state_done, args)
        pooled = tables["states"]["rows"][-1]
        tables["findings"].append(
            f"On {pooled[1]} sessions of the bench file's worn states, on surface files no design ran, the 90 % intervals "
            f"hold the truth in {pooled[8]:.2f} (clearance), {pooled[9]:.2f} (cycles run), {pooled[10]:.2f} (wear depth).")
    if args.json:
        d = est.design
        write_result(args.json, question="Do the estimator's intervals hold the truth on benches it never saw?",
                     script=__file__, run=run_clock, findings=tables.pop("findings"),
                     seeds={"truths": f"{args.seed}..{args.seed + args.truths - 1}",
                            "estimator realisations": f"{d.settings.seed}..{d.settings.seed + d.settings.realisations - 1}"},
                     tables=list(tables.values()),
                     notes=[f"Truths: a clearance uniform over {d.clearances[0] * 1e3:g}-{d.clearances[-1] * 1e3:g} mm and "
                            f"cycles run uniform over 0-{d.cycles[-1]:,.0f}, each bench drawn from the bench file's "
                            "[tolerances] with a seed the estimator does not use, worn in its own wear run ("
                            + ("the drawn bench itself, from its random start: a wear realisation no design ran"
                               if args.truth_wear == "drawn" else "the nominal bench") + "), seen "
                            "through the emulator's sensor chain"
                            + (" with a drawn mount" if args.sensor_paths else "") + ".",
                            ("A calibrated 90 % interval holds the truth in 0.90 of truths, within about two standard "
                            "errors (the se column).")]
                     + ([(f"Worn states: {args.states} sessions per worn state of the bench file, each on a bench drawn "
                         "with its own seed and the state's own surface files (worn by an earlier version of the "
                         "wear model, never a run of the estimator's); truth: the state's clearance, the files' "
                         "cycles and wear depth.")] if state_truths else []))
        print(f"results: {args.json}")
    if args.store_move:
        store_move(bench, model, lives_asked, life_key, args)
    if lives:
        scored = args.move or args.store_move  # a rebuilt estimator's shipped move is another key's
        stored = load_move(scored, model.estimator) if scored else stored_move(est)
        report_lives(bench, model, lives, life_runs, args, t_lives, stored)


def report_truths(est, t_build: float, ok, failed, t_truth: float, args):
    """Fit ``est`` and print its calibration on the truths ``ok`` ((c, n, seed), result) at 5, 10 and
    --cycles cycles: coverage, ranks, widths, clearance errors, the --at truths; returns the model."""
    from wearbench.validation.estimation.estimate import estimate_features, fit_estimator
    from wearbench.validation.measurement.features import CycleFeatures, FeatureSpec

    design, n_max = est.design, est.design.cycles[-1]
    t0 = time.perf_counter()
    model = fit_estimator(est)
    t_fit = time.perf_counter() - t0
    spec = FeatureSpec()
    rows = {}
    t0 = time.perf_counter()
    for n in (5, 10, args.cycles):
        rows[n] = [(t, d["depth"], estimate_features(CycleFeatures(spec, d["features"][:n], np.zeros(n)), model))
                   for t, d in ok if d["features"].shape[0] >= n]
    t_est = (time.perf_counter() - t0) / max(1, sum(len(r) for r in rows.values()))
    print(f"\nestimator: {len(design.clearances)} clearances {[round(c * 1e3, 3) for c in design.clearances]} mm x "
          f"{len(design.cycles)} cycles-run values {[int(c) for c in design.cycles]}, {design.settings.realisations} "
          f"realisations x {design.settings.cycles} cycles; temperature {model.temperature:.2f}; emulator error (median sd) "
          f"{np.median(np.sqrt(model.discrepancy)):.3f}")
    print(f"build {t_build:.0f} s (wear runs + ensembles: what the cache and a shipped file lack)   truths {t_truth:.0f} s   fit {t_fit:.1f} s   "
          f"one estimate {t_est * 1e3:.0f} ms   truths failed {len(failed)}"
          + (f" ({failed[0]})" if failed else "") + ("   sensor paths drawn: modes "
          + ", ".join(f"{d['mode']:.0f}" for _, d in ok[:12]) + " Hz ..." if args.sensor_paths else ""))
    prior = [r for r in rows[args.cycles] if r[0][2] < args.seed + 5000]
    calibration_rows, width_rows = [], []
    print(f"\ncalibration at {args.cycles} cycles, {len(prior)} truths drawn from the prior:")
    print("parameter       90 % coverage (se)   50 % coverage (se)   rank histogram (10 bins)")
    for name, truth_of, interval in (("clearance", lambda t, dep: t[0], lambda e: e.clearance),
                                     ("cycles run", lambda t, dep: t[1], lambda e: e.cycles_run),
                                     ("wear depth", lambda t, dep: dep, lambda e: e.depth)):
        inside = [e.explains and interval(e).contains(truth_of(t, dep), 90) for t, dep, e in prior]
        half = [e.explains and interval(e).contains(truth_of(t, dep), 50) for t, dep, e in prior]
        ranks = [rank(e, truth_of(t, dep), name, model) for t, dep, e in prior]
        hist = np.histogram(ranks, bins=10, range=(0, 1))[0]
        k = max(1, len(prior))
        calibration_rows.append([name, float(np.mean(inside)), float(np.mean(half)), float(np.sqrt(0.09 / k)),
                                 " ".join(str(h) for h in hist)])
        print(f"{name:14s}  {np.mean(inside):.2f} ({np.sqrt(0.09 / k):.2f})          {np.mean(half):.2f} "
              f"({np.sqrt(0.25 / k):.2f})          {' '.join(str(h) for h in hist)}")
    print("\nmedian 90 % interval width and clearance error against cycles used:")
    print("cycles  truths  clearance width (mm)  cycles-run width  wear-depth width (um)  |clearance error| median (mm)"
          "  'no parameter value explains it'")
    for n, rs in rows.items():
        rs = [r for r in rs if r[0][2] < args.seed + 5000]
        if not rs:
            continue
        cw = np.median([e.clearance.hi90 - e.clearance.lo90 for *_, e in rs]) * 1e3
        nw = np.median([e.cycles_run.hi90 - e.cycles_run.lo90 for *_, e in rs])
        dw = np.median([e.depth.hi90 - e.depth.lo90 for *_, e in rs]) * 1e6
        err = np.median([abs(e.clearance.median - t[0]) for t, _, e in rs]) * 1e3
        none = np.mean([not e.explains for *_, e in rs])
        width_rows.append([n, len(rs), float(cw), float(nw), float(dw), float(err), float(none)])
        print(f"{n:6d}  {len(rs):6d}  {cw:20.3f}  {nw:16,.0f}  {dw:23.1f}  {err:29.3f}  {none:.2f}")
    prior = [(t[0], e.clearance.median - t[0]) for t, _, e in rows[args.cycles] if t[2] < args.seed + 5000]
    if prior:
        mid = [d for c, d in prior if 0.45e-3 <= c <= 0.55e-3]
        print(f"clearance error (posterior median - truth) at {args.cycles} cycles, median: "
              f"{np.median([d for _, d in prior]) * 1e3:+.4f} mm ({len(prior)} truths); at 0.45-0.55 mm "
              + (f"{np.median(mid) * 1e3:+.4f} mm ({len(mid)})" if mid else "none"))
    at = [r for r in rows[args.cycles] if r[0][2] >= args.seed + 5000]
    if at:
        excl = np.mean([e.explains and e.cycles_run.lo90 > 0 and e.cycles_run.hi90 < 2 * args.at for *_, e in at])
        held = np.mean([e.explains and e.cycles_run.contains(args.at) for *_, e in at])
        c_held = np.mean([e.explains and e.clearance.contains(t[0]) for t, _, e in at])
        print(f"\n{len(at)} truths at {args.at:,.0f} cycles run: the 90 % interval excludes 0 and {2 * args.at:,.0f} "
              f"in {excl:.2f} (a design that ends at {n_max:,.0f} cycles excludes its end in every interval that "
              f"does not reach it); the 90 % intervals hold the cycles run in {held:.2f}, the clearance in "
              f"{c_held:.2f}; median cycles-run interval {np.median([e.cycles_run.lo90 for *_, e in at]):,.0f}-"
              f"{np.median([e.cycles_run.hi90 for *_, e in at]):,.0f}")
        information(model, [t[0] for t, _, _ in at], args.at)
        recording(model, [t[0] for t, _, _ in at], args.at)
    size = (f"{len(design.clearances)} x {len(design.cycles)} design points, {design.settings.realisations} realisations "
            f"x {design.settings.cycles} cycles")
    tables = {
        "calibration": table(f"coverage at {args.cycles} cycles per session, {len(prior)} truths; estimator {size}", [
            column("parameter"), column("90 % coverage", None, ".2f"), column("50 % coverage", None, ".2f"),
            column("se of the 90 % coverage", None, ".2f", "binomial, sqrt(0.9 x 0.1 / truths)"),
            column("rank histogram", None, None, "posterior CDF at the truth in 10 bins: flat when calibrated")],
            calibration_rows),
        "widths": table("median 90 % interval width and clearance error against the cycles a session holds", [
            column("cycles"), column("truths"), column("clearance width", "mm", ".3f"),
            column("cycles-run width", "cycles", ",.0f"), column("wear-depth width", "um", ".1f"),
            column("median clearance error", "mm", ".3f"),
            column("'no parameter value explains it'", None, ".2f", "share of the truths")], width_rows),
        "findings": [f"On {len(prior)} single {args.cycles}-cycle sessions of benches the estimator never saw, its 90 % "
                     "intervals hold the truth in " + ", ".join(f"{r[1]:.2f} ({r[0]})" for r in calibration_rows)
                     + (f"; median clearance error {width_rows[-1][5]:.3f} mm." if width_rows else ".")]}
    return model, tables


def report_states(model, state_truths, tasks, done, args) -> dict:
    """Score the sessions of the bench file's worn states (``tasks``: ``state_session``, on their own
    surface files): per state the truth, the medians of the estimate and how many 90 % intervals hold
    it; one row for all."""
    from wearbench.compute import TaskFailure
    from wearbench.validation.estimation.estimate import estimate_features
    from wearbench.validation.measurement.features import CycleFeatures

    cycles_run = {st.name: surfaces_wear(st.surfaces)[0] for st, _ in state_truths}
    per_state: dict[str, list] = {}
    for (st, _), task, d in zip(state_truths, tasks, done, strict=True):
        if isinstance(d, TaskFailure):
            print(f"{st.name}: a session failed: {d}")
            continue
        truth = (task.kwargs["clearance"], cycles_run[st.name], d["depth"])
        f = d["features"][:args.cycles]
        per_state.setdefault(st.name, []).append((truth, estimate_features(CycleFeatures(model.estimator.spec, f,
                                                                                          np.zeros(len(f))), model)))
    parts = (lambda e: e.clearance, lambda e: e.cycles_run, lambda e: e.depth)
    rows = []
    print(f"\nthe bench file's worn states, {args.states} sessions each on their own surface files:")
    print("state                 sessions  truth (mm, k cycles, um)   median estimate (mm, k cycles, um)   "
          "90 % holds c / N / depth   explained")
    for name, rs in list(per_state.items()) + [("all worn states", [r for v in per_state.values() for r in v])]:
        n = len(rs)
        holds = [sum(e.explains and part(e).contains(t[k]) for t, e in rs) for k, part in enumerate(parts)]
        med = [float(np.median([part(e).median for _, e in rs])) for part in parts]
        t = rs[0][0]
        rows.append([name, n, t[0] * 1e3, t[1] / 1e3, t[2] * 1e6, med[0] * 1e3, med[1] / 1e3, med[2] * 1e6,
                     *(h / n for h in holds), sum(e.explains for _, e in rs) / n])
        same = all(r[0] == t for r in rs)
        print(f"{name:20s}  {n:8d}  " + (f"{t[0] * 1e3:.3f}, {t[1] / 1e3:.0f}, {t[2] * 1e6:.1f}" if same else "(several)")
              .ljust(27) + f"{med[0] * 1e3:.3f}, {med[1] / 1e3:.0f}, {med[2] * 1e6:.1f}".ljust(37)
              + f"{holds[0]}/{n}  {holds[1]}/{n}  {holds[2]}/{n}".ljust(26) + f"{rows[-1][-1]:.2f}")
    rows[-1][2:5] = [None, None, None]  # the pooled row has no one truth
    return table(f"the bench file's worn states on their own surface files, {args.cycles}-cycle sessions", [
        column("state"), column("sessions"), column("truth clearance", "mm", ".3f"),
        column("truth cycles run", "k cycles", ".0f"), column("truth wear depth", "um", ".1f"),
        column("median clearance", "mm", ".3f"), column("median cycles run", "k cycles", ".0f"),
        column("median wear depth", "um", ".1f"), column("90 % holds clearance", None, ".2f"),
        column("90 % holds cycles run", None, ".2f"), column("90 % holds wear depth", None, ".2f"),
        column("explained", None, ".2f", "share of sessions some parameter value explains")], rows)


def information(model, clearances, at: float) -> None:
    """What limits the cycles-run interval at ``at`` cycles: the local (Fisher) sd of cycles run and
    clearance at the truths' clearances with the model's covariance, then with one of its parts left
    out or changed (tempered as the posterior is). A central 90 % interval excludes 0 and 2 x ``at``
    when its median lies within ``at`` - 1.645 sd of the truth: for a Gaussian median, in a share
    P(|Z| < at / sd - 1.645) of sessions, the 'expected' column."""
    from scipy import stats

    st = model.stats[model.reference]
    sb, sw, d = st.between, st.within, np.diag(model.discrepancy)
    ff = st.nuisance @ st.nuisance.T if st.nuisance is not None else 0.0 * sb
    ens, floor = (sb + sw / st.cycles) / st.realisations, np.diag(st.floor)
    cases = {"as estimated, 20 cycles": sb + sw / 20 + ens + floor + ff + d,
             "100 cycles": sb + sw / 100 + ens + floor + ff + d,
             "an endless session": sb + ens + floor + ff + d,
             "20 cycles, no emulator error": sb + sw / 20 + ens + floor + ff,
             "20 cycles, exact design means, no emulator error": sb + sw / 20 + floor + ff,
             "20 cycles, sensor path known": sb + sw / 20 + ens + floor + d,
             "20 cycles, no floor": sb + sw / 20 + ens + ff + d,
             "20 cycles, the bench's tolerances known": sw / 20 + ens + floor + ff + d}

    print(f"\nwhat limits the cycles-run interval at {at:,.0f} cycles (local Fisher information at the {len(clearances)} "
          "truths' clearances, median over them):")
    print("covariance                                          sd cycles run   sd clearance (mm)   expected exclusion")
    for name, cov in cases.items():
        sds = []
        for c in clearances:
            g = _gradient(model, c, at)
            inv = np.linalg.inv(g.T @ np.linalg.solve(cov, g)) * model.temperature
            sds.append(np.sqrt(np.diag(inv)))
        sd_n, sd_c = np.median(sds, axis=0)[::-1]
        expected = 2 * stats.norm.cdf(max(0.0, at / sd_n - 1.645)) - 1
        print(f"{name:50s}  {sd_n:13,.0f}   {sd_c * 1e3:17.4f}   {expected:18.2f}")


def _gradient(model, clearance: float, cycles_run: float) -> np.ndarray:
    """(p, 2): the emulated mean's derivatives in the clearance and the cycles run, central differences."""
    hc, hn = 5e-6, 5e3
    return np.stack([(model.mean(clearance + hc, cycles_run) - model.mean(clearance - hc, cycles_run)) / (2 * hc),
                     (model.mean(clearance, cycles_run + hn) - model.mean(clearance, cycles_run - hn)) / (2 * hn)],
                    axis=1)


def recording(model, clearances, at: float) -> None:
    """What a lab must record for the cycles-run interval at ``at`` to exclude 0 and 2 x ``at``: the
    local (Fisher) sd of the effective cycles run at ``at`` for one session, and for sessions of the
    same bench at equally spaced cycles run up to ``at`` (``track``: they share the bench's offset and
    sensor path, the worn ones its move from new, each has its own cycle-to-cycle and estimator error,
    and the wear coefficient scales them all), against the cycles per session; tempered as the posterior is. 'expected exclusion' as in
    :func:`information`."""
    from scipy import linalg, stats
    from wearbench.validation.estimation.track import session_covariances, wear_drift

    st = model.stats[model.reference]
    drift = wear_drift(model)
    shared, own = session_covariances(model)
    print(f"\nwhat to record for the cycles-run interval at {at:,.0f} to exclude 0 and {2 * at:,.0f} (local Fisher "
          f"information, median over the {len(clearances)} truths' clearances; sd of the effective cycles run at "
          f"{at:,.0f} / expected exclusion):")
    counts = (5, 10, 20, 50, 100, 1000)
    print("sessions of one bench at cycles run            " + "".join(f"{n:>10d} cyc" for n in counts) + "      endless")
    for sessions in (1, 2, 3, 5):
        f = np.array([1.0]) if sessions == 1 else np.linspace(0.0, 1.0, sessions)
        cells = []
        for n in (*counts, np.inf):
            sds = []
            for c in clearances:
                g = np.concatenate([_gradient(model, c, fi * at) * [1.0, fi] for fi in f])
                worn = (f > 0) * float(f.size > 1)  # a worn session's share of the bench's move from new (track's)
                cov = (np.kron(np.ones((f.size, f.size)), shared) + np.kron(np.outer(worn, worn), drift)
                       + linalg.block_diag(*[st.within / n + own] * f.size))
                sds.append(np.sqrt(np.linalg.inv(g.T @ np.linalg.solve(cov, g))[1, 1] * model.temperature))
            sd = float(np.median(sds))
            cells.append(f"{sd / 1e3:7.0f}k/{2 * stats.norm.cdf(max(0.0, at / sd - 1.645)) - 1:.2f}")
        name = "one session" if sessions == 1 else ", ".join(f"{v * at / 1e3:.0f}k" for v in f)
        print(f"{name:45s}  " + "  ".join(cells))


def store_move(bench, model, lives, life_key, args) -> None:
    """Measure the move from new to worn (``track_move.life_move``) on the lives of the --move-from
    path kinds (this run's seeds; cached ones only with --cached-only), store it at --store-move, and
    print how the kinds' moves compare: along the direction that tells the factor (the estimator's
    change from new to 1.3 x 200k cycles at each life's clearance, weighted by one 20-cycle session's
    inverse covariance with the drift; in units of that change) and overall (Hotelling's T^2 of the
    difference, against its chi-square with p degrees of freedom)."""
    from scipy import stats
    from wearbench.compute import Task, TaskFailure, run_tasks
    from wearbench.compute.task_cache import MISSING, cache_load
    from wearbench.validation.estimation.move import life_move, save_move
    from wearbench.validation.estimation.track import session_covariances, wear_drift
    from wearbench.validation.inference.statistics import shrunk_covariance

    every = [k * args.life_step for k in range(5)]
    kinds = {"default": False, "drawn": True}
    shared, own = session_covariances(model)
    weight = np.linalg.inv(shared + model.stats[model.reference].within / 20 + own + wear_drift(model))
    pooled, about, per_kind, kind_seeds = [], {"sensor_paths": [], "seeds": [], "clearances": []}, {}, []
    for kind in args.move_from.split(","):
        if kind not in kinds:
            raise SystemExit(f"--move-from {args.move_from!r}: {kind!r}: expected default or drawn")
        chosen = [(c, s) for c, s in lives if not args.cached_only or cache_load(life_key(c, s, kinds[kind])) is not MISSING]
        runs = run_tasks([Task(life_features, {"bench": bench, "clearance": c, "factor": args.life_factor,
                                               "step": args.life_step, "stages": 5, "seed": s,
                                               "cycles": args.life_cycles, "spread": kinds[kind]},
                               life_key(c, s, kinds[kind]), f"life {s}") for c, s in chosen], progress=f"lives, {kind}")
        done = [((c, s), r) for (c, s), r in zip(chosen, runs, strict=True) if not isinstance(r, TaskFailure)]
        rows = [(life_means(r), every, c, args.life_factor) for (c, _), r in done]
        per_kind[kind] = life_move(model, rows)
        along = []
        for xbars, _, c, f in rows:
            g = model.mean(c, f * 2 * args.life_step) - model.mean(c, 0.0)
            along.append(float(per_kind[kind].rows[len(along)] @ weight @ g / (g @ weight @ g)))
        print(f"move, {kind} path: {len(rows)} lives; along the change from new to {args.life_factor * 2 * args.life_step:,.0f}"
              f" effective cycles: {np.mean(along):+.3f} (se {np.std(along, ddof=1) / np.sqrt(len(along)):.3f}) of it")
        pooled += rows
        about["sensor_paths"].append("drawn mounts" if kinds[kind] else "default path")
        about["seeds"] += [s for (_, s), _ in done]
        kind_seeds.append([s for (_, s), _ in done])
        about["clearances"] += [c for (c, _), _ in done]
    if len(per_kind) == 2 and len({tuple(seeds) for seeds in kind_seeds}) == 1:
        a, b = per_kind.values()  # paired by seed: one seed's two lives are one bench, clearance and wear run
        diff = a.rows - b.rows
        d = diff.mean(axis=0)
        t2 = float(d @ np.linalg.solve(shrunk_covariance(diff) / len(diff), d))
        same = [np.corrcoef(a.rows[:, k], b.rows[:, k])[0, 1] for k in range(d.size)]
        print(f"the two kinds' moves differ (paired by seed) by T^2 = {t2:.1f} over {d.size} features (chi-square p "
              f"{stats.chi2.sf(t2, d.size):.2g}); one seed's two lives (one bench seen through two sensor paths) "
              f"correlate {np.median(same):.2f} (median over features)")
    # a seed is one drawn bench (its tolerances, clearance and wear run): its lives through the two path kinds
    # are one bench seen twice, averaged before the move's error is taken (life_move's benches)
    move = move_with_rate(model, pooled, {"bench": bench.name, **about, "factor": args.life_factor, "sessions": every,
                                          "cycles": args.life_cycles, "measured_by": "benchmarks/validation/estimate.py "
                                          "--store-move --move-from " + args.move_from},
                          cycles=args.life_cycles, benches=about["seeds"])
    save_move(move, args.store_move)
    print(f"stored: {args.store_move}: move from new to worn {move.describe()}")


def _held_out(move, lives, args) -> str:
    """Whether the scored lives are outside the lives ``move`` was measured on: their seeds (a seed is
    one drawn bench, clearance and wear run) and their sensor path kind."""
    seeds = set(move.about.get("seeds", []))
    overlap = sum(s in seeds for _, s in lives)
    if not overlap:
        return "held out (other benches)"
    kind = "drawn mounts" if args.sensor_paths else "default path"
    if kind not in move.about.get("sensor_paths", []):
        return f"{overlap} of these {len(lives)} benches measured through another sensor path: held out by path only"
    return f"measured on {overlap} of these {len(lives)} lives: NOT held out"


def report_lives(bench, model, lives, runs, args, seconds: float, stored=None) -> None:
    """Coverage of the track's wear factor, cycles to a limit and initial clearance over the simulated
    lives, for every --life-sessions subset of their sessions: without a move (as track gave them before
    a move was stored), with the bench's move from new to worn beyond the estimator's measured on the
    other half of the lives (``track_move.life_move``; lives split by their order, first half and second
    half, each scored with the move of the other), so no life is scored with a term measured on it, and
    with the ``stored`` move (track's default; said whether it was measured on these lives), and with
    it but without the features' rate spread (``track_features(rate_spread=0)``, track before it)."""
    from wearbench.compute import TaskFailure
    from wearbench.validation.estimation.move import life_move
    from wearbench.validation.estimation.track import RATE_SPREAD, depth_curve, track_features
    from wearbench.validation.measurement.features import CycleFeatures, FeatureSpec

    n_curve, d_curve = depth_curve(model)
    good = [((c, seed), r) for (c, seed), r in zip(lives, runs, strict=True) if not isinstance(r, TaskFailure)]
    for (c, seed), r in zip(lives, runs, strict=True):
        if isinstance(r, TaskFailure):
            print(f"life {seed} failed: {r}")
    if not good:
        return
    every = [k * args.life_step for k in range(5)]
    means = [life_means(r) for _, r in good]
    half = len(good) // 2
    halves = [range(half, len(good)), range(half)]  # life i is scored with the move of the other half
    moves = [life_move(model, [(means[i], every, good[i][0][0], args.life_factor) for i in part]) for part in halves
             ] if half >= 3 else []  # each half's move needs three lives
    ratios = []
    for (c, _), r in good:  # the truth's depth against the estimator's trajectory at the same effective cycles
        i = int(np.argmin(np.abs(model.grid_c - c)))
        ratios.append([r["depth"][k] / np.interp(args.life_factor * k * args.life_step, n_curve, d_curve[i])
                       for k in range(1, 6)])
    print(f"\n{len(good)} lives ({seconds:.0f} s), wear factor {args.life_factor}, {args.life_cycles} cycles per session; "
          "90 % (50 %) coverage; factor ranks: the posterior CDF at the truth, 5 bins (flat when calibrated)")
    if stored is not None:
        print(f"stored move {stored.describe()}: {_held_out(stored, [life for life, _ in good], args)}")
    print("sessions at (k cycles)   track             factor 90 (50)   to limit 90 (50)   clearance 90 (50)   "
          "clearance error   factor interval   factor ranks")
    for subset in args.life_sessions:
        idx = [round(n / args.life_step) for n in subset]
        cycles_run = [every[k] for k in idx]
        names = (["no move"] + ["move, other half"] * bool(moves) + ["stored move"] * (stored is not None)
                 + ["stored, sd 0.2"] * (stored is not None and stored.rate is not None)
                 + ["stored, rate 0"] * (stored is not None) + ["offset constant"] * (len(idx) == 5))
        for name in names:
            if args.life_rows and name not in [n.strip() for n in args.life_rows.split(";")]:
                continue
            rows = []
            for j, ((c, seed), r) in enumerate(good):
                limit = c + r["depth"][5]  # the truth reaches it after 5 steps (its last stage)
                feats = [CycleFeatures(FeatureSpec(), r["features"][k], np.zeros(len(r["features"][k]))) for k in idx]
                kw = ({"move": moves[int(j < half)]} if name.startswith("move") else {"move": stored}
                      if name.startswith("stored") else {})
                if name == "stored, rate 0":  # the features' rate about the estimator's not marginalised (before)
                    kw["rate_spread"] = 0.0
                if name == "stored, sd 0.2":  # the rate's constant spread, not the move's rate against clearance
                    kw["rate_spread"] = RATE_SPREAD
                t = track_features(feats, cycles_run, model, coefficient=bench.wear.coefficient, limit=limit,
                                   drift=name != "offset constant", **kw)
                m, truth, post_k = t.cycles_to_limit, 5 * args.life_step, t.factor
                rows.append((post_k.contains(args.life_factor), post_k.contains(args.life_factor, 50),
                             m is not None and m.contains(truth), m is not None and m.contains(truth, 50),
                             t.clearance.contains(c), t.clearance.contains(c, 50), t.clearance.median - c,
                             post_k.lo90, post_k.hi90, _rank(post_k, args.life_factor)))
                if args.verbose_lives:
                    print(f"  life {seed} {name}: clearance {c * 1e3:.3f} mm (estimated {t.clearance.median * 1e3:.3f}, "
                          f"90 % {t.clearance.lo90 * 1e3:.3f}-{t.clearance.hi90 * 1e3:.3f}), factor {post_k.median:.2f} "
                          f"(90 % {post_k.lo90:.2f}-{post_k.hi90:.2f}), cycles to {limit * 1e3:.4f} mm: "
                          + (f"{m.median:,.0f} (90 % {m.lo90:,.0f}-{m.hi90:,.0f})" if m else "beyond")
                          + f" (truth {truth:,.0f})")
            a = np.asarray(rows, float)
            hist = np.histogram(a[:, 9], bins=5, range=(0, 1))[0]
            print(f"{'/'.join(f'{n / 1e3:.0f}' for n in cycles_run):23s}  {name:16s}  {a[:, 0].mean():.2f} ({a[:, 1].mean():.2f})"
                  f"      {a[:, 2].mean():.2f} ({a[:, 3].mean():.2f})        {a[:, 4].mean():.2f} ({a[:, 5].mean():.2f})"
                  f"         {np.median(a[:, 6]) * 1e3:+.4f} mm     {np.median(a[:, 7]):.2f}-{np.median(a[:, 8]):.2f}"
                  f"         {' '.join(str(h) for h in hist)}", flush=True)
    along, expected = change_from_new(model, [(means[j], every, c, args.life_factor) for j, ((c, _), _) in enumerate(good)])
    print("the lives' change from new along the estimator's change from new to its last cycles run (1 = that whole "
          "change; weighted by one session's inverse covariance, at each life's true clearance), sessions at "
          + "/".join(f"{n / 1e3:.0f}k" for n in every[1:]) + ": mean " + " ".join(f"{v:.3f}" for v in along.mean(axis=0))
          + " (se " + " ".join(f"{v:.3f}" for v in along.std(axis=0, ddof=1) / np.sqrt(len(along)))
          + "); the estimator's at the same effective cycles " + " ".join(f"{v:.3f}" for v in expected.mean(axis=0)))
    ratios = np.asarray(ratios)
    print("the truths' wear depth / the estimator's trajectory at the same effective cycles, after each step: mean "
          + " ".join(f"{v:.3f}" for v in ratios.mean(axis=0)) + ", sd "
          + " ".join(f"{v:.3f}" for v in ratios.std(axis=0)))


def change_from_new(model, lives) -> tuple[np.ndarray, np.ndarray]:
    """Per life (session means, cycles run with 0 first, clearance, factor): each worn session's mean less
    the new one's, and the estimator's mean change to the same effective cycles, both projected on the
    estimator's change from new to its last cycles run at the life's clearance (weighted by the inverse
    of one 20-cycle session's covariance, drift included): (lives, worn sessions) each."""
    from wearbench.validation.estimation.track import session_covariances, wear_drift

    shared, own = session_covariances(model)
    weight = np.linalg.inv(shared + model.stats[model.reference].within / 20 + own + wear_drift(model))
    last = model.grid_n[-1]
    seen, expected = [], []
    for xbars, runs, c, factor in lives:
        g = model.mean(c, last) - model.mean(c, 0.0)
        project = lambda d, g=g: float(d @ weight @ g / (g @ weight @ g))
        seen.append([project(xbars[k] - xbars[0]) for k in range(1, len(runs))])
        expected.append([project(model.mean(c, factor * n) - model.mean(c, 0.0)) for n in runs[1:]])
    return np.asarray(seen), np.asarray(expected)


def _rank(interval, value: float) -> float:
    """Where ``value`` falls in a posterior given by its median and central intervals: the CDF at it,
    piecewise linear in log through the 5 / 25 / 50 / 75 / 95 % points (0 or 1 outside them)."""
    q = np.log([interval.lo90, interval.lo50, interval.median, interval.hi50, interval.hi90])
    return float(np.interp(np.log(value), q, [0.05, 0.25, 0.5, 0.75, 0.95], left=0.0, right=1.0))


def rank(e, value: float, name: str, model) -> float:
    """Posterior CDF of the marginal at the truth ``value`` (uniform over truths when calibrated)."""
    post = e.posterior
    if name == "clearance":
        grid, w = model.grid_c, post.sum(axis=1)
    elif name == "cycles run":
        grid, w = model.grid_n, post.sum(axis=0)
    else:
        grid, w = model.depth_values(post)
        order = np.argsort(grid, kind="stable")
        grid, w = grid[order], w[order]
    cdf = np.cumsum(w) - 0.5 * w
    return float(np.interp(value, grid, cdf / w.sum()))


if __name__ == "__main__":
    main()
