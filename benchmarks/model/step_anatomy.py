"""Where a simulated revolution's steps go: contact phases, flights between them, and steps per phase.

Issue 27 asked for a revolution four times cheaper. The profile (``profile_revolution.py``) says the
time follows the steps; this script says what sets the number of steps. For the test bed (0.3 mm,
nominal bench, default method and tolerance) on new and 400,000-cycle worn surfaces it runs
``--settle`` s and then ``--revolutions`` more, records every accepted step (``record_contacts``)
and splits the steps after the settle into

- **contact phases** of each clearance joint (a run of accepted steps ending in penetration > 0)
  and **flights** (no joint in contact), with how many there are per revolution, how long they
  last and how many accepted steps each takes;
- the **approach**: the accepted steps of a flight after its largest one (the controller shrinking
  its step onto the next contact onset; one step would do if the onset were located as an event);
- **rejected steps** per contact onset: the difference of two runs from the same start, one to the
  settle and one to the end (rejections are not recorded step by step).

Run:  .venv/bin/python -m benchmarks.model.step_anatomy [--revolutions 2] [--settle 0.5] [--method accurate] [--rtol 1e-6]
"""

from __future__ import annotations

import argparse

import numpy as np

STATES = ("0.3 mm new", "0.3 mm second wear")


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) index pairs of the True runs of ``mask``."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)))


def anatomy(scene, speed_rev_s: float, settle: float, revolutions: float, method: str = "default",
            rtol: float | None = None) -> dict:
    """Step counts of one state after ``settle`` s, per revolution (``method`` at its own tolerance or rtol,
    atol = rtol x 1e-3 m)."""
    from wearbench.model import simulate

    t_end = settle + revolutions / speed_rev_s
    tol = {} if rtol is None else {"rtol": rtol, "atol": rtol * 1e-3}
    early = simulate(scene, t_end=settle, method=method, **tol).summary
    run = simulate(scene, t_end=t_end, record_contacts=True, method=method, **tol)
    joints = list(run.contacts)
    t = run.contacts[joints[0]]["t"].to_numpy()
    keep = t[1:] > settle
    h = np.diff(t)[keep]
    pen = np.stack([run.contacts[j]["pen"].to_numpy()[1:][keep] > 0 for j in joints])
    flights = _runs(~pen.any(axis=0))
    approach = [b - a - 1 - int(np.argmax(h[a:b])) for a, b in flights]
    out = {"steps": int(h.size), "rejected": run.summary["rejected_steps"] - early["rejected_steps"],
           "flights": len(flights), "flight_steps": [b - a for a, b in flights],
           "flight_ms": [1e3 * h[a:b].sum() for a, b in flights], "approach": approach,
           "time_in_flight": float(sum(h[a:b].sum() for a, b in flights) / h.sum())}
    for k, j in enumerate(joints):
        phases = _runs(pen[k])
        out[j] = {"onsets": len(phases), "steps": [b - a for a, b in phases],
                  "ms": [1e3 * h[a:b].sum() for a, b in phases]}
    out["joints"] = joints
    return {k: (v / revolutions if isinstance(v, int) else v) for k, v in out.items()} | {"revolutions": revolutions}


def _q(values, q=0.5) -> float:
    return float(np.quantile(values, q)) if len(values) else float("nan")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--revolutions", type=float, default=2.0)
    ap.add_argument("--settle", type=float, default=0.5, help="seconds run before counting (s)")
    ap.add_argument("--method", default="default", help="a method of wearbench.model.METHODS (e.g. accurate)")
    ap.add_argument("--rtol", type=float, help="the method at this rtol (atol = rtol x 1e-3 m) instead of its own")
    args = ap.parse_args()
    from wearbench.bench.load import load_bench, shipped_bench
    from wearbench.model.realisation import state_scene

    bench = load_bench(shipped_bench("ninebar-testbed"))
    states = {s.name: s for s in bench.states}
    speed = abs(bench.speed) / (2 * np.pi)
    rows = {name: anatomy(state_scene(bench, states[name]), speed, args.settle, args.revolutions, args.method,
                          args.rtol) for name in STATES}
    tol = "its own tolerance" if args.rtol is None else f"rtol {args.rtol:g}"
    print(f"test bed ninebar-testbed, nominal bench, method {args.method} at {tol}; {args.revolutions:g} revolutions after "
          f"{args.settle:g} s; per revolution unless said")
    print(f"  {'':<44}" + "".join(f"{n:>20}" for n in STATES))

    def line(label, fn):
        print(f"  {label:<44}" + "".join(f"{fn(rows[n]):>20}" for n in STATES))

    line("accepted / rejected steps", lambda r: f"{r['steps']:.0f} / {r['rejected']:.0f}")
    for j in rows[STATES[0]]["joints"]:
        line(f"joint {j}: contact onsets", lambda r, j=j: f"{r[j]['onsets'] / r['revolutions']:.0f}")
        line(f"joint {j}: steps per contact phase (median, p90)",
             lambda r, j=j: f"{_q(r[j]['steps']):.0f}, {_q(r[j]['steps'], 0.9):.0f}")
        line(f"joint {j}: contact phase length (median, ms)", lambda r, j=j: f"{_q(r[j]['ms']):.3f}")
    line("flights (no joint in contact)", lambda r: f"{r['flights']:.0f}")
    line("share of time in flight", lambda r: f"{r['time_in_flight']:.2f}")
    line("flight length (median, p90, ms)", lambda r: f"{_q(r['flight_ms']):.2f}, {_q(r['flight_ms'], 0.9):.2f}")
    line("steps per flight (median, p90)", lambda r: f"{_q(r['flight_steps']):.0f}, {_q(r['flight_steps'], 0.9):.0f}")
    line("approach steps in flights (sum)", lambda r: f"{sum(r['approach']) / r['revolutions']:.0f}")
    line("rejected steps per contact onset",
         lambda r: f"{r['rejected'] / sum(r[j]['onsets'] / r['revolutions'] for j in r['joints']):.2f}")


if __name__ == "__main__":
    main()
