"""What a calibration of the sensor path gives back: resolution of identify and estimate on one bench and mount.

Each of ``--benches`` benches is drawn from the test bed's [tolerances] with its own seed (no ensemble
or design uses them) and carries one mount for its whole life: a mount or carriage mode drawn from the
bench emulator's ``SensorSpread`` (``--cross-axis``: with its cross-axis part), not the bench file's
path. Its life is three 20-cycle sessions of the test bed's states at 0.3 mm: new (the first session,
the state the lab knows), first wear and second wear (the shipped state files). The same benches are
also seen through the bench file's own path, for the reference a lab without a calibration gets there.

The worn sessions are judged four ways: default path and drawn mount, each with the unknown mount's
prior (identification's default) and calibrated on the bench's first session (``fit_calibration``, as
``wearbench calibrate --state "0.3 mm new"`` fits it). Per way: identification's verdicts (named right,
named wrong, undecided, none of the candidates, with 95 % Wilson intervals) and the estimate's 90 %
intervals (median widths of clearance and cycles run, and whether they hold 0.3 mm and the state's
cycles run).

    .venv/bin/python -m benchmarks.validation.calibration_gain [--benches 10] [--cross-axis] [--json PATH]

Sessions are simulated in-process through the emulator's sensor chain and cached by content
(``WEARBENCH_CACHE``, default ~/.cache/wearbench: a rerun judges again without simulating); the
ensembles and the estimator are the shipped test bed's (built from the cache where a shipped file's
key does not match this version).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from benchmarks.result_json import Run, column, table, write_result
from benchmarks.validation.identify import wilson

KNOWN = "0.3 mm new"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--benches", type=int, default=10, help="benches, one life and one mount each (10)")
    ap.add_argument("--cycles", type=int, default=20, help="cycles per session (20)")
    ap.add_argument("--seed", type=int, default=40000, help="first bench's seed (40000)")
    ap.add_argument("--cross-axis", action="store_true", help="draw the mount's cross-axis part too")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--json", metavar="PATH", help="also write the result (docs/results/data/ for the docs)")
    args = ap.parse_args()
    run = Run()

    from wearbench.bench.load import load_bench, shipped_bench
    from wearbench.compute import TaskFailure, compute_client, run_tasks
    from wearbench.synthetic.lives import state_session, surfaces_wear
    from wearbench.validation.estimation.estimate import EstimatorDesign, build_estimator
    from wearbench.validation.inference.ensemble import build_ensembles

    bench = load_bench(shipped_bench("ninebar-testbed"))
    states = {s.name: s for s in bench.states}
    life = [KNOWN] + [s.name for s in bench.states if s.surfaces]
    drawn = "cross-axis" if args.cross_axis else True
    paths = {"default path": False, "drawn mount": drawn}
    seeds = [args.seed + k for k in range(args.benches)]
    t0 = time.perf_counter()
    with compute_client(workers=args.workers):
        ensembles = build_ensembles(bench, bench.states, label="ensembles")
        est = build_estimator(bench, EstimatorDesign())
        t_build = time.perf_counter() - t0
        t0 = time.perf_counter()
        keys = [(path, s, name) for path in paths for s in seeds for name in life]
        tasks = [state_session(bench, states[name], s, args.cycles, paths[path], label=f"{path} {s} {name}")
                 for path, s, name in keys]
        done = dict(zip(keys, run_tasks(tasks, progress="sessions"), strict=True))
        given = {name: task.kwargs for (_, _, name), task in zip(keys, tasks, strict=True)}  # one per state
        truths = {name: (kw["clearance"], surfaces_wear(kw["files"])[0]) for name, kw in given.items()}
    t_sessions = time.perf_counter() - t0
    failed = [k for k, r in done.items() if isinstance(r, TaskFailure)]
    for k in failed:
        print(f"session {k} failed: {done[k]}")
    good = [s for s in seeds if not any((p, s, n) in failed for p in paths for n in life)]
    print(f"{len(good)} benches x {len(paths)} sensor paths x {len(life)} sessions ({len(failed)} failed); ensembles and "
          f"estimator {t_build:.0f} s, sessions {t_sessions:.0f} s")
    t0 = time.perf_counter()
    rows = judge(bench, ensembles, est, done, good, paths, life, truths, args.cycles)
    print(f"judged in {time.perf_counter() - t0:.0f} s")
    report(rows, life[1:])
    if args.json:
        write_json(args.json, rows, life[1:], good, args, run, est)


def judge(bench, ensembles, est, done, seeds, paths, life, truths, cycles) -> list[dict]:
    """Every worn session identified and estimated four ways (path x with/without the calibration on
    the bench's first session): one row each; ``truths``: per state its (clearance, cycles run)."""
    from dataclasses import replace

    from wearbench.validation.estimation.estimate import estimate_features, fit_estimator
    from wearbench.validation.inference.calibration import fit_calibration
    from wearbench.validation.inference.identify import (
        IdentifyOptions,
        fit_states,
        identify_features,
    )
    from wearbench.validation.measurement.features import CycleFeatures
    from wearbench.validation.measurement.scaling import resolve_analysis

    options = IdentifyOptions()
    spec = resolve_analysis(bench).features  # what truth_features computed
    feats = lambda r: CycleFeatures(spec, np.asarray(r["features"])[:cycles], np.zeros(min(cycles, len(r["features"]))))
    prior_models, prior_model = fit_states(ensembles, options), fit_estimator(est, options)
    exact = fit_states(ensembles, replace(options, sensor_path="none"))
    rows = []
    for path in paths:
        for s in seeds:
            cal = fit_calibration([feats(done[path, s, KNOWN])], exact, KNOWN, key=f"bench {s} {path}",
                                  bench=bench.name, labels=[f"{s} {KNOWN}"])
            ways = {"unknown mount's prior": (prior_models, prior_model),
                    "calibrated on its first session": (fit_states(ensembles, options, sensor=cal.path),
                                                        fit_estimator(est, options, sensor=cal.path))}
            for way, (models, model) in ways.items():
                for name in life[1:]:
                    f = feats(done[path, s, name])
                    ident = identify_features(f, models, label=f"{s} {name}")
                    e = estimate_features(f, model, label=f"{s} {name}")
                    rows.append({"path": path, "way": way, "seed": s, "state": name, "verdict": ident.verdict,
                                 "p_top": ident.p_top, "estimate": e, "truth": truths[name],
                                 "calibration_p": cal.p_value})
    return rows


WAYS = (("default path", "unknown mount's prior"), ("default path", "calibrated on its first session"),
        ("drawn mount", "unknown mount's prior"), ("drawn mount", "calibrated on its first session"))


def tally(rows: list[dict], state: str) -> dict:
    sel = [r for r in rows if r["state"] == state]
    n = len(sel)
    verdicts = [r["verdict"] for r in sel]
    e = [r["estimate"] for r in sel]
    c, n_run = sel[0]["truth"]
    return {"n": n, "right": verdicts.count(state), "wrong": sum(v not in (state, "undecided", "none of the candidates")
                                                                  for v in verdicts),
            "undecided": verdicts.count("undecided"), "none": verdicts.count("none of the candidates"),
            "c_width": float(np.median([x.clearance.hi90 - x.clearance.lo90 for x in e])),
            "n_width": float(np.median([x.cycles_run.hi90 - x.cycles_run.lo90 for x in e])),
            "c_hold": sum(x.explains and x.clearance.contains(c) for x in e),
            "n_hold": sum(x.explains and x.cycles_run.contains(n_run) for x in e),
            "c_error": float(np.median([abs(x.clearance.median - c) for x in e]))}


def report(rows, worn) -> None:
    print("\nsensor path    judged with                        state                 named right [Wilson 95 %]  wrong  "
          "undecided  none   clearance 90 % width (mm) / holds   cycles-run 90 % width / holds")
    for path, way in WAYS:
        sel = [r for r in rows if r["path"] == path and r["way"] == way]
        for state in worn:
            t = tally(sel, state)
            lo, hi = wilson(t["right"], t["n"])
            print(f"{path:13s}  {way:33s}  {state:20s}  {t['right']:2d}/{t['n']:<2d} [{lo:.2f}, {hi:.2f}]        "
                  f"{t['wrong']:4d}  {t['undecided']:9d}  {t['none']:4d}   {t['c_width'] * 1e3:.3f} / {t['c_hold']:2d}"
                  f"                     {t['n_width']:9,.0f} / {t['n_hold']:2d}")


def write_json(path, rows, worn, seeds, args, run, est) -> None:
    cols = [column("sensor path"), column("judged with"), column("state"), column("sessions", None, "d"),
            column("named right", None, "d"), column("named right, share", None, ".2f"),
            column("Wilson 95 % low", None, ".2f"), column("Wilson 95 % high", None, ".2f"),
            column("named wrong", None, "d"), column("undecided", None, "d"), column("none of the candidates", None, "d"),
            column("clearance 90 % width", "mm", ".3f", "median over the sessions"),
            column("clearance 90 % holds 0.3 mm", None, "d"),
            column("cycles-run 90 % width", "k cycles", ".0f", "median over the sessions"),
            column("cycles-run 90 % holds the truth", None, "d")]
    out = []
    for p, way in WAYS:
        sel = [r for r in rows if r["path"] == p and r["way"] == way]
        for state in worn:
            t = tally(sel, state)
            out.append([p, way, state, t["n"], t["right"], t["right"] / t["n"], *wilson(t["right"], t["n"]),
                        t["wrong"], t["undecided"], t["none"], t["c_width"] * 1e3, t["c_hold"], t["n_width"] / 1e3,
                        t["n_hold"]])
    first = worn[0]
    get = lambda p, way: tally([r for r in rows if r["path"] == p and r["way"] == way], first)
    ref, drawn, cal = (get("default path", "unknown mount's prior"), get("drawn mount", "unknown mount's prior"),
                       get("drawn mount", "calibrated on its first session"))
    findings = [(f"{first} benches named right: {cal['right']} of {cal['n']} on a drawn mount calibrated on the bench's "
                f"first session, {drawn['right']} of {drawn['n']} on the same mounts without a calibration, "
                f"{ref['right']} of {ref['n']} on the bench file's own path without one."),
                (f"The estimate's clearance interval (90 %, median width) on {first} sessions: {cal['c_width'] * 1e3:.3f} mm "
                f"calibrated, {drawn['c_width'] * 1e3:.3f} mm without, on the drawn mounts; cycles run "
                f"{cal['n_width'] / 1e3:.0f}k against {drawn['n_width'] / 1e3:.0f}k.")]
    mount = "a drawn mount with its cross-axis part" if args.cross_axis else "a drawn axial mount"
    tables = [table("Identification and estimate of worn sessions, with and without a calibration", cols, out,
                    f"Each bench: {mount} (or the bench file's path), calibrated on its first session "
                    f"({KNOWN}, {args.cycles} cycles); {len(seeds)} benches.")]
    seeds_used = {"benches (tolerances, start, mount)": f"{seeds[0]}-{seeds[-1]}",
                  "estimator realisations and wear runs": f"{est.design.settings.seed}-"
                                                          f"{est.design.settings.seed + est.features.shape[2] - 1}"}
    notes = [("Calibration: the sensor path's prior conditioned on the first session against the known state's "
             "ensemble (fit_calibration, as wearbench calibrate fits it), without its doubts checked."),
             "Identification: the shipped test bed ensembles; estimate: the shipped test bed estimator."]
    write_result(path, question="What does a calibration from one known-state session give back on a bench's own "
                 "mount?", script=__file__, tables=tables, seeds=seeds_used, findings=findings, notes=notes, run=run)
    print(f"result: {path}")


if __name__ == "__main__":
    main()
