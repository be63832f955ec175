"""Wear convergence at a fixed cycle count, and the cost of a converged prediction (issue 13).

Wears the nine-bar (0.6 mm, -5 pi rad/s) through two stages of 200,000 cycles at refinements
k = 1, 2, 4, ... (the depth added per surface update is ``--cap`` / k), and prints per refinement
and joint: max depth and reachable depth (what a circular counter-body can touch) of bearing and
journal, worn volume, surface updates, simulated revolutions, CPU time and wall time, and the
largest change against the next coarser refinement (target: < 10 % between the two finest).

    .venv/bin/python -m benchmarks.model.wear_convergence [--refinements 1,2,4] [--out DIR]
    .venv/bin/python -m benchmarks.model.wear_convergence --refinements 4 --out DIR   # one run, e.g. in parallel
    .venv/bin/python -m benchmarks.model.wear_convergence --table --out DIR          # table of the runs in DIR

Each run is written to DIR/k<refinement>/ (surfaces, summary.json with CPU time), so refinements
can run as separate processes and be tabulated together.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

from wearbench.bench.load import load_bench, shipped_bench
from wearbench.model.surfaces import JointSurfaces
from wearbench.model.wear_stages import StagePlan, WearRun, convergence, run_stages
from wearbench.studies.wear_report import convergence_markdown, write_run


def _run(bench, k: float, args) -> None:
    plan = StagePlan.from_bench(bench, stages=args.stages, stage_cycles=args.cycles / args.stages,
                                update_depth=args.cap * 1e-6, refinement=k)
    clear = dict.fromkeys((j.name for j in bench.clearance_joints), args.clearance * 1e-3)
    cpu0, wall0 = time.process_time(), time.perf_counter()
    run = run_stages(bench, plan, clearances=clear, speed=args.speed)
    cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
    out = Path(args.out) / f"k{k:g}"
    write_run(run, out, plots=False)
    (out / "cost.json").write_text(json.dumps({"refinement": k, "cpu_s": cpu, "wall_s": wall,
                                               "revolutions": run.revolutions,
                                               "updates": sum(s.updates for s in run.stages)}))


def _load(bench, directory: Path, args) -> tuple[WearRun, dict]:
    """A finished run back from its directory (final surfaces and stage volumes)."""
    cost = json.loads((directory / "cost.json").read_text())
    summary = json.loads((directory / "summary.json").read_text())
    plan = StagePlan.from_bench(bench, stages=args.stages, stage_cycles=args.cycles / args.stages,
                                update_depth=args.cap * 1e-6, refinement=cost["refinement"])
    clear = {j: float(c) for j, c in summary["clearances_m"].items()}
    run = WearRun(summary["bench"], summary["speed_rad_s"], clear, plan, {})
    from wearbench.model.wear_stages import Stage

    for k, st in enumerate(summary["stages"], start=1):
        surf = {j: JointSurfaces.load(directory / "surfaces" / f"{j}_{k}.npz") for j in clear}
        vol = {j: st["joints"][j]["worn_volume_m3"] for j in clear}
        run.stages.append(Stage(k, st["label"], {}, {}, surf, {}, 0.0, vol, vol, st["wall_time_s"],
                                st["updates"], st["revolutions"]))
    return run, cost


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bench", default="ninebar")
    ap.add_argument("--refinements", default="1,2,4")
    ap.add_argument("--cycles", type=float, default=400_000.0, help="total crank cycles (fixed)")
    ap.add_argument("--stages", type=int, default=2)
    ap.add_argument("--cap", type=float, default=4.0, help="depth cap per update at refinement 1, um")
    ap.add_argument("--clearance", type=float, default=0.6, help="mm, every clearance joint")
    ap.add_argument("--speed", type=float, default=-5 * math.pi, help="rad/s")
    ap.add_argument("--out", default="/tmp/wear-convergence")
    ap.add_argument("--table", action="store_true", help="only tabulate the runs already in --out")
    args = ap.parse_args()
    bench = load_bench(shipped_bench(args.bench))
    if not args.table:
        for k in (float(x) for x in args.refinements.split(",")):
            _run(bench, k, args)
    runs, costs = {}, {}
    for d in sorted(Path(args.out).glob("k*")):
        if (d / "cost.json").exists():
            run, cost = _load(bench, d, args)
            runs[cost["refinement"]], costs[cost["refinement"]] = run, cost
    rows = convergence(runs)
    for r in rows:
        r["wall_time_s"] = round(costs[r["refinement"]]["wall_s"], 1)
    print(f"{args.bench}, {args.clearance:g} mm, {args.speed:.4g} rad/s, {args.cycles:,.0f} cycles in "
          f"{args.stages} stages (fixed); cap {args.cap:g} um / refinement")
    print(convergence_markdown(rows))
    print()
    print("| refinement | CPU s | wall s | revolutions | updates |")
    print("|---|---|---|---|---|")
    for k in sorted(costs):
        c = costs[k]
        print(f"| {k:g} | {c['cpu_s']:.0f} | {c['wall_s']:.0f} | {c['revolutions']:g} | {c['updates']} |")
    ks = sorted(runs)
    if len(ks) >= 2:
        finest = [r for r in rows if r["refinement"] == ks[-1]]
        worst = max(v for r in finest for key, v in r.items() if key.endswith("_change"))
        print(f"largest change between refinements {ks[-2]:g} and {ks[-1]:g}: {worst:.1%} (target < 10 %)")
    print("CPU time: this process only (the machine is shared by other jobs; wall time is longer)")


if __name__ == "__main__":
    main()
