"""Cost of one surface update (issue 13; target: deeply worn <= 2x new): one simulated revolution
on the current surfaces, continued from the last state, plus spreading its wear over the contact
arcs, on the nine-bar at 0.6 mm, -5 pi rad/s.

Times ``--steps`` update steps on new surfaces and on deeply worn ones (by default the state after
400,000 cycles, worn first by this script at refinement 1 and reported; or ``--worn DIR`` holding
``A.npz`` and ``B.npz``), after one settling revolution each, and prints per state CPU time,
integrator steps, rejected steps, right-hand-side evaluations, CPU per right-hand side (the wear
spreading included) and the ratio worn / new.

    .venv/bin/python -m benchmarks.model.wear_stage [--worn DIR] [--steps 10]
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

from wearbench.bench.load import load_bench, shipped_bench
from wearbench.model import build_scene, simulate
from wearbench.model.surfaces import JointSurfaces
from wearbench.model.wear import WearLaw, accumulate_wear
from wearbench.model.wear_stages import StagePlan, run_stages

SPEED = -5 * math.pi


def _update_cost(bench, clear, surfaces, steps: int) -> dict:
    """CPU seconds and integrator counts per update step (mean of ``steps``)."""
    geometry = bench.with_clearances(clear)
    laws = {j: WearLaw.from_bench(geometry, j) for j in clear}
    scene = build_scene(bench, clearances=clear, surfaces=surfaces)
    settle = simulate(scene, revolutions=1, speed=SPEED, output_rate=500.0, record_contacts=True)
    for j in clear:  # untimed: compiles (or loads) the wear spreading, so no step times a compile
        accumulate_wear(settle.contacts[j], laws[j], 1000, surfaces=surfaces.get(j))
    state = settle.final
    totals = {"cpu_s": 0.0, "steps": 0, "rejected": 0, "nfev": 0}
    for _ in range(steps):
        q, v = state
        turns = [round((q[3 * i + 2] - scene.q0[3 * i + 2]) / (2 * math.pi)) for i in range(len(q) // 3)]
        q = q.copy()
        for i, t in enumerate(turns):
            q[3 * i + 2] -= 2 * math.pi * t
        cpu0 = time.process_time()
        res = simulate(scene, revolutions=1, speed=SPEED, output_rate=500.0, record_contacts=True, initial=(q, v))
        for j in clear:
            accumulate_wear(res.contacts[j], laws[j], 1000, surfaces=surfaces.get(j))
        totals["cpu_s"] += time.process_time() - cpu0
        totals["steps"] += res.summary["steps"]
        totals["rejected"] += res.summary["rejected_steps"]
        totals["nfev"] += res.summary["function_evaluations"]
        state = res.final
    return {k: v / steps for k, v in totals.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worn", default=None, help="directory with A.npz and B.npz (default: wear 400,000 cycles)")
    ap.add_argument("--steps", type=int, default=10)
    args = ap.parse_args()
    bench = load_bench(shipped_bench("ninebar"))
    clear = {j.name: 0.6e-3 for j in bench.clearance_joints}
    if args.worn:
        worn = {j: JointSurfaces.load(Path(args.worn) / f"{j}.npz") for j in clear}
    else:
        cpu0, wall0 = time.process_time(), time.perf_counter()
        run = run_stages(bench, StagePlan.from_bench(bench, stages=2), clearances=clear, speed=SPEED)
        worn = run.final
        print(f"worn 400,000 cycles first: {run.revolutions:g} revolutions, "
              f"{sum(s.updates for s in run.stages)} updates, CPU {time.process_time() - cpu0:.0f} s, "
              f"wall {time.perf_counter() - wall0:.0f} s")
    depth = " ".join(f"{j} {s.max_depth[0] * 1e6:.0f}/{s.max_depth[1] * 1e6:.0f}" for j, s in worn.items())
    rows = [("new", _update_cost(bench, clear, {}, args.steps)),
            (f"worn ({depth} um)", _update_cost(bench, clear, worn, args.steps))]
    print(f"nine-bar, 0.6 mm, -5 pi rad/s: one update step = 1 revolution + wear spreading "
          f"(mean of {args.steps}; CPU time of this process, the machine is shared)")
    print(f"{'surfaces':<28} {'CPU ms':>7} {'steps':>7} {'rejected':>9} {'RHS evals':>10} {'us/RHS':>7} {'x new':>6}")
    base = rows[0][1]["cpu_s"]
    for label, r in rows:
        print(f"{label:<28} {r['cpu_s'] * 1e3:7.0f} {r['steps']:7.0f} {r['rejected']:9.0f} {r['nfev']:10.0f} "
              f"{r['cpu_s'] / r['nfev'] * 1e6:7.2f} {r['cpu_s'] / base:6.2f}")
    print("target: worn / new <= 2 (bearing/journal max depths in um)")


if __name__ == "__main__":
    main()
