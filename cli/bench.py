"""`wearbench bench`: list the shipped bench files, check a bench file, show what it describes, copy one
(with the files it names) to start your own."""

from __future__ import annotations

import argparse
import math
import shutil
from pathlib import Path

from rich.markup import escape
from rich.table import Table
from wearbench.bench.load import BENCH_DIR, load_bench, resolve_bench
from wearbench.bench.schema import Bench
from wearbench.cli.options import add_force_argument
from wearbench.cli.progress import console as table_console


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "bench",
        help="list, check or show bench definition files",
        description="Bench files (TOML) describe a test bed: mechanism, clearance joints, drivers, "
        "sensors and hardware backend. 'check' validates every key, that the mechanism assembles, that "
        "its cranks turn full revolutions (a kinematic sweep, seconds), that the accelerometer's range is "
        "above what the motion alone gives it, and the [emulator] table.",
    )
    verbs = p.add_subparsers(dest="verb", metavar="VERB", required=True)
    verbs.add_parser("list", help="list the bench files shipped with wearbench").set_defaults(func=_list)
    c = verbs.add_parser("check", help="validate bench files: keys, assembly, full crank turns, sensor range, "
                         "[emulator]")
    c.add_argument("files", nargs="+", metavar="BENCH.toml")
    c.set_defaults(func=_check)
    s = verbs.add_parser("show", help="print bodies, joints, clearances, drivers and sensors")
    s.add_argument("file", metavar="BENCH.toml")
    s.set_defaults(func=_show)
    cp = verbs.add_parser("copy", help="copy a bench file and the files it names (worn surfaces) to start yours",
                          description="Copy BENCH (a file or a shipped bench's name) to DEST.toml and every file "
                          "it names by a relative path (worn surfaces) to the same place beside DEST, so the "
                          "copy loads and records as the original does.")
    cp.add_argument("file", metavar="BENCH")
    cp.add_argument("dest", metavar="DEST.toml")
    add_force_argument(cp)
    cp.set_defaults(func=_copy)


def _list(args: argparse.Namespace) -> int:
    for path in sorted(BENCH_DIR.glob("*.toml")):
        bench = load_bench(path)
        print(f"{path}  {bench.description}")
    return 0


def _check(args: argparse.Namespace) -> int:
    from wearbench.cli.bench_checks import check_bench
    from wearbench.model import build_scene  # the model owns the kinematics of assembly

    for file in args.files:
        bench = load_bench(resolve_bench(file))
        scene = build_scene(bench)
        notes = check_bench(bench)  # kinematic sweep, sensor range against the motion, [emulator]
        missing = [k for k in ("encoder", "accelerometer") if k not in {s.kind for s in bench.sensors}]
        if missing:
            notes.append(f"simulate only, cannot record: no {' or '.join(missing)} sensor")
        print(f"{file}: ok ({bench.name}: {len(bench.bodies)} bodies, {len(bench.joints)} joints, "
              f"{scene.dof} degrees of freedom with the drivers applied: {scene.description}; {'; '.join(notes)})")
    return 0


def _copy(args: argparse.Namespace) -> int:
    from wearbench.acquisition.layout import bench_files
    from wearbench.bench.output_file import check_output, output_file

    bench = load_bench(resolve_bench(args.file))
    dest = Path(args.dest)
    files = {dest.parent / relative: source for relative, source in bench_files(bench).items()}
    for target in (dest, *files):  # everything refused before anything is written
        check_output(target, force=args.force, option="DEST")
    for target, source in [(dest, Path(bench.path)), *files.items()]:
        with output_file(target, force=args.force, option="DEST") as tmp:
            shutil.copyfile(source, tmp)
    load_bench(dest)
    print(f"{dest}: a copy of {bench.name}" + (f" and {len(files)} files it names" if files else ""))
    return 0


def _show(args: argparse.Namespace) -> int:
    bench: Bench = load_bench(resolve_bench(args.file))
    console = table_console()
    console.print(f"[bold]{bench.name}[/bold]: {bench.description}")
    console.print(f"motor speed {bench.speed:.4g} rad/s ({bench.speed * 30 / math.pi:.4g} rpm), "
                  f"backend {bench.hardware.backend}")
    bodies = Table(*map(escape, ("body", "mass [kg]", "inertia [kg m^2]", "length [mm]", "points")))
    for b in bench.bodies:
        bodies.add_row(b.name, f"{b.mass:.4g}", f"{b.inertia:.4g}",
                       "" if b.length is None else f"{b.length * 1e3:.4g}", ", ".join(b.points))
    console.print(bodies)
    joints = Table(*map(escape, ("joint", "type", "bodies", "clearance [mm]", "bearing / journal radius [mm]")))
    for j in bench.joints:
        c = j.clearance
        joints.add_row(j.name, j.kind, " - ".join(j.bodies),
                       "ideal" if c is None else f"{c.radial_clearance * 1e3:.4g}",
                       "" if c is None else f"{c.bearing_radius * 1e3:.4g} / {c.journal_radius * 1e3:.4g}")
    console.print(joints)
    for d in bench.drivers:
        console.print(f"driver {d.joint}: {d.ratio:+g} x motor speed, phase {math.degrees(d.phase):.4g} deg")
    for s in bench.sensors:
        console.print(f"sensor {s.name}: {s.kind} at {s.sample_rate:g} Hz")
        if s.chain is not None:
            from wearbench.validation.measurement.chain_delay import stated_delay

            console.print(f"  its chain, as stated: {escape(stated_delay(s.chain).describe())}")
    return 0
