"""`wearbench wear`: wear a bench's clearance joints in stages and write surfaces, summary, plots."""

from __future__ import annotations

import argparse
import json
import math
import sys

from wearbench.bench.load import load_bench, resolve_bench
from wearbench.bench.output_file import check_output, output_folder
from wearbench.bench.schema import Bench
from wearbench.bench.units import QuantityError, parse_quantity
from wearbench.cli.compute import add_compute_arguments, compute_options
from wearbench.cli.options import (
    add_force_argument,
    check_wear_coefficient,
    motor_speed,
    nonnegative_int,
    parse_clearances,
    positive_int,
    positive_number,
)


def parse_speed(text: str | None) -> float | None:
    """``--speed`` of wear and study (None: the bench's)."""
    return None if text is None else motor_speed(text)


def add_plan_arguments(p: argparse.ArgumentParser) -> None:
    """Options shared by `wear` and `study` that shape how the surfaces wear."""
    p.add_argument("--stage-cycles", type=positive_number, default=None,
                   help="crank cycles per stage (default: bench cycles_per_stage x stage_scale = 200000)")
    p.add_argument("--update-depth", default=None,
                   help="most depth one surface update adds to any surface, e.g. 4um (default 4 um; "
                   "updates also shrink when the contact pressure changes)")
    p.add_argument("--settle", type=nonnegative_int, default=None,
                   help="revolutions simulated before the first update, not counted (default 1)")
    p.add_argument("--sliding", choices=("rotation", "tangential"), default="rotation",
                   help="sliding distance per step: R1 x relative rotation (paper, default) or |v_t| dt")
    p.add_argument("--footprint", choices=("pressure", "hertz", "region"), default="pressure",
                   help="spread wear over the contact arc by elastic-foundation pressure (default), evenly over "
                   "the Hertz width, or into one region (paper)")
    p.add_argument("--split", type=float, default=None,
                   help="share of each depth increment on the bearing (default: bench [wear] split)")
    p.add_argument("--wear-coefficient", default=None,
                   help="Archard K_n = K_m/H, e.g. '6.6e-14 1/Pa' (default: bench [wear] coefficient)")
    p.add_argument("--method", default="default", help="integrator (see 'wearbench simulate --help')")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "wear", help="wear clearance joints in stages (Archard), write surfaces, summary and plots",
        description="Run the mechanism continuously, recording contacts; after every revolution spread its "
        "Archard wear (V = K_n F dS) over the contact arc by pressure and apply it for as many cycles as keep "
        "the depth added per update under --update-depth, until each stage (default 200,000 cycles) is worn. "
        "Starts from the surfaces the bench file names, else unworn.")
    p.add_argument("bench", metavar="BENCH.toml")
    p.add_argument("--clearance", help="radial clearance: '0.6mm' for every joint or 'A=0.6mm,B=0.3mm'")
    p.add_argument("--speed", help="motor speed, e.g. -5pi (rad/s), 150rpm (default: the bench's)")
    p.add_argument("--stages", type=positive_int, default=2, help="number of wear stages (default 2)")
    add_plan_arguments(p)
    p.add_argument("--convergence", default=None, metavar="K1,K2,...",
                   help="also wear the same total cycles with the update depth divided by K1, K2, ... and report "
                   "max depth, reachable depth and worn volume per refinement (e.g. 1,2,4); the refinements run on the "
                   "compute layer (--scheduler, --workers)")
    add_compute_arguments(p)
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG figures")
    add_force_argument(p)
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=run)


def plan_from_args(args: argparse.Namespace, bench: Bench, stages: int):
    from wearbench.model.wear_stages import StagePlan

    return StagePlan.from_bench(bench, stages=stages, stage_cycles=args.stage_cycles,
                                update_depth=_length("--update-depth", args.update_depth), settle=args.settle,
                                method=args.method, sliding=args.sliding, footprint=args.footprint,
                                split=args.split, coefficient=_coefficient(args.wear_coefficient))


def _length(option: str, text: str | None) -> float | None:
    if text is None:
        return None
    try:
        return parse_quantity(text, "length")
    except QuantityError as exc:
        raise ValueError(f"{option} {text!r}: {exc}") from None


def _coefficient(text: str | None) -> float | None:
    if text is None:
        return None
    try:
        value = parse_quantity(text, "wear_coefficient", bare_unit="1/Pa")
    except (QuantityError, KeyError) as exc:
        raise ValueError(f"--wear-coefficient {text!r}: {exc}") from None
    return check_wear_coefficient(value, "--wear-coefficient", text)


def run(args: argparse.Namespace) -> int:
    from wearbench.cli.progress import progress
    from wearbench.model.surfaces import surfaces_from_bench
    from wearbench.model.wear_stages import run_stages
    from wearbench.studies.wear_report import convergence_markdown, run_summary, write_run

    bench = load_bench(resolve_bench(args.bench))
    clearances = parse_clearances(args.clearance, bench) or None
    speed = parse_speed(args.speed)
    plan = plan_from_args(args, bench, args.stages)
    compute = compute_options(args, bench) if args.convergence else None  # a bad scheduler fails now, not after the run
    ks = _refinements(args.convergence) if args.convergence else []
    initial = surfaces_from_bench(bench) or None
    check_output(args.out, force=args.force, folder=True)  # refused before the wear run
    with progress() as bar:
        task = bar.add_task(f"wear {bench.name}", total=plan.stages * plan.stage_cycles, info="")

        def update(cycles, surfaces):
            peak = " ".join(f"{j} {max(s.max_depth) * 1e6:.3g}um" for j, s in surfaces.items())
            bar.update(task, completed=cycles, info=f"{cycles:,.0f} cycles, max depth {peak}")

        wear_run = run_stages(bench, plan, clearances=clearances, speed=speed, initial=initial, on_update=update)
    with output_folder(args.out, force=args.force) as out:
        paths = write_run(wear_run, out, plots=not args.no_plots)
        summary = run_summary(wear_run)
        if ks:
            from wearbench.studies.study import staging_convergence

            total = plan.stage_cycles * plan.stages
            rows = staging_convergence(bench, ks, total, plan, clearances=clearances, speed=speed, initial=initial,
                                       out=out, known={plan.refinement: wear_run}, scheduler=compute.scheduler,
                                       workers=compute.workers)
            summary["convergence"] = rows
            paths["summary"].write_text(json.dumps(summary, indent=2, default=float) + "\n")
    if ks and not args.json:
        print(convergence_markdown(summary["convergence"]))
    if args.json:
        json.dump(summary, sys.stdout, indent=2, default=float)
        print()
    else:
        for st in summary["stages"]:
            for j, js in st["joints"].items():
                b, jr = js["bearing"], js["journal"]
                print(f"{st['label']:>12}  {j}: bearing max {b['max_depth_m']:.3e} m at {b['max_at_deg']:.0f} deg "
                      f"(reachable {b['reachable_depth_m']:.3e} m) zones {b['zones_deg']}; journal max "
                      f"{jr['max_depth_m']:.3e} m (reachable {jr['reachable_depth_m']:.3e} m)")
        print(f"wrote {args.out}/ (surfaces/*.npz, depths.csv, summary.json{', figures' if not args.no_plots else ''})")
    return 0


def _refinements(text: str) -> list[float]:
    """``--convergence K1,K2,...``: refinement factors > 0."""
    try:
        ks = sorted({float(k) for k in text.split(",")})
    except ValueError:
        ks = []
    if not ks or not all(math.isfinite(k) and k > 0 for k in ks):
        raise ValueError(f"--convergence {text!r}: expected refinement factors > 0 such as 1,2,4")
    return ks
