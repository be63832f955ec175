"""Statistics of the test bed's cycles: this version against a stored baseline and a tight-tolerance reference.

Speed work changes rounding, and the clearance dynamics are chaotic, so a changed kernel cannot be
checked pointwise over many revolutions; it is checked in distribution. For each state (0.3 mm new,
0.3 mm second wear) the script simulates realisations of the test bed (seeds 0..``--seeds``-1, the
ensembles' draws: bench within its tolerances, random journal start, 2 settling revolutions) and
cuts what follows into crank cycles. Per cycle and clearance joint it takes

- the number of impacts (contact onsets on the 20 kHz table),
- the impact energy per unit effective mass (sum of vn^2 / 2 at the onsets, J/kg) in each quarter
  of the crank revolution (impact energies by crank angle),
- the peak normal contact force (N),

and per cycle the peak |slider acceleration| (m/s^2). Each feature's cycles are compared between
versions by the two-sample Kolmogorov-Smirnov test; the p-values are Holm-corrected for the number
of features of a state, and a state passes when no corrected p is below 0.01.

Three samples per state: this version at the default tolerance, the baseline version (numbers
stored in ``benchmarks/model/data/statistics_baseline.npz``, written by running this script with the old
code importable, ``--dump``) and this version at the tight tolerance (method "accurate": rtol 1e-8,
atol 1e-11 m). It also prints the reference against the baseline, the yardstick of what a
tolerance alone changes.

Run:  .venv/bin/python -m benchmarks.model.statistics_equivalence [--seeds 16 --revolutions 14]
      (or its parts in parallel: --dump this.npz; --dump ref.npz --method accurate; then --this this.npz
      --reference ref.npz)
      Which tolerance keeps the statistics at the fewest right-hand sides: one dump per setting
      (--dump F --tolerances RTOL ATOL, or --scales POSITION VELOCITY for absolute error scales), then
      --sweep F... --reference ref.npz [--timing 3 5] prints the table; --impacts SETTING... shows how a
      setting changes the impacts (by impact speed, with their restitution).
      PYTHONPATH=/tmp/wb_base_f183162 .venv/bin/python -m benchmarks.model.statistics_equivalence \
          --dump benchmarks/model/data/statistics_baseline.npz        (the baseline, once, with the old code)
"""

from __future__ import annotations

import argparse
import itertools
import math
import os
import time
from pathlib import Path

import numpy as np
from wearbench.studies.equivalence import compare, keywords, label, setting

STATES = ("0.3 mm new", "0.3 mm second wear")
SECTORS = 4
ALPHA = 0.01
SETTLE = 2.0  # settling motor revolutions before the kept ones
# what a state's simulations cost, summed over its realisations (the dump's "cost" rows)
COST = ("CPU s", "right-hand sides", "steps", "rejected", "revolutions")
BASELINE = Path(__file__).with_name("data") / "statistics_baseline.npz"


def _realisation_table(bench, state, seed: int, revolutions: float, method: str, tolerances=None):
    """The full table of one realisation (as ``simulate_state`` runs it, with ``method`` at its own or the
    given (rtol, atol)), the kept mask, the run and the CPU seconds of its ``simulate`` call."""
    from wearbench.model import realisation as R

    kept = {}
    inner = R.simulate

    def capture(*args, **kw):
        kw["method"] = method
        if tolerances is not None:
            kw["rtol"], kw["atol"] = tolerances
        t0 = time.process_time()
        res = inner(*args, **kw)
        kept["cpu"] = time.process_time() - t0
        kept["res"] = res
        return res

    R.simulate = capture
    try:
        run = R.simulate_state(bench, state, seed, revolutions=revolutions, settle=SETTLE)
    finally:
        R.simulate = inner
    table = kept["res"].table
    t = table["t"].to_numpy()
    keep = t >= t[-1] - run.t[-1] - 1e-12
    return table, keep, run, kept["cpu"]


