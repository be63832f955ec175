"""Which route makes identification survive an unknown sensor path: measured on the model's physics.

The same raw realisations (the model's slider acceleration at 20 kHz, seeds 1..M per state, settled,
``--ensemble-cycles`` cycles) and non-twin truths (seeds 9000 + 100 k + d, 20 cycles) are reduced
to features in every variant, so the variants differ only in the route:

- ensembles: the acceleration as it is (earlier versions) or each realisation through its own drawn
  sensor path (``PathSpread``, what ``EnsembleSettings.sensor_paths`` does);
- feature spec: the default three impact bands, or six narrower ones (a mode changes less of a band's
  crank-angle shape when the band is narrow);
- likelihood: with the band-gain prior of the sensor path (``IdentifyOptions.sensor_path="prior"``) or without;
- truths: the test bed's default path (no mode below 3 kHz), or a drawn path per truth exactly as the
  emulator draws it (``[emulator.accelerometer.spread]``: mode 0.3-3 kHz, damping 0.02-0.1,
  sensitivity +/-5 %), applied to the model's output (no DAQ, noise or ADC: those are the same in
  every variant; ``benchmarks/validation/identify.py`` runs the full chain).

Prints, per variant, the rates at 20 and 10 cycles (top-1, named right / wrong, undecided, none, the
true state failing its consistency test) and how often a truth held out of the candidates is caught
(undecided or none; per state). Realisations run through the compute layer in this process (cached).

    .venv/bin/python -m benchmarks.validation.sensor_path_routes [--realisations 16] [--draws 3]
    .venv/bin/python -m benchmarks.validation.sensor_path_routes --modes 300-3000,300-8500 --specs 3   # mode ranges

--modes: the mode ranges (Hz, log-uniform) of the drawn ensemble paths compared (default 300-3000,
``PathSpread``'s); a range reaching far above the bands holds the stud mount of the emulator's
default path too (the top is limited to 0.45 x the 20 kHz output rate).
"""

from __future__ import annotations

import argparse

import numpy as np


