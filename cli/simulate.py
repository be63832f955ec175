"""`wearbench simulate`: run the multibody theory of a bench file and write the results table."""

from __future__ import annotations

import argparse
import json
import math

from wearbench.cli.options import (
    add_force_argument,
    joint_values,
    motor_speed,
    parse_clearances,
    positive_number,
    positive_quantity,
)
from wearbench.model.methods import METHODS


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "simulate",
        help="simulate a bench's mechanism with its (worn) clearance joints",
        description="Simulate the planar multibody model of a bench file. A fully driven mechanism "
        "with ideal joints is solved by kinematics + inverse dynamics; each clearance joint adds two "
        "freedoms integrated in time (default: adaptive Dormand-Prince 5(4) with constraint projection; "
        "'rk4-paper': the paper's fixed-step RK4 at 1e-4 s with Baumgarte alpha = beta = 20).",
        epilog="Example: wearbench simulate ninebar.toml --clearance A=0.6mm,B=0.6mm --speed -5pi "
        "--revolutions 3 --out run.parquet --plots figs/ --json",
    )
    p.add_argument("bench", metavar="BENCH.toml", help="bench definition file (or a shipped bench name)")
    p.add_argument("--clearance", metavar="J=C,...", default="",
                   help="radial clearance per joint, e.g. A=0.6mm,B=0.3mm; 'ideal' makes a joint an ideal pin")
    p.add_argument("--surfaces", metavar="J=FILE.npz,...", default="",
                   help="worn surfaces per clearance joint (saved JointSurfaces .npz files)")
    p.add_argument("--speed", help="motor speed: '-5pi' (rad/s), '300rpm', '2Hz' (default: the bench's)")
    p.add_argument("--revolutions", type=positive_number, default=3.0, help="duration in motor revolutions (default 3)")
    p.add_argument("--t-end", help="duration instead of revolutions, e.g. '0.5s'")
    p.add_argument("--method", default="default", choices=list(METHODS),
                   help="default: kinematics + inverse dynamics for a fully driven scene with ideal joints, else "
                   "the registered default; or a registered method: "
                   + "; ".join(f"{name} ({m.tableau.name}, {'adaptive' if m.adaptive else 'fixed step'})"
                               if m.tableau else name for name, m in METHODS.items() if name != "default"))
    p.add_argument("--rtol", type=positive_number, help="relative tolerance of the adaptive method")
    p.add_argument("--atol", type=positive_number, help="absolute tolerance (m) of the adaptive method")
    p.add_argument("--step", help="fixed step of rk4-paper, e.g. '1e-4s' or '50us'")
    p.add_argument("--output-rate", help="table samples per second, e.g. '20kHz' (default 20 kHz)")
    p.add_argument("--out", metavar="FILE", help="write the table (.parquet or .csv)")
    p.add_argument("--contacts", metavar="DIR", help="record per-step contact data into DIR/<joint>.parquet")
    p.add_argument("--plots", metavar="DIR", help="write the paper-style figures (PNG and SVG) into DIR")
    add_force_argument(p)
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from wearbench.bench.load import load_bench, resolve_bench
    from wearbench.bench.output_file import check_output, output_file, output_folder
    from wearbench.model import build_scene, simulate
    from wearbench.model.surfaces import JointSurfaces

    bench = load_bench(resolve_bench(args.bench))
    clearances = parse_clearances(args.clearance, bench, ideal=True)
    joints = [j.name for j in bench.clearance_joints]
    surfaces = {j: JointSurfaces.load(v) for j, v in joint_values(args.surfaces, "--surfaces", joints).items()} or None
    speed = motor_speed(args.speed, allow_zero=True) if args.speed else None  # 0 with --t-end: a still motor
    outputs = (("--out", args.out, False), ("--contacts", args.contacts, True), ("--plots", args.plots, True))
    for option, path, folder in outputs:
        if path:  # refused before the simulation runs
            check_output(path, force=args.force, option=option, folder=folder)
    from wearbench.cli.bench_checks import sweep_turns

    sweep_turns(bench, check_range=False)  # a crank that cannot turn is refused in seconds, before the simulation
    try:
        scene = build_scene(bench, clearances=clearances or None, surfaces=surfaces)
    except KeyError as exc:  # an unknown joint name: a user error, one line
        raise ValueError(str(exc.args[0])) from None
    result = simulate(
        scene, revolutions=args.revolutions, method=args.method, rtol=args.rtol, atol=args.atol, speed=speed,
        t_end=positive_quantity(args.t_end, "time", "--t-end", bare_unit="s") if args.t_end else None,
        step=positive_quantity(args.step, "time", "--step", bare_unit="s") if args.step else None,
        output_rate=positive_quantity(args.output_rate, "frequency", "--output-rate", bare_unit="Hz") if args.output_rate else None,
        record_contacts=bool(args.contacts),
    )
    if args.out:
        with output_file(args.out, force=args.force) as out:
            if out.suffix == ".csv":
                result.table.to_csv(out, index=False)
            else:
                result.table.to_parquet(out, index=False)
    if args.contacts:
        with output_folder(args.contacts, force=args.force, option="--contacts") as folder:
            for joint, frame in (result.contacts or {}).items():
                frame.to_parquet(folder / f"{joint}.parquet", index=False)
    if args.plots:
        from wearbench.studies.plots import save_figures

        with output_folder(args.plots, force=args.force, option="--plots") as folder:
            save_figures(result, folder)
    s = result.summary
    if args.json:
        print(json.dumps(s, indent=2))
    else:
        print(f"{bench.name}: {s['description']}")
        print(f"method {s['method']}: {s['steps']} steps ({s['rejected_steps']} rejected) in "
              f"{s['wall_time_s']:.3g} s wall; {s['t_end']:.4g} s simulated at {s['speed']:.4g} rad/s "
              f"({s['speed'] * 30 / math.pi:.4g} rpm)")
        sensor = next((f"{x.name} ({x.body}.{x.point})" for x in bench.sensors if x.kind == "accelerometer"),
                      "the model's acceleration signal")
        print(f"peak acceleration of {sensor} {s['peak_slider_acc']:.4g} m/s^2; constraint drift "
              f"{s['max_constraint_drift']:.2g}")
        for j, f in s["peak_fn"].items():
            print(f"peak contact force {j}: {f:.4g} N")
    return 0