def _cycle_features(bench, table, keep, joints) -> dict[str, np.ndarray]:
    """Per-cycle features of the kept part of a table (see the module docstring)."""
    driver = bench.encoder_driver
    crank = table[f"theta_{driver.joint}"].to_numpy()[keep]
    turn = (crank - crank[0]) * np.sign(crank[-1] - crank[0])
    cycle = np.floor(turn / (2 * math.pi) + 1e-9).astype(int)
    ncyc = int(np.floor(turn[-1] / (2 * math.pi) + 1e-6))  # whole cycles only
    angle = np.mod(turn, 2 * math.pi)
    out: dict[str, np.ndarray] = {}
    acc = np.abs(table["slider_acc"].to_numpy()[keep])
    out["peak |slider acc|"] = np.array([acc[cycle == c].max() for c in range(ncyc)])
    for j in joints:
        pen = table[f"{j}_pen"].to_numpy()[keep]
        vn = table[f"{j}_vn"].to_numpy()[keep]
        fn = table[f"{j}_fn"].to_numpy()[keep]
        onset = np.flatnonzero((pen[:-1] <= 0.0) & (pen[1:] > 0.0)) + 1
        f = pen[onset - 1] / (pen[onset - 1] - pen[onset])
        v0 = vn[onset - 1] + f * (vn[onset] - vn[onset - 1])
        energy = 0.5 * v0 ** 2
        c_on = cycle[onset]
        sector = np.minimum((angle[onset] / (2 * math.pi) * SECTORS).astype(int), SECTORS - 1)
        ok = c_on < ncyc
        out[f"{j} impacts"] = np.bincount(c_on[ok], minlength=ncyc).astype(float)
        for s in range(SECTORS):
            sel = ok & (sector == s)
            out[f"{j} energy {90 * s}-{90 * (s + 1)} deg"] = np.bincount(c_on[sel], weights=energy[sel],
                                                                         minlength=ncyc)
        out[f"{j} peak fn"] = np.array([fn[cycle == c].max() for c in range(ncyc)])
    return out


def collect(seeds: int, revolutions: float, method: str, tolerances=None, scales=None, first_seed: int = 0
            ) -> tuple[dict[str, dict[str, np.ndarray]], dict, dict]:
    """Per-cycle features of every state (concatenated over seeds), the time spent per state and the
    cost of its simulations alone (:data:`COST` summed over the realisations); ``scales``: (position m,
    velocity m/s) absolute error scales (``simulate``'s atol pair, rtol 0) instead of ``tolerances``; the
    seeds ``first_seed`` .. ``first_seed + seeds - 1``."""
    if scales is not None:
        return collect(seeds, revolutions, method, (0.0, tuple(scales)), first_seed=first_seed)
    from wearbench.bench.load import load_bench, shipped_bench

    bench = load_bench(shipped_bench("ninebar-testbed"))
    by_name = {s.name: s for s in bench.states}
    joints = [j.name for j in bench.joints if j.clearance is not None]
    feats: dict[str, dict[str, list]] = {}
    spent = {}
    costs = {}
    for name in STATES:
        t0 = time.process_time()
        acc: dict[str, list] = {}
        cost = np.zeros(5)
        for seed in range(first_seed, first_seed + seeds):
            table, keep, run, cpu = _realisation_table(bench, by_name[name], seed, revolutions, method, tolerances)
            s = run.summary
            cost += (cpu, s["function_evaluations"], s["steps"], s["rejected_steps"], revolutions + SETTLE)
            for k, v in _cycle_features(bench, table, keep, joints).items():
                acc.setdefault(k, []).append(v)
        feats[name] = {k: np.concatenate(v) for k, v in acc.items()}
        spent[name] = time.process_time() - t0
        costs[name] = cost
    return feats, spent, costs


def _load_or_collect(path: str | None, seeds: int, revs: float, method: str | None):
    """Features and CPU seconds per state from a --dump file, or simulated here with ``method``."""
    if path is None:
        return collect(seeds, revs, method)[:2]
    data = np.load(path)
    if float(data["revolutions"]) != revs or int(data["seeds"]) > seeds:
        raise SystemExit(f"{path}: {int(data['seeds'])} seeds x {float(data['revolutions']):g} revolutions; "
                         f"expected at most {seeds} x {revs:g} (write it again with --dump)")
    return _unflat(data), dict(zip(STATES, (float(x) for x in data["seconds"]), strict=True))


def _flat(feats) -> dict[str, np.ndarray]:
    return {f"{s}|{k}": v for s, d in feats.items() for k, v in d.items()}


def _unflat(data) -> dict[str, dict[str, np.ndarray]]:
    out: dict[str, dict[str, np.ndarray]] = {}
    for key in data.files:
        if "|" in key:
            s, k = key.split("|", 1)
            out.setdefault(s, {})[k] = data[key]
    return out