def raw_run(bench, state, seed: int, revolutions: float) -> dict[str, np.ndarray]:
    """The model's slider acceleration of one realisation (a compute-layer task)."""
    from wearbench.model.realisation import simulate_state

    run = simulate_state(bench, state, seed, revolutions=revolutions, settle=2.0, speed=bench.speed,
                         output_rate=20_000.0)
    return {"t": run.t, "crank": run.crank, "acc": run.acc.astype(np.float32)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--realisations", type=int, default=16, help="realisations per state (16)")
    ap.add_argument("--ensemble-cycles", type=int, default=6, help="cycles per realisation (6)")
    ap.add_argument("--draws", type=int, default=3, help="truths per state (3)")
    ap.add_argument("--modes", default="300-3000", help="mode ranges of the drawn ensemble paths, Hz (300-3000)")
    ap.add_argument("--specs", choices=("3", "6", "both"), default="both", help="feature specs: 3 or 6 bands (both)")
    args = ap.parse_args()

    from wearbench.bench.content import bench_key
    from wearbench.bench.load import load_bench, shipped_bench
    from wearbench.compute import Task, run_tasks, task_key
    from wearbench.hardware.emulators.config import Accelerometer, SensorSpread
    from wearbench.validation.inference.ensemble import Ensemble, EnsembleSettings
    from wearbench.validation.inference.identify import (
        IdentifyOptions,
        fit_states,
        identify_features,
    )
    from wearbench.validation.inference.sensor_path import PathSpread, mount_response
    from wearbench.validation.measurement.features import CycleFeatures, FeatureSpec, cycle_features

    bench = load_bench(shipped_bench("ninebar-testbed"))
    names = [s.name for s in bench.states]
    fs, m, c = 20_000.0, args.realisations, args.ensemble_cycles
    jobs = [("truth", k, 9000 + 100 * k + d, 21.0) for d in range(args.draws) for k in range(len(names))]
    jobs += [("real", k, i, c + 1.0) for i in range(1, m + 1) for k in range(len(names))]
    runs = run_tasks([Task(raw_run, {"bench": bench, "state": bench.states[k], "seed": seed, "revolutions": revs},
                           task_key("raw-run", bench_key(bench), names[k], seed, revs), f"{kind} {names[k]} {seed}")
                      for kind, k, seed, revs in jobs], workers=0, progress="realisations and truths")
    runs = {(kind, k, seed): r for (kind, k, seed, _), r in zip(jobs, runs, strict=True)}
    # the ensembles' drawn paths by label ("drawn" for PathSpread's own range)
    spreads = {f"drawn {lo}-{hi}" if args.modes != "300-3000" else "drawn":
               PathSpread(mode=(float(lo), float(hi))) for lo, hi in (r.split("-") for r in args.modes.split(","))}

    def features(key, spec, path):
        """``path``: a realisation's ``PathSpread``, a truth's mount as the emulator draws it
        ("drawn"), or the acceleration as it is (None, "default")."""
        r = runs[key]
        acc = r["acc"].astype(float)
        if isinstance(path, PathSpread):
            acc = path.apply(acc, fs, key[2])
        elif path == "drawn":
            a = SensorSpread().draw(Accelerometer(), key[2])
            acc = mount_response(acc, fs, a.resonance, a.damping, a.sensitivity)
        return cycle_features(r["t"], r["crank"], acc, spec)

    def rates(models, rows) -> str:
        rs = [(identify_features(f, models), names[k]) for f, k in rows]
        share = lambda test: np.mean([test(r, t) for r, t in rs])
        return (f"{share(lambda r, t: max(r.posterior, key=r.posterior.get) == t):5.2f} "
                f"{share(lambda r, t: r.verdict == t):5.2f} {share(lambda r, t: r.verdict in names and r.verdict != t):5.2f} "
                f"{share(lambda r, t: r.verdict == 'undecided'):5.2f} "
                f"{share(lambda r, t: r.verdict == 'none of the candidates'):5.2f} {share(lambda r, t: not r.consistent[t]):5.2f}")

    specs = {"3 bands": FeatureSpec(), "6 bands": FeatureSpec(bands=((50.0, 100.0), (100.0, 150.0), (150.0, 250.0),
                                                                      (250.0, 400.0), (400.0, 650.0), (650.0, 1000.0)))}
    specs = {k: v for k, v in specs.items() if args.specs == "both" or k.startswith(args.specs)}
    truths = [k for k in runs if k[0] == "truth"]
    print(f"{m} realisations x {c} cycles per state, {len(truths)} truths of 20 cycles")
    print("spec     ensembles  likelihood  truth path   cycles  top-1 right wrong undec none  true-inconsistent   "
          "held out caught (per state)")
    for sname, spec in specs.items():
        for ens_label, ens_path in (("as is", None), *spreads.items()):
            settings = EnsembleSettings(realisations=m, cycles=c, features=spec)
            ens = {}
            for k, nm in enumerate(names):
                f = np.stack([features(("real", k, i), spec, ens_path).values[:c] for i in range(1, m + 1)])
                ens[nm] = Ensemble(nm, settings, f, np.zeros((m, c, 4)), np.zeros((m, c)), bench.speed)
            tf = {p: [(features(t, spec, p), t[1]) for t in truths] for p in ("default", "drawn")}
            for lik in ("prior", "none"):
                options = IdentifyOptions(sensor_path=lik)
                models = fit_states(ens, options)
                held = [fit_states({nm: e for nm, e in ens.items() if nm != names[k]}, options)
                        for k in range(len(names))]
                for p, rows in tf.items():
                    caught = [np.mean([identify_features(f, held[k]).verdict in ("undecided", "none of the candidates")
                                       for f, kk in rows if kk == k]) for k in range(len(names))]
                    for n in (20, 10):
                        sub = [(CycleFeatures(f.spec, f.values[s:s + n], f.clipped[s:s + n]), k) for f, k in rows
                               for s in range(0, f.cycles - n + 1, n)]
                        tail = " ".join(f"{v:.2f}" for v in caught) if n == 20 else ""
                        print(f"{sname}  {ens_label:9s}  {lik:10s}  "
                              f"{p:11s}  {n:6d}  {rates(models, sub)}  {'':17s}  {tail}", flush=True)


if __name__ == "__main__":
    main()
