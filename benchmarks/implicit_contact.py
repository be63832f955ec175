"""The contact force treated implicitly (method "imex") against the default DOPRI5: cost and accuracy, one run.

Issue 27 asked whether the explicit method's steps are set by the stiff contact (22-27 % of its
attempts rejected, about 4 rejections per contact onset) and whether an implicit treatment of the
contact force could remove them. Method "imex" (``model/implicit_contact.py``) is linearly implicit
Euler extrapolation of order 4 whose Jacobian holds exactly the clearance contacts' force law, mapped
through the constrained system (the stiff eigenvalues: at a low-speed contact the hysteresis damping
gives a real eigenvalue near -6e4 1/s, beyond DOPRI5's stability interval at its usual 60 us steps).

For the test bed (``ninebar-testbed``, 0.3 mm, nominal bench, 20 kHz table) on new and 400,000-cycle
worn surfaces, from t = 0 over ``--revolutions``, each method at each tolerance (atol = rtol x 1e-3 m):
accepted and rejected steps and right-hand sides per revolution, CPU ms per revolution (best of
``--repeat``, all runs interleaved in this process), and the error against a tight reference (the
default method at rtol 1e-11): relative RMS of the slider acceleration over the predictability horizon
(where two tight references, rtol 1e-11 and 1e-10, first differ by 1 % of the RMS acceleration) and
the time each run tracks the reference within that 1 %. Then, at equal error: for each default run, the
cheapest imex run whose horizon error is no larger, and the CPU ratio. The control case "explicit" is
imex with the contacts left out of its Jacobian (the same extrapolation, step control and onset rule,
explicit in the contact force): what the implicit treatment itself changes.

Run:  nice -n 15 .venv/bin/python benchmarks/implicit_contact.py [--revolutions 1 --repeat 3]
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.model import METHODS, simulate
from wearbench.model.methods import Extrapolation
from wearbench.model.realisation import state_scene

STATES = ("0.3 mm new", "0.3 mm second wear")
TOLERANCES = (1e-4, 1e-5, 1e-6, 1e-7)
# the default, imex, and imex's control case: the same extrapolation with the contacts out of its Jacobian
RUNS = {"default": "default", "imex": "imex",
        "explicit": dataclasses.replace(METHODS["imex"], name="imex-explicit",
                                        tableau=Extrapolation("liex4-explicit", 4, implicit=False))}


def _horizon(ref, ref2) -> int:
    """Samples over which the two references agree to 1 % of the RMS slider acceleration."""
    a, b = ref.table["slider_acc"].to_numpy(), ref2.table["slider_acc"].to_numpy()
    bad = np.flatnonzero(np.abs(a - b) > 0.01 * np.sqrt(np.mean(a ** 2)))
    return int(bad[0]) if bad.size else a.size


def _error(res, ref, n: int) -> tuple[float, float]:
    """Relative RMS slider-acceleration error over the first n samples; the time (s) tracked within 1 %."""
    a, r = res.table["slider_acc"].to_numpy(), ref.table["slider_acc"].to_numpy()
    scale = np.sqrt(np.mean(r ** 2))
    rms = float(np.sqrt(np.mean((a[:n] - r[:n]) ** 2)) / np.sqrt(np.mean(r[:n] ** 2)))
    bad = np.flatnonzero(np.abs(a - r) > 0.01 * scale)
    return rms, float(ref.table["t"].iloc[bad[0]] if bad.size else ref.table["t"].iloc[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--revolutions", type=float, default=1.0)
    ap.add_argument("--repeat", type=int, default=3, help="timed runs per case (best of), interleaved")
    ap.add_argument("--tolerances", type=float, nargs="+", default=list(TOLERANCES))
    args = ap.parse_args()
    bench = load_bench(shipped_bench("ninebar-testbed"))
    states = {s.name: s for s in bench.states}
    revs = args.revolutions
    print(f"test bed ninebar-testbed, 0.3 mm, nominal bench, 20 kHz table, {revs:g} revolution(s) from t = 0; "
          f"CPU time, best of {args.repeat} (interleaved); atol = rtol x 1e-3 m")
    for name in STATES:
        scene = state_scene(bench, states[name])
        for m in RUNS.values():
            simulate(scene, t_end=1e-3, method=m)  # compile
        ref = simulate(scene, revolutions=revs, rtol=1e-11, atol=1e-14)
        ref2 = simulate(scene, revolutions=revs, rtol=1e-10, atol=1e-13)
        n_h = _horizon(ref, ref2)
        horizon = float(ref.table["t"].iloc[n_h - 1])
        cases = [(m, r) for m in RUNS for r in args.tolerances]
        best = {c: np.inf for c in cases}
        runs = {}
        for _ in range(args.repeat):
            for m, r in cases:
                t0 = time.process_time()
                runs[(m, r)] = simulate(scene, revolutions=revs, method=RUNS[m], rtol=r, atol=r * 1e-3)
                best[(m, r)] = min(best[(m, r)], time.process_time() - t0)
        print(f"\n{name}: predictability horizon {horizon * 1e3:.1f} ms (references rtol 1e-11 / 1e-10)")
        print(f"{'method':<8} {'rtol':>6} | {'ms/rev':>7} {'steps/rev':>9} {'rej/rev':>8} {'rej %':>6} {'RHS/rev':>8} "
              f"{'RHS/step':>8} | {'acc RMS err':>11} {'tracks ms':>9} | {'peak Fn A, B (N)':>17} {'acc':>6}")
        rows = {}
        for m, r in cases:
            s = runs[(m, r)].summary
            rms, tracks = _error(runs[(m, r)], ref, n_h)
            rows[(m, r)] = (best[(m, r)] / revs, rms)
            att = s["steps"] + s["rejected_steps"]
            print(f"{m:<8} {r:>6.0e} | {best[(m, r)] / revs * 1e3:>7.0f} {s['steps'] / revs:>9.0f} "
                  f"{s['rejected_steps'] / revs:>8.0f} {100 * s['rejected_steps'] / att:>5.0f}% "
                  f"{s['function_evaluations'] / revs:>8.0f} {s['function_evaluations'] / att:>8.2f} | {rms:>11.2e} "
                  f"{tracks * 1e3:>9.1f} | {s['peak_fn']['A']:>8.0f} {s['peak_fn']['B']:>8.0f} "
                  f"{s['peak_slider_acc']:>6.0f}")
        print("at equal error (horizon RMS): the cheapest imex run with an error <= the default run's")
        for r in args.tolerances:
            cost, err = rows[("default", r)]
            ok = [(rows[("imex", ri)][0], ri) for ri in args.tolerances if rows[("imex", ri)][1] <= err]
            if ok:
                c, ri = min(ok)
                print(f"  default rtol {r:.0e} ({err:.1e}, {cost * 1e3:.0f} ms/rev): imex rtol {ri:.0e} "
                      f"{c * 1e3:.0f} ms/rev, default / imex = {cost / c:.2f}x")
            else:
                print(f"  default rtol {r:.0e} ({err:.1e}): no imex run that accurate")


if __name__ == "__main__":
    main()