def _report(title: str, rows) -> bool:
    worst = min(r[4] for r in rows)
    ok = worst >= ALPHA
    print(f"  {title}: {'equal in distribution' if ok else 'DIFFERENT'} (smallest Holm-adjusted p {worst:.3g}, "
          f"{len(rows)} features)")
    for k, ma, mb, p, adj in rows:
        print(f"    {k:<28} {ma:12.4g} {mb:12.4g}   p {p:6.3f}  adj {adj:6.3f}")
    return ok


def _timed(bench, settings: list[dict], revolutions: float, repeat: int) -> np.ndarray:
    """CPU ms per revolution of the nominal test bed per setting and state (best of ``repeat``, the
    settings interleaved in one run so that load changes hit all alike)."""
    from wearbench.model import simulate
    from wearbench.model.realisation import state_scene

    by_name = {s.name: s for s in bench.states}
    best = np.full((len(settings), len(STATES)), np.inf)
    simulate(state_scene(bench, by_name[STATES[0]]), revolutions=0.1)  # the compiled code loaded before timing
    for _ in range(repeat):
        for j, name in enumerate(STATES):
            scene = state_scene(bench, by_name[name])
            for i, opt in enumerate(settings):
                t0 = time.process_time()
                simulate(scene, revolutions=revolutions, **keywords(opt))
                best[i, j] = min(best[i, j], (time.process_time() - t0) / revolutions * 1e3)
    return best


SPEED_CLASSES = (0.0, 1e-3, 3e-3, 1e-2, math.inf)  # m/s: classes of impact speed in impacts()


def impacts(names: list[str], state: str, seeds: int, revolutions: float, rate: float = 1e5) -> None:
    """Why a tolerance changes the impact counts: per setting (a :func:`label`) and clearance joint, the
    impacts per revolution (onsets on a ``rate`` table, the same realisations for every setting) by
    impact speed, each class's median effective restitution -vn(separation) / vn(onset) (with its
    quartiles) and the share of impacts within 0.5 ms of the joint's previous separation."""
    from wearbench.bench.load import load_bench, shipped_bench
    from wearbench.model import realisation as R

    bench = load_bench(shipped_bench("ninebar-testbed"))
    joints = [j.name for j in bench.joints if j.clearance is not None]
    by_name = {s.name: s for s in bench.states}
    print(f"{state}: impacts per revolution by impact speed (mm/s) and their effective restitution, median "
          f"(quartiles); {seeds} realisations x {revolutions:g} revolutions after {SETTLE:g}, {rate:g} samples/s")
    for name in names:
        rows: dict[str, list] = {j: [] for j in joints}
        nfev = 0
        kw = keywords(setting(name))
        for seed in range(seeds):
            run = R.simulate_state(bench, by_name[state], seed, revolutions=revolutions, settle=SETTLE,
                                   output_rate=rate, **kw)
            nfev += run.summary["function_evaluations"]
            for j in joints:
                pen, vn = (run.table[f"{j}_{c}"].to_numpy() for c in ("pen", "vn"))
                inside = pen > 0
                on = np.flatnonzero(~inside[:-1] & inside[1:]) + 1
                off = np.flatnonzero(inside[:-1] & ~inside[1:]) + 1
                for a in on:
                    later, before = off[off > a], off[off < a]
                    if not later.size:
                        continue
                    b = later[0]
                    v0 = vn[a - 1] + pen[a - 1] / (pen[a - 1] - pen[a]) * (vn[a] - vn[a - 1])
                    v1 = vn[b - 1] + pen[b - 1] / (pen[b - 1] - pen[b]) * (vn[b] - vn[b - 1])
                    gap = (a - before[-1]) / rate if before.size else math.inf
                    rows[j].append((abs(v0), -v1 / v0 if v0 else math.nan, gap))
        per = seeds * revolutions
        print(f"  {name}: {nfev / seeds / (revolutions + SETTLE):.0f} right-hand sides per revolution")
        for j in joints:
            v0, e, gap = np.array(rows[j]).T
            parts = []
            for lo, hi in itertools.pairwise(SPEED_CLASSES):
                sel = (v0 >= lo) & (v0 < hi)
                q = np.nanquantile(e[sel], [0.25, 0.5, 0.75]) if sel.any() else np.full(3, math.nan)
                parts.append(f"{lo * 1e3:g}-{hi * 1e3:g}: {sel.sum() / per:5.1f} e {q[1]:.2f} ({q[0]:.2f}-{q[2]:.2f})")
            print(f"    {j}: {v0.size / per:5.1f} per rev; " + "; ".join(parts)
                  + f"; within 0.5 ms of a separation {np.mean(gap < 5e-4):.2f}")


