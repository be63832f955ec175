"""Identification of the test bed's wear state on non-twin sessions: accuracy, calibration, cost.

Truths are never a candidate theory: each session's emulator plays a bench drawn from the bench
file's [tolerances] with its own seed (masses, inertias, lengths, ground points, friction,
restitution, contact exponent, speed and ripple differ; another start state), seen through the
test bed's sensor chain (mounting resonance, anti-alias filter, noise, drift, 16-bit ADC), and
recorded through the sim backend to MCAP. The ensembles' seeds (1..M) never meet the truths'.

Prints: ensemble build time (cold cache unless --cache), time per identification of a 20-cycle
session against 4 cached ensembles, accuracy against the number of cycles used (top-1, named
right / named wrong / undecided / none), Brier score, wrong states judged to explain a session
(consistent and p >= 0.1), wrong states passing the consistency test alone (both parts) and its
all-feature part alone (the test of earlier versions), true states failing it,
the confusion matrix and a reliability table at the full session length, held-out candidates, and
the earlier pointwise ISO ranking (one nominal simulation per state) on the same sessions.

    .venv/bin/python -m benchmarks.validation.identify [--draws 5] [--cycles 20] [--realisations 64]
    .venv/bin/python -m benchmarks.validation.identify --bins 36 --bands 100-1000    # the earlier statistics
    .venv/bin/python -m benchmarks.validation.identify --sensor-paths --calibrate    # drawn mounts, with calibration
    .venv/bin/python -m benchmarks.validation.identify --ensemble-paths none         # ensembles without drawn paths
    .venv/bin/python -m benchmarks.validation.identify --draws 10 --seed 41000 --sensor-paths --calibrate gains \
        --sessions DIR --cache DIR   # a rerun judges the recorded sessions again, nothing re-simulated

The ensembles' realisations are each seen through a drawn sensor path (``EnsembleSettings.sensor_paths``;
--ensemble-paths none: the model's acceleration as it is, earlier versions). --sensor-paths draws each
truth's sensor path (a mount/carriage mode log-uniform in 0.3-3 kHz, damping 0.02-0.1, sensitivity
+/-5 %, and a cross-axis sensitivity of 1-5 % at a drawn angle seeing the carriage's lateral mode,
log-uniform in 0.3-3 kHz, damping 0.02-0.1: ``[emulator.accelerometer.spread]``; --cross-axis off:
the same axial paths without it, as before cross-axis was drawn); the accuracy table is then printed for the likelihood
with the band-gain prior of the sensor path (the default), without it and, with --calibrate, with
each bench calibrated on one session of a known state (0.3 mm new; 0.6 mm new for the 0.3 mm new
truths, so calibration and test never share a state), same bench and mount: once with the
calibration's band gains only, once relative to the calibration session and once with the
ensembles' realisations weighted by it (``validation/calibrated.py``; --calibrate gains: the band gains
only); --brief adds the held-out
candidates judged with either. --ensemble-modes LO-HI draws the ensembles' modes from another range.
The full sessions' rates and each held-out state's catch are printed with their counts and 95 %
Wilson intervals.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from wearbench.compute.options import QUIET


def main() -> None:
    from wearbench.validation.inference.ensemble import EnsembleSettings

    shipped = EnsembleSettings()
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=5, help="truth draws per state (5)")
    ap.add_argument("--cycles", type=int, default=20, help="cycles per session (20)")
    ap.add_argument("--realisations", type=int, default=shipped.realisations,
                    help=f"ensemble realisations per state ({shipped.realisations}, as shipped)")
    ap.add_argument("--ensemble-cycles", type=int, default=shipped.cycles,
                    help=f"cycles per realisation ({shipped.cycles})")
    ap.add_argument("--workers", type=int, default=None, help="compute workers (default: the machine's cores)")
    ap.add_argument("--cache", help="cache folder (default: a fresh one, so ensembles are built cold)")
    ap.add_argument("--seed", type=int, default=9000, help="first truth seed (9000)")
    ap.add_argument("--bins", type=int, help="crank-angle bins of the features (default: FeatureSpec's)")
    ap.add_argument("--bands", help="impact bands, e.g. 100-1000 or 50-150,150-400,400-1000 Hz "
                    "(default: FeatureSpec's)")
    ap.add_argument("--sensor-paths", action="store_true", help="draw each truth's sensor path (see above)")
    ap.add_argument("--cross-axis", choices=("on", "off"), default="on",
                    help="with --sensor-paths: draw the cross-axis sensitivity and lateral carriage mode too (on) or "
                    "keep the paths axial (off: the same seeds' axial paths, for a paired comparison)")
    ap.add_argument("--ensemble-paths", choices=("drawn", "none"), default="drawn",
                    help="the ensembles' realisations each seen through a drawn sensor path (drawn, the default: "
                    "EnsembleSettings.sensor_paths) or the model's acceleration as it is (none: earlier versions)")
    ap.add_argument("--ensemble-modes", metavar="LO-HI",
                    help="the drawn paths' mode range of the ensembles, log-uniform, e.g. 300-8500 Hz "
                    "(default: PathSpread's, 300-3000)")
    ap.add_argument("--calibrate", nargs="?", const="all", choices=("gains", "all"),
                    help="also identify with one calibration session per bench: its band gains (gains) or every "
                    "calibrated likelihood (all, the default of the bare option)")
    ap.add_argument("--sessions", metavar="DIR", help="where the recorded sessions go; a session already there is "
                    "judged again, not re-recorded (default: a fresh folder)")
    ap.add_argument("--brief", action="store_true", help="accuracy tables only")
    args = ap.parse_args()
    os.environ["WEARBENCH_CACHE"] = args.cache or tempfile.mkdtemp(prefix="wearbench-identify-")

    from wearbench.bench.load import load_bench, shipped_bench
    from wearbench.compute import Task, compute_client, run_tasks, task_key
    from wearbench.model.surfaces import JointSurfaces
    from wearbench.synthetic.truths import prepare_truth, record_state, slug, truth_revolutions
    from wearbench.validation import CompareOptions, load_session, rank_theories
    from wearbench.validation.comparison.theory import simulate_theory
    from wearbench.validation.inference.calibration import fit_calibration
    from wearbench.validation.inference.ensemble import build_ensembles
    from wearbench.validation.inference.identify import (
        IdentifyOptions,
        fit_states,
        identify_features,
    )
    from wearbench.validation.inference.relative_states import (
        RelativeStatistics,
        WeightedStatistics,
    )
    from wearbench.validation.inference.sensor_path import PathSpread
    from wearbench.validation.measurement.features import FeatureSpec
    from wearbench.validation.workflows.assess import assess_sessions
    from wearbench.validation.workflows.measure import calibrate_sessions

    bench = load_bench(shipped_bench("ninebar-testbed"))
    states = bench.states
    names = [s.name for s in states]
    spec = FeatureSpec()
    if args.bins or args.bands:
        bands = (tuple(tuple(float(v) for v in b.split("-")) for b in args.bands.split(",")) if args.bands
                 else spec.bands)
        spec = FeatureSpec(bins=args.bins or spec.bins, bands=bands)
    paths_of_ensembles = {}
    if args.ensemble_paths == "none":
        paths_of_ensembles = {"sensor_paths": None}
    elif args.ensemble_modes:
        paths_of_ensembles = {"sensor_paths": PathSpread(mode=tuple(float(v) for v in args.ensemble_modes.split("-")))}
    settings = EnsembleSettings(realisations=args.realisations, cycles=args.ensemble_cycles, features=spec,
                                **paths_of_ensembles)
    out = Path(args.sessions) if args.sessions else Path(tempfile.mkdtemp(prefix="wearbench-identify-sessions-"))
    out.mkdir(parents=True, exist_ok=True)
    truths = [(s, args.seed + 100 * k + d) for k, s in enumerate(states) for d in range(args.draws)]
    # the emulator's drawn paths (SensorSpread's defaults; cross-axis off: its magnitude range [0, 0])
    spread = {"spread": {} if args.cross_axis == "on" else {"cross_axis": [0.0, 0.0]}}
    emulator = {"accelerometer": spread} if args.sensor_paths else {}
    drawn_tag = ("_drawnx" if args.cross_axis == "on" else "_drawn") if args.sensor_paths else ""
    known = {s.name: states[1] if s is states[0] else states[0] for s in states}
    calibrations = [(known[s.name], seed) for s, seed in truths] if args.calibrate else []
    with compute_client(workers=args.workers):
        t0 = time.perf_counter()
        ensembles = build_ensembles(bench, states, settings=settings, cache=True, label="ensembles")
        t_ens = time.perf_counter() - t0
        t0 = time.perf_counter()
        revolutions = truth_revolutions(bench, args.cycles + 1)
        run_tasks([Task(prepare_truth, {"bench": bench, "state": s, "seed": seed, "revolutions": revolutions},
                        task_key("bench-truth", s.name, seed), f"truth {s.name} {seed}")
                   for s, seed in {(s.name, seed): (s, seed) for s, seed in truths + calibrations}.values()],
                  cache=False, progress="emulator truths")
        t_truth = time.perf_counter() - t0
    t0 = time.perf_counter()
    paths = []
    for s, seed in truths:
        paths.append(out / f"{slug(s.name)}_{seed}{drawn_tag}_{args.cycles}.mcap")
        if paths[-1].exists():
            continue
        # one cycle more than analysed: cycles are cut at crank angle 0, so the partial ends are dropped
        record_state(bench, s, seed, paths[-1], backend="sim", cycles=args.cycles + 1, revolutions=revolutions,
                     **emulator)
    cal_paths = []
    for s, seed in calibrations:
        cal_paths.append(out / f"calibration_{slug(s.name)}_{seed}{drawn_tag}_{args.cycles}.mcap")
        if cal_paths[-1].exists():
            continue
        record_state(bench, s, seed, cal_paths[-1], backend="sim", cycles=args.cycles + 1, revolutions=revolutions,
                     **emulator)
    t_record = time.perf_counter() - t0

    t0 = time.perf_counter()
    assess_sessions([paths[0]], ensembles=build_ensembles(bench, states, settings=settings, compute=QUIET))
    t_one = time.perf_counter() - t0
    options = IdentifyOptions()
    models = fit_states(ensembles, options)
    sessions = [load_session(p) for p in paths]
    feats = [s.features(settings.features) for s in sessions]
    truth_names = [s.name for s, _ in truths]
    variants = {"band-gain prior of the sensor path (default)": [models] * len(feats),
                "no band-gain prior (only the ensembles' own spread)": [fit_states(ensembles, replace(options,
                                                                                        sensor_path="none"))] * len(feats)}
    if calibrations:
        t0 = time.perf_counter()
        first = calibrate_sessions([cal_paths[0]], calibrations[0][0].name, ensembles=ensembles)
        t_cal = time.perf_counter() - t0  # what `wearbench calibrate` costs; the others share its exact fit
        exact = fit_states(ensembles, replace(options, sensor_path="none"))
        cals = [first] + [fit_calibration([load_session(p).features(settings.features)], exact, s.name,
                                          key=first.key, bench=bench.name, labels=[p.name])
                          for p, (s, _) in zip(cal_paths[1:], calibrations[1:], strict=True)]
        variants["calibrated on one session of a known state: its sensor path only"] = [
            fit_states(ensembles, options, sensor=c.path) for c in cals]
    t_rel = t_w = float("nan")
    if args.calibrate == "all":
        t0 = time.process_time()
        relative = {k: RelativeStatistics.fit(ensembles, k, options) for k in {c.state for c in cals}}
        t_rel = (time.process_time() - t0) / len(relative)
        variants["calibrated on one session of a known state: relative to it"] = [
            relative[c.state].models(np.asarray(c.features), c.cycles, c.describe()) for c in cals]
        t0 = time.process_time()
        weighted = {k: WeightedStatistics.fit(ensembles, k, options) for k in {c.state for c in cals}}
        t_w = (time.process_time() - t0) / len(weighted)
        variants["calibrated on one session of a known state: realisations weighted by it"] = [
            weighted[c.state].models(np.asarray(c.features), c.cycles, c.describe()) for c in cals]
    if calibrations:
        print(f"\ncalibration: {t_cal:.1f} s for one 20-cycle session (ensembles loaded); sessions still far from the "
              f"known state after the fit (p < 0.001): {sum(c.p_value < 0.001 for c in cals)} of {len(cals)}; "
              f"nulls of a calibrated bench, once per known state: relative {t_rel:.1f} s CPU, weighted {t_w:.1f} s CPU")
    if args.sensor_paths:
        from wearbench.hardware.emulators.config import emulator_config

        drawn = [emulator_config(bench, s, seed, accelerometer=spread).accelerometer for s, seed in truths]
        print("drawn sensor paths: modes " + ", ".join(f"{a.resonance:.0f}" for a in drawn) + " Hz")
        if args.cross_axis == "on":
            print("  cross-axis (%) / lateral mode (Hz): " + ", ".join(f"{100 * a.cross_axis:+.1f}/{a.lateral_mode:.0f}"
                                                                       for a in drawn))

    print(f"\nnon-twin identification: {len(states)} states x {args.draws} draws, {args.cycles}-cycle sessions; "
          f"ensembles {args.realisations} x {args.ensemble_cycles} cycles; temperature {models.temperature:.2f}")
    print(f"build 4 ensembles: {t_ens:.0f} s   emulator truths: {t_truth:.0f} s   record {len(paths)} sessions: "
          f"{t_record:.0f} s   identify one 20-cycle session (cached ensembles, load to report data): {t_one:.1f} s")
    full = min(min(f.cycles for f in feats), args.cycles)
    verdicts = {}
    for variant, session_models in variants.items():
        reliability, final = accuracy_table(variant, session_models, feats, truth_names, names, full, options)
        verdicts[variant] = [final[i] for i in range(len(feats))]
        if variant.endswith("(default)"):
            kept = reliability, final
    print(f"\nfull sessions ({full} cycles), count of {len(feats)} and 95 % Wilson interval:")
    print(f"  {'likelihood':52s} " + "  ".join(f"{c:>20s}" for c in ("top-1", "named right", "named wrong",
                                                                        "undecided", "none")))
    for variant, rs in verdicts.items():
        vs = [r.verdict for r in rs]
        tops = [max(r.posterior, key=r.posterior.get) for r in rs]
        counts = (sum(t == u for t, u in zip(tops, truth_names, strict=True)),
                  sum(v == u for v, u in zip(vs, truth_names, strict=True)),
                  sum(v in names and v != u for v, u in zip(vs, truth_names, strict=True)),
                  vs.count("undecided"), vs.count("none of the candidates"))
        print(f"  {variant[:52]:52s} " + "  ".join(f"{rate_interval(k, len(vs)):>20s}" for k in counts))
    if calibrations:
        band_gains = "calibrated on one session of a known state: its sensor path only"
        prior = [r.verdict for r in verdicts["band-gain prior of the sensor path (default)"]]
        rescued = [f"{t.name} seed {seed}: p {r.p_top:.3f}" for (t, seed), u, r in zip(truths, prior,
                                                                                      verdicts[band_gains], strict=True)
                   if u == "none of the candidates" and r.verdict == t.name]
        print(f"uncalibrated 'none of the candidates', calibrated (band gains) named right: {len(rescued)} of "
              f"{prior.count('none of the candidates')} 'none' ({len(feats)} sessions)"
              + "".join(f"\n  {r}" for r in rescued))
    if args.brief:
        for path in ("prior", "none"):
            print(f"\n[sensor path: {path}]", end="")
            held_out(ensembles, feats, truth_names, names, replace(options, sensor_path=path))
        if calibrations:
            print("\n[calibrated on one session of a known state: its band gains]", end="")
            held_out(ensembles, feats, truth_names, names, options, cals)
        if args.calibrate == "all":
            for method in (RelativeStatistics, WeightedStatistics):
                print(f"\n[calibrated on one session of a known state: {method.__name__}]", end="")
                held_out(ensembles, feats, truth_names, names, options, cals, method)
        return
    reliability, final = kept
    print("\nreliability (all cycle counts): p_top bin, count, mean p_top, observed accuracy")
    p = np.array([x[0] for x in reliability])
    ok = np.array([x[1] for x in reliability])
    for lo, hi in ((0.25, 0.5), (0.5, 0.7), (0.7, 0.9), (0.9, 0.99), (0.99, 1.01)):
        m = (p >= lo) & (p < hi)
        if m.any():
            print(f"  [{lo:.2f}, {min(hi, 1):.2f})  {m.sum():5d}  {p[m].mean():.3f}  {ok[m].mean():.3f}")

    def scores(sub_models) -> str:
        """The full sessions identified with ``sub_models``: one line of scores."""
        rs = [(identify_features(f, sub_models), t) for f, t in zip(feats, truth_names, strict=True)]
        brier = np.mean([sum((r.posterior[s] - (s == t)) ** 2 for s in names) for r, t in rs])
        return (f"top-1 {np.mean([max(r.posterior, key=r.posterior.get) == t for r, t in rs]):.2f}"
                f"  named right {np.mean([r.verdict == t for r, t in rs]):.2f}"
                f"  named wrong {np.mean([r.verdict in names and r.verdict != t for r, t in rs]):.2f}"
                f"  Brier {brier:.3f}  temperature {sub_models.temperature:.2f}"
                f"  wrong state consistent {np.mean([r.consistent[s] for r, t in rs for s in names if s != t]):.2f}")

    spec = settings.features
    print(f"\nwhich statistics (full sessions; chosen: all blocks; {spec.bins} crank-angle bins):")
    blocks = [("low-passed curve + impact energy, all bands", slice(None)),
              (f"low-passed curve ({spec.lowpass:g} Hz) only", slice(0, spec.bins)),
              ("impact energy, all bands", slice(spec.bins, None))]
    blocks += [(f"impact energy {lo:g}-{hi:g} Hz only", slice((i + 1) * spec.bins, (i + 2) * spec.bins))
               for i, (lo, hi) in enumerate(spec.bands)]
    for label, cols in blocks:
        print(f"  {label:44s} {scores(fit_states(ensembles, options, columns=cols))}")

    print("\ncovariances (full sessions; default: pooled over the candidates):")
    for label, pooled in (("pooled over the candidates", True), ("one per state (earlier versions)", False)):
        print(f"  {label:34s} {scores(fit_states(ensembles, replace(options, pooled=pooled)))}")

    print(f"\nhow many realisations (full sessions; this run {args.realisations}):")
    for m in sorted({8, 16, 24, args.realisations}):
        if m <= args.realisations:
            subsets = {k: replace(e, features=e.features[:m]) for k, e in ensembles.items()}
            print(f"  M = {m:3d}  {scores(fit_states(subsets, options))}")

    # a distribution-free alternative: the energy distance between the session's cycles and each
    # ensemble's cycles (features standardised by the pooled ensemble spread); smallest wins
    pooled = np.concatenate([e.features.reshape(-1, e.features.shape[-1]) for e in ensembles.values()])
    scale = pooled.std(axis=0)

    def energy_distance(x: np.ndarray, y: np.ndarray) -> float:
        x, y = x / scale, y / scale
        d = lambda a, b: np.linalg.norm(a[:, None, :] - b[None, :, :], axis=-1).mean()
        return 2 * d(x, y) - d(x, x) - d(y, y)

    tops = [min(names, key=lambda s: energy_distance(f.values, ensembles[s].features.reshape(-1, f.values.shape[1])))
            == t for f, t in zip(feats, truth_names, strict=True)]
    print(f"  {'energy distance (no model of the spread)':34s} {np.mean(tops):.2f}")

    held_out(ensembles, feats, truth_names, names, options)

    t0 = time.perf_counter()
    speed = bench.speed
    theories = {s.name: simulate_theory(bench, speed=speed, clearances=dict(s.clearances),
                                        surfaces={j: JointSurfaces.load(p) for j, p in s.surfaces.items()} or None,
                                        revolutions=3.0, output_rate=bench.sensor("accelerometer").sample_rate)
                for s in states}
    iso_right = [rank_theories(sess, theories, options=CompareOptions())[0].label == t
                 for sess, t in zip(sessions, truth_names, strict=True)]
    print(f"\nearlier method (pointwise ISO/TS 18571 ranking against one nominal simulation per state): "
          f"top-1 {np.mean(iso_right):.2f} ({sum(iso_right)}/{len(iso_right)}) at {args.cycles} cycles "
          f"[{time.perf_counter() - t0:.0f} s]")


def held_out(ensembles, feats, truth_names, names, options, calibrations=None, method=None) -> None:
    """Each state removed from the candidates in turn: how its sessions are judged (full sessions;
    ``calibrations``: each session's bench calibration, used as ``method`` (a ``calibrated.py`` class) does)."""
    from wearbench.validation.inference.identify import fit_states, identify_features

    print("\nheld-out candidate (the true state removed from the candidates), full sessions:")
    for s in names:
        rest = {k: v for k, v in ensembles.items() if k != s}
        rows = [(f, calibrations[i] if calibrations else None) for i, (f, t) in enumerate(zip(feats, truth_names,
                                                                                             strict=True)) if t == s]
        if calibrations and method is None:
            rs = [identify_features(f, fit_states(rest, options, sensor=c.path)) for f, c in rows]
        elif calibrations:
            relative = {k: method.fit(rest, k, options) for k in {c.state for _, c in rows}}
            rs = [identify_features(f, relative[c.state].models(np.asarray(c.features), c.cycles)) for f, c in rows]
        else:
            held = fit_states(rest, options)
            rs = [identify_features(f, held) for f, _ in rows]
        named = sum(r.verdict not in ("undecided", "none of the candidates") for r in rs)
        none = sum(r.verdict == "none of the candidates" for r in rs)
        print(f"  truth {s:20s} caught (not named): {rate_interval(len(rs) - named, len(rs))}   named a wrong state "
              f"with p >= {options.threshold}: {named / len(rs):.2f}   'none of the candidates': {none / len(rs):.2f}   "
              f"max p {max(r.p_top for r in rs):.3f}")


def wilson(k: int, n: int) -> tuple[float, float]:
    """The 95 % Wilson score interval of the rate ``k`` of ``n``."""
    from scipy.stats import binomtest

    ci = binomtest(k, n).proportion_ci(method="wilson")
    return float(ci.low), float(ci.high)


def rate_interval(k: int, n: int) -> str:
    """``k`` of ``n`` as a rate with its 95 % Wilson score interval: ``0.90 [0.77, 0.96] 36/40``."""
    lo, hi = wilson(k, n)
    return f"{k / n:.2f} [{lo:.2f}, {hi:.2f}] {k}/{n}"


def accuracy_table(variant, session_models, feats, truth_names, names, full, options):
    """Print the accuracy against cycles used of one likelihood variant; (reliability rows, full-length results)."""
    from wearbench.validation.inference.identify import identify_features
    from wearbench.validation.measurement.features import CycleFeatures

    print(f"\n[{variant}]")
    print("cycles  sessions  top-1   named right  named wrong  undecided  none   Brier   wrong state explains"
          "  wrong state consistent (all features alone)  true state inconsistent")
    reliability = []
    final = {}
    for n in sorted({1, 2, 5, 10, 20, 40, full}):
        if n > full:
            continue
        rows = []
        for f, truth, models in zip(feats, truth_names, session_models, strict=True):
            for start in range(0, f.cycles - n + 1, n):
                sub = CycleFeatures(f.spec, f.values[start:start + n], f.clipped[start:start + n])
                rows.append((truth, identify_features(sub, models)))
        top1 = np.mean([max(r.posterior, key=r.posterior.get) == t for t, r in rows])
        right = np.mean([r.verdict == t for t, r in rows])
        wrong = np.mean([r.verdict in names and r.verdict != t for t, r in rows])
        undecided = np.mean([r.verdict == "undecided" for _, r in rows])
        none = np.mean([r.verdict == "none of the candidates" for _, r in rows])
        brier = np.mean([sum((r.posterior[s] - (s == t)) ** 2 for s in names) for t, r in rows])
        explains = np.mean([r.explains[s] for t, r in rows for s in names if s != t])
        consistent = np.mean([r.consistent[s] for t, r in rows for s in names if s != t])
        omnibus = np.mean([r.p_value[s] >= options.consistency for t, r in rows for s in names if s != t])
        rejected = np.mean([not r.consistent[t] for t, r in rows])
        print(f"{n:6d}  {len(rows):8d}  {top1:5.2f}   {right:11.2f}  {wrong:11.2f}  {undecided:9.2f}  {none:4.2f}   "
              f"{brier:5.3f}   {explains:20.2f}  {consistent:22.2f} ({omnibus:.2f}){rejected:25.2f}")
        reliability += [(r.p_top, max(r.posterior, key=r.posterior.get) == t) for t, r in rows]
        if n == full:
            final = {i: r for i, (_, r) in enumerate(rows)}
    print(f"\nconfusion at {full} cycles (rows: truth, columns: top state)")
    print(" " * 22 + "".join(f"{s[:18]:>20s}" for s in names))
    for s in names:
        tops = [max(final[i].posterior, key=final[i].posterior.get) for i, t in enumerate(truth_names) if t == s]
        if not tops:
            continue
        print(f"{s:22s}" + "".join(f"{tops.count(c):20d}" for c in names))
    return reliability, final


if __name__ == "__main__":
    main()
