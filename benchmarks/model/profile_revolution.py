"""Where a simulated revolution's time goes: the test bed (0.3 mm) on new and on 400,000-cycle worn surfaces.

For each state it runs ``--revolutions`` motor revolutions of the nominal bench with the default
method (DOPRI5 + projection, 20 kHz table) and splits the wall time:

- **Python** between compiled calls: ``simulate``'s set-up, the table and the pauses of the loop
  (wall time minus the time inside the compiled loop ``run_loop``);
- the compiled loop's right-hand-side evaluations by where they are spent: accepted steps,
  rejected steps and re-evaluations after a projection or a contact-mode change (and one at each
  call's start), each as its count times the measured cost of one evaluation;
- the table samples and the peak search (golden-section): since issue 27 no right-hand side each (the
  state, accelerations and reactions come from DOPRI5's continuous extension), only the contact force
  law at each point (count times its measured cost);
- **step control**: what remains of the compiled loop (stage combinations, error norm, drift check
  and projection, the continuous extension, contact records, peak bookkeeping).

The cost of one evaluation is measured on the run's own states (the table's samples: the same
positions, speeds and contacts) part by part: the constraint Jacobian (Phi, Phi_q, gamma), the
force elements, the contact search and contact forces, the Schur complement Phi_q M^-1 Phi_q^T
(the mass matrix is diagonal: this is where it enters), the linear solve (Cholesky) and the whole
evaluation (``deriv``'s: ``kernel.accel_arrays`` on the model record's parts, as a step takes them); the
parts are timed in compiled loops, so call overhead is excluded.

All times are the process's CPU time (``time.process_time``; the loop is single-threaded), so a busy
shared machine inflates them less than wall time would; ratios are still best measured in one run.

With ``--baseline DIR [DIR ...]`` (scratch copies of earlier versions whose ``wearbench`` package lies in
``DIR/wearbench``, e.g. main and f183162 exported by ``git archive``) it also times each of them in a
subprocess, interleaved with this one (best of ``--repeat``), and prints the ratio per state.
This version is timed in this process, after its profile, and there ran up to 1.24x faster or slower
than the same code in a fresh process (issue 47's runs): to compare two versions, export both and
give both as baselines (``--baseline NEW OLD``), so each is timed in fresh processes.

Run:  .venv/bin/python -m benchmarks.model.profile_revolution [--revolutions 3] [--repeat 3]
          [--baseline /tmp/wb_main /tmp/wb_base_f183162]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from contextlib import contextmanager

import numpy as np

STATES = ("0.3 mm new", "0.3 mm second wear")


def _scenes():
    from wearbench.bench.load import load_bench, shipped_bench
    from wearbench.model.realisation import state_scene

    bench = load_bench(shipped_bench("ninebar-testbed"))
    by_name = {s.name: s for s in bench.states}
    return {name: state_scene(bench, by_name[name]) for name in STATES}


def _timed_runs(revolutions: float) -> dict:
    """One timed run per state (compiled beforehand): wall time and step counts."""
    from wearbench.model import simulate

    out = {}
    for name, scene in _scenes().items():
        simulate(scene, t_end=1e-3)
        t0 = time.process_time()
        res = simulate(scene, revolutions=revolutions)
        wall = time.process_time() - t0
        s = res.summary
        out[name] = {"wall": wall, "steps": s["steps"], "rejected": s["rejected_steps"],
                     "nfev": s["function_evaluations"], "peak_fn": s["peak_fn"],
                     "peak_acc": s["peak_slider_acc"]}
    return out


def _part_timers():
    """Compiled loops timing each part of one evaluation over a set of states (built on first use), compiled
    as the model's loop is: without numba's reference counting (``_nrt=False``, see ``model/integrators.py``)."""
    from numba import njit
    from wearbench.model import kernel as K

    as_the_loop = njit(_nrt=False)

    @as_the_loop
    def constraints(reps, ts, ys, speed, P, W):
        n = ys.shape[1] // 2
        for _ in range(reps):
            for i in range(ts.shape[0]):
                K.constraints(ts[i], ys[i, :n], ys[i, n:], speed, P, W)

    @as_the_loop
    def elements(reps, ts, ys, speed, P, W):
        n = ys.shape[1] // 2
        for _ in range(reps):
            for i in range(ts.shape[0]):
                K.element_forces(ys[i, :n], ys[i, n:], P, W.g)

    @as_the_loop
    def contacts(reps, ts, ys, speed, P, W, inc, v0i, cout):
        """The force law alone (as at a table sample: the bodies' cos/sin computed)."""
        n = ys.shape[1] // 2
        for _ in range(reps):
            for i in range(ts.shape[0]):
                K.clearance_arrays(ys[i, :n], ys[i, n:], P, W, inc[i], v0i[i], cout, False)

    @as_the_loop
    def contacts_in_rhs(reps, ts, ys, speed, P, W, inc, v0i, cout, css, sns):
        """The force law as in a right-hand side: the bodies' cos/sin from the constraints (copied in)."""
        n = ys.shape[1] // 2
        for _ in range(reps):
            for i in range(ts.shape[0]):
                for b in range(css.shape[1]):
                    W.cs[b] = css[i, b]
                    W.sn[b] = sns[i, b]
                K.clearance_arrays(ys[i, :n], ys[i, n:], P, W, inc[i], v0i[i], cout, True)

    @as_the_loop
    def schur(reps, ts, ys, speed, P, W, Jvs):
        for _ in range(reps):
            for i in range(ts.shape[0]):
                K.schur(P, Jvs[i], W.S)

    @as_the_loop
    def _copy(dst, src):  # dst[:] = src would allocate (numba copies a source that may overlap)
        for a in range(src.shape[0]):
            for b in range(src.shape[1]):
                dst[a, b] = src[a, b]

    @as_the_loop
    def solve(reps, Ss, rhs, S, lam, first):
        for _ in range(reps):
            for i in range(Ss.shape[0]):
                _copy(S, Ss[i])
                K.cholesky_solve(S, rhs, lam, first)

    @as_the_loop
    def copy_only(reps, Ss, rhs, S, lam, first):
        for _ in range(reps):
            for i in range(Ss.shape[0]):
                _copy(S, Ss[i])

    @as_the_loop
    def evaluation(reps, ts, ys, speed, P, W, inc, v0i, dy, lam, cout):
        """A right-hand side as the step evaluates it (integrators.deriv on the model record's parts)."""
        n = ys.shape[1] // 2
        for _ in range(reps):
            for i in range(ts.shape[0]):
                K.accel_arrays(ts[i], ys[i, :n], ys[i, n:], speed, P, W, (0.0, 0.0), inc[i], v0i[i], dy[n:], lam, cout)
                for j in range(n):
                    dy[j] = ys[i, n + j]

    return constraints, elements, contacts, contacts_in_rhs, schur, solve, copy_only, evaluation


def clock(fn, *args, budget: float = 0.3, best_of: int = 3) -> float:
    """CPU seconds per call of fn(reps, *args), reps grown until a call takes ``budget / 3``; the best of
    ``best_of`` timings at that count."""
    fn(1, *args)
    reps = 1
    while True:
        t0 = time.process_time()
        fn(reps, *args)
        dt = time.process_time() - t0
        if dt > budget / 3 or reps > 1 << 20:
            break
        reps *= 2
    best = dt
    for _ in range(best_of - 1):
        t0 = time.process_time()
        fn(reps, *args)
        best = min(best, time.process_time() - t0)
    return best / reps


@contextmanager
def watched_loop(whole_state: bool = False):
    """Patch the compiled integration loop for the runs inside: yields a dict with the CPU seconds
    spent in it (``cpu``), its calls (``calls``) and the output times ``t`` of the last call's ``Output``
    record (the eighth argument). The loop records only the state entries the table reads; with
    ``whole_state`` it records every entry, kept as ``y`` (one row per output time; the table's own
    entries are copied back after each call), and its time is then not the plain loop's."""
    from wearbench.model import integrators as I

    inner, spent = I.run_loop, {"cpu": 0.0, "calls": 0}

    def timed(*args):
        out = args[7]
        if whole_state:
            N = args[4].shape[0]
            if spent.get("t") is not out.t:  # a new run: its whole-state arrays
                spent["y"], spent["a"] = np.zeros((out.t.size, N)), np.zeros((out.t.size, N // 2))
            whole = I.Output(t=out.t, y=spent["y"], a=spent["a"], c=out.c, lam=out.lam, rec=out.rec,
                             record=out.record, evaluate=out.evaluate, ycols=np.arange(N),
                             acols=np.arange(N // 2))
            args = (*args[:7], whole, *args[8:])
        t0 = time.process_time()
        status = inner(*args)
        spent["cpu"] += time.process_time() - t0
        spent["calls"] += 1
        spent["t"] = out.t
        if whole_state:
            out.y[:] = spent["y"][:, out.ycols]
            out.a[:] = spent["a"][:, out.acols]
        return status

    I.run_loop = timed
    try:
        yield spent
    finally:
        I.run_loop = inner


def contact_modes(scene, res, every: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """(in contact, impact-speed memory) per output sample of ``res`` and clearance joint, as the
    run's table shows them (every ``every``-th sample): the contact arguments of the kernel's parts."""
    pen = np.stack([res.table[f"{j}_pen"].to_numpy()[::every] for j in scene.clearance_joints], axis=1)
    vn = np.stack([res.table[f"{j}_vn"].to_numpy()[::every] for j in scene.clearance_joints], axis=1)
    return np.ascontiguousarray((pen > 0).astype(np.int64)), np.ascontiguousarray(np.maximum(np.abs(vn), 1e-3))


def _profile(name: str, scene, revolutions: float) -> dict:
    """Run ``scene`` once with the compiled loop timed and its states kept, then time the parts."""
    from wearbench.model import integrators as I
    from wearbench.model import kernel as K
    from wearbench.model import simulate

    simulate(scene, t_end=1e-3)  # compile
    with watched_loop() as spent:
        t0 = time.process_time()
        res = simulate(scene, revolutions=revolutions)
        wall = time.process_time() - t0
    with watched_loop(whole_state=True) as states:  # the same run again, for its states
        simulate(scene, revolutions=revolutions)
    s = res.summary
    every = max(1, states["t"].size // 400)
    ts = np.ascontiguousarray(states["t"][::every])
    ys = np.ascontiguousarray(states["y"][::every])
    P, W, speed = scene.params, scene.work(), scene.bench.speed
    n, m, nc = scene.n, scene.m, len(scene.clearance_joints)
    inc, v0i = contact_modes(scene, res, every)
    cout = np.zeros((nc, K.NCO))
    Jvs = np.zeros((ts.size, m, 2, 3))
    Ss = np.zeros((ts.size, m, m))
    css, sns = np.zeros((ts.size, n // 3)), np.zeros((ts.size, n // 3))
    for i in range(ts.size):
        K.constraints(ts[i], ys[i, :n].copy(), ys[i, n:].copy(), speed, P, W)
        Jvs[i] = W.Jv
        css[i], sns[i] = W.cs, W.sn
        K.schur(P, W.Jv, W.S)
        Ss[i] = W.S
    constraints, elements, contacts, contacts_in_rhs, schur, solve, copy_only, evaluation = _part_timers()
    solve_args = (Ss, np.ones(m), np.zeros((m, m)), np.zeros(m), P.s_first)
    per = ts.size
    cost = {
        "constraint Jacobian (Phi, Phi_q, gamma)": clock(constraints, ts, ys, speed, P, W) / per,
        "force elements (gravity, springs)": clock(elements, ts, ys, speed, P, W) / per,
        "contact search + contact forces": clock(contacts_in_rhs, ts, ys, speed, P, W, inc, v0i, cout, css, sns)
                                           / per,
        "Schur complement Phi_q M^-1 Phi_q^T": clock(schur, ts, ys, speed, P, W, Jvs) / per,
        "linear solve (Cholesky, m x m)": max(0.0, (clock(solve, *solve_args) - clock(copy_only, *solve_args))
                                                / per),
    }
    one = clock(evaluation, ts, ys, speed, P, W, inc, v0i, np.zeros(2 * n), np.zeros(m), cout) / per
    cost["rest of an evaluation (a = M^-1 (g - Phi_q^T lam), rhs)"] = max(0.0, one - sum(cost.values()))
    stages = 6  # DOPRI5 with FSAL: six new evaluations per attempted step
    steps, rej, nfev = s["steps"], s["rejected_steps"], s["function_evaluations"]
    counts = {
        "accepted steps": stages * steps,
        "rejected steps": stages * rej,
        "re-evaluation (projection, mode change, start)": max(0, nfev - stages * (steps + rej)),
    }
    loop = spent["cpu"]
    # table samples and the peak search's points (golden section on the same continuous extension): the
    # contact force law each, no right-hand side
    law = clock(contacts, ts, ys, speed, P, W, inc, v0i, cout) / per  # with the bodies' cos/sin computed
    table = res.table.shape[0] * law
    peaks = s["peak_searches"] * (2 * I.GOLDEN_ITERATIONS + 4) * law
    evals = sum(counts.values()) * one + table + peaks
    return {"state": name, "wall": wall, "loop": loop, "calls": spent["calls"], "python": wall - loop,
            "one": one, "cost": cost, "counts": counts, "table": table, "samples": res.table.shape[0],
            "peaks": peaks, "searches": s["peak_searches"],
            "control": loop - evals, "steps": steps, "rejected": rej,
            "nfev": nfev, "revolutions": revolutions}


def _print_profile(p: dict) -> None:
    rev = p["revolutions"]
    wall = p["wall"]
    print(f"\n{p['state']}: {wall / rev * 1e3:.0f} ms per revolution ({rev:g} revolutions in {wall:.2f} s; "
          f"{p['steps'] / rev:.0f} accepted + {p['rejected'] / rev:.0f} rejected steps, "
          f"{p['nfev'] / rev:.0f} step evaluations per revolution; one evaluation {p['one'] * 1e6:.2f} us)")
    print(f"  {'where':<58} {'evals/rev':>10} {'ms/rev':>8} {'share':>7}")
    rows = [(f"RHS in {what}", cnt / rev, cnt * p["one"]) for what, cnt in p["counts"].items()]
    rows.append((f"table samples ({p['samples'] / rev:.0f}/rev): contact force law only", None, p["table"]))
    rows.append((f"peak search ({p['searches'] / rev:.0f}/rev): contact force law only", None, p["peaks"]))
    rows.append(("step control (combinations, error norm, drift/projection, records)", None, p["control"]))
    rows.append((f"Python between compiled calls ({p['calls']} calls)", None, p["python"]))
    for what, cnt, sec in rows:
        c = f"{cnt:10.0f}" if cnt is not None else f"{'':>10}"
        print(f"  {what:<58} {c} {sec / rev * 1e3:8.1f} {sec / wall:7.1%}")
    print("  one evaluation, part by part (us; share of an evaluation):")
    for what, sec in p["cost"].items():
        print(f"    {what:<56} {sec * 1e6:8.3f} {sec / p['one']:7.1%}")


def _baseline(path: str, revolutions: float) -> dict:
    env = dict(os.environ, PYTHONPATH=path)
    cmd = [sys.executable, os.path.abspath(__file__), "--time-only", "--revolutions", str(revolutions)]
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--revolutions", type=float, default=3.0)
    ap.add_argument("--repeat", type=int, default=3, help="timed runs per version (best of)")
    ap.add_argument("--baseline", nargs="+", default=[], help="directories holding earlier versions' wearbench "
                    "packages (each timed interleaved with this one)")
    ap.add_argument("--time-only", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.time_only:
        import wearbench.model

        out = _timed_runs(args.revolutions)
        out["_source"] = os.path.dirname(wearbench.model.__file__)
        print(json.dumps(out))
        return
    import wearbench.model

    print(f"test bed ninebar-testbed, 0.3 mm, nominal bench, default method, 20 kHz table; "
          f"wearbench from {os.path.dirname(wearbench.model.__file__)}")
    for name, scene in _scenes().items():
        _print_profile(_profile(name, scene, args.revolutions))
    if not args.baseline:
        return
    best: dict[str, dict[str, dict]] = {label: {} for label in ("this", *args.baseline)}
    for _ in range(args.repeat):
        timed = [(path, _baseline(path, args.revolutions)) for path in args.baseline]
        for label, runs in (*timed, ("this", _timed_runs(args.revolutions))):
            for name in STATES:
                if name not in best[label] or runs[name]["wall"] < best[label][name]["wall"]:
                    best[label][name] = runs[name]
    rev = args.revolutions
    for path in args.baseline:
        print(f"\nthis version against {path} (best of {args.repeat}, interleaved, same machine, "
              f"{rev:g} revolutions)")
        print(f"  {'state':<20} {'base ms/rev':>11} {'this ms/rev':>11} {'speed-up':>8} | {'base steps':>10} "
              f"{'rej':>6} {'this steps':>10} {'rej':>6}")
        for name in STATES:
            b, t = best[path][name], best["this"][name]
            print(f"  {name:<20} {b['wall'] / rev * 1e3:11.1f} {t['wall'] / rev * 1e3:11.1f} "
                  f"{b['wall'] / t['wall']:7.2f}x | {b['steps']:10d} {b['rejected']:6d} {t['steps']:10d} "
                  f"{t['rejected']:6d}")
    new, worn = (best["this"][s]["wall"] for s in STATES)
    print(f"  worn / new (this version): {worn / new:.2f}x")


if __name__ == "__main__":
    main()