def sweep(paths: list[str], reference: str, baseline: str, timing: tuple[float, int] | None) -> None:
    """The tolerance table: per --dump file (a setting), right-hand sides and CPU per revolution (new,
    worn), the smallest Holm-adjusted p against the baseline and the tight reference, and the verdict;
    then the cheapest passing setting against the default (the dump written without --tolerances). The
    dumps and the reference must hold the same realisations (seeds; the stored baseline holds 0..15):
    features differ more between realisations than between tolerances, so other seeds fail the test
    against the baseline even at the tight tolerance."""
    ref = _unflat(np.load(reference))
    base = _unflat(np.load(baseline))
    rows = []
    for path in paths:
        data = np.load(path)
        feats, cost = _unflat(data), data["cost"]
        p_base = np.array([min(r[4] for r in compare(feats[s], base[s])) for s in STATES])
        p_ref = np.array([min(r[4] for r in compare(feats[s], ref[s])) for s in STATES])
        rows.append({"name": str(data["method"]), "setting": setting(str(data["method"])), "rhs": cost[:, 1] / cost[:, 4],
                     "cpu": cost[:, 0] / cost[:, 4] * 1e3, "p_base": p_base, "p_ref": p_ref,
                     "ok": min(p_base.min(), p_ref.min()) >= ALPHA, "cycles": len(next(iter(feats[STATES[0]].values())))})
    default = next((r for r in rows if r["setting"] == {"method": "default"}), None)
    if timing is not None:
        from wearbench.bench.load import load_bench, shipped_bench

        ms = _timed(load_bench(shipped_bench("ninebar-testbed")), [r["setting"] for r in rows], *timing)
        for r, m in zip(rows, ms, strict=True):
            r["timed"] = m
    print("per setting: cycles per state; right-hand sides and CPU ms per simulated revolution over the dump's "
          "realisations (new / worn; the dump's CPU moves with the machine's load)" + (", and CPU ms per revolution "
          "timed interleaved on the nominal bench" if timing else "") + "; smallest Holm-adjusted p against the "
          "baseline and the tight reference (new / worn)")
    print(f"{'setting':<46} {'cycles':>6} {'rhs/rev':>13} {'CPU dump':>9}" + (f" {'CPU timed':>9}" if timing else "")
          + f" {'p baseline':>15} {'p reference':>15}  verdict")
    for r in rows:
        print(f"{r['name']:<46} {r['cycles']:6d} {r['rhs'][0]:6.0f} {r['rhs'][1]:6.0f} {r['cpu'][0]:4.0f} "
              f"{r['cpu'][1]:4.0f}" + (" {:4.0f} {:4.0f}".format(*r["timed"]) if timing else "")
              + " {:>7.2g} {:>7.2g} {:>7.2g} {:>7.2g}".format(*r["p_base"], *r["p_ref"])
              + f"  {'pass' if r['ok'] else 'FAIL'}")
    passing = [r for r in rows if r["ok"]]
    if default is None or not passing:
        print("\n(no default dump or no passing setting: no ratio)")
        return
    cheapest = min(passing, key=lambda r: r["rhs"].sum())
    ratio = default["rhs"] / cheapest["rhs"]
    print(f"\ncheapest passing setting: {cheapest['name']}: right-hand sides per revolution {ratio[0]:.2f}x (new), "
          f"{ratio[1]:.2f}x (worn) fewer than the default's"
          + (", CPU {:.2f}x / {:.2f}x (interleaved timing)".format(*(default["timed"] / cheapest["timed"]))
             if timing else ""))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=16)
    ap.add_argument("--revolutions", type=float, default=14.0, help="kept revolutions per realisation")
    ap.add_argument("--dump", help="only write the importable version's features to this .npz")
    ap.add_argument("--method", default="default", help="with --dump: the method (default, or accurate for the "
                    "reference)")
    ap.add_argument("--tolerances", type=float, nargs=2, metavar=("RTOL", "ATOL"),
                    help="with --dump: the method at these tolerances (atol in m) instead of its own (the "
                         "work-precision side of the check: which default tolerance keeps the statistics)")
    ap.add_argument("--scales", type=float, nargs=2, metavar=("POSITION", "VELOCITY"),
                    help="with --dump: absolute error scales instead (m on positions, m/s on velocities, rtol 0; "
                         "a tolerance shape the (rtol, atol) pair cannot express)")
    ap.add_argument("--sweep", nargs="+", metavar="DUMP",
                    help="the tolerance table of these --dump files (settings) against --baseline and --reference")
    ap.add_argument("--timing", type=float, nargs=2, metavar=("REVOLUTIONS", "REPEAT"),
                    help="with --sweep: also time every setting on the nominal test bed, interleaved, best of REPEAT")
    ap.add_argument("--impacts", nargs="+", metavar="SETTING",
                    help="the impacts by speed and their restitution per setting (a dump's method label, e.g. "
                         "'accurate', 'default rtol 1e-05 atol 1e-08', 'default absolute scales 1e-07 m, 1.3e-05 m/s') "
                         "on new surfaces, --seeds realisations x --revolutions")
    ap.add_argument("--first-seed", type=int, default=0, help="with --dump: the realisations' first seed (another "
                    "sample of the same size; the stored baseline holds seeds 0..15)")
    ap.add_argument("--baseline", default=str(BASELINE), help="stored baseline features (.npz)")
    ap.add_argument("--this", help="this version's features from a --dump file instead of simulating them")
    ap.add_argument("--reference", help="the reference's features from a --dump --method accurate file")
    args = ap.parse_args()
    import wearbench.model

    source = os.path.dirname(wearbench.model.__file__)
    if args.impacts:
        impacts(args.impacts, STATES[0], args.seeds, args.revolutions)
        return
    if args.sweep:
        if not args.reference:
            raise SystemExit("--sweep needs --reference (a --dump --method accurate file)")
        timing = (args.timing[0], int(args.timing[1])) if args.timing else None
        sweep(args.sweep, args.reference, args.baseline, timing)
        return
    if args.dump:
        feats, spent, cost = collect(args.seeds, args.revolutions, args.method, args.tolerances, args.scales,
                                     args.first_seed)
        method = label(args.method, args.tolerances, args.scales)
        np.savez_compressed(args.dump, **_flat(feats), seeds=args.seeds, revolutions=args.revolutions,
                            source=source, method=method, seconds=np.array([spent[s] for s in STATES]),
                            cost=np.array([cost[s] for s in STATES]))
        print(f"wrote {args.dump} from {source} ({method}): "
              f"{[(s, len(next(iter(feats[s].values())))) for s in STATES]} cycles")
        return
    seeds, revs = args.seeds, args.revolutions
    this, t_this = _load_or_collect(args.this, seeds, revs, "default")
    ref, t_ref = _load_or_collect(args.reference, seeds, revs, "accurate")
    base, _ = _load_or_collect(args.baseline, seeds, revs, None)
    base_file = np.load(args.baseline)
    print(f"test bed, {seeds} realisations x {revs:g} revolutions per state; baseline {args.baseline} "
          f"(written by {base_file['source']}); this version {source}")
    passed = True
    for name in STATES:
        n, n_ref = (len(next(iter(x[name].values()))) for x in (this, ref))
        same = all(np.array_equal(this[name][k], base[name][k]) for k in this[name])
        print(f"\n{name}: {n} cycles (this version, baseline), {n_ref} (reference); simulated in "
              f"{t_this[name]:.0f} s CPU (this version), {t_ref[name]:.0f} s (reference); this version's "
              f"features {'equal the baseline bit for bit' if same else 'differ from the baseline'}")
        print(f"    {'feature':<28} {'mean this':>12} {'mean other':>12}")
        passed &= _report("this vs baseline", compare(this[name], base[name]))
        passed &= _report("this vs tight reference", compare(this[name], ref[name]))
        _report("baseline vs tight reference (yardstick)", compare(base[name], ref[name]))
    print(f"\n{'PASS' if passed else 'FAIL'}: no feature with Holm-adjusted p < {ALPHA} in any comparison of this version")


if __name__ == "__main__":
    main()
