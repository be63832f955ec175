"""Time one wear stage on the nine-bar at 0.6 mm, -5 pi rad/s (issue 4; target <= 60 s).

Runs the paper's stage (100 counted cycles x 2000) and cheaper variants (fewer counted cycles after
a settling revolution, scaled to the same 200,000 cycles), and prints per variant the wall time,
integrator steps and the stage's max depth per joint with its error against the 100-cycle stage.

    .venv/bin/python benchmarks/wear_stage.py [--variants 100,20+1,10+1,5+1]

A variant "N+S" counts N cycles after S settling revolutions.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from wearbench.hardware.bench import load_bench, shipped_bench
from wearbench.model.wear_stages import StagePlan, run_stages


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variants", default="100,20+1,10+1,5+1")
    ap.add_argument("--method", default="default")
    args = ap.parse_args()
    bench = load_bench(shipped_bench("ninebar"))
    clear = {j.name: 0.6e-3 for j in bench.clearance_joints}
    rows = []
    for v in args.variants.split(","):
        n, _, s = v.partition("+")
        plan = StagePlan.from_bench(bench, stages=1, sim_cycles=float(n), settle=float(s or 0), method=args.method)
        t0 = time.perf_counter()
        run = run_stages(bench, plan, clearances=clear, speed=-5 * math.pi)
        wall = time.perf_counter() - t0
        st = run.stages[0]
        rows.append((v, wall, st.sim_summary.get("steps"), {j: s.bearing for j, s in st.surfaces.items()}))
    ref = rows[0][3]
    print(f"nine-bar, 0.6 mm, -5 pi rad/s, one stage = {plan.stage_cycles:.0f} cycles, method {args.method}")
    print(f"{'variant':>8} {'wall s':>8} {'steps':>9} " + " ".join(
        f"{'max ' + j + ' um':>10} {'err ' + j:>7} {'rms ' + j:>7}" for j in ref))
    for v, wall, steps, depth in rows:
        cells = []
        for j, d in depth.items():
            r = ref[j]
            cells.append(f"{d.max() * 1e6:10.3f} {abs(d.max() / r.max() - 1):7.1%} "
                         f"{np.sqrt(np.mean((d - r) ** 2)) / r.max():7.1%}")
        print(f"{v:>8} {wall:8.1f} {steps!s:>9} " + " ".join(cells))
    print("target: one stage of 100 cycles <= 60 s; err = |max depth / reference - 1|, "
          "rms = RMS depth difference / reference max (reference: first row)")


if __name__ == "__main__":
    main()
