"""`wearbench record`: run a bench session and write it to an MCAP file."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from wearbench.bench.schema import BACKENDS
from wearbench.cli.options import (
    cycle_count,
    joint_values,
    motor_speed,
    parse_clearances,
    positive_quantity,
)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "record", help="record a bench session (motor, encoder, accelerometer) to MCAP",
        description="Warm up to speed, record a number of crank cycles or a duration, ramp down, and "
        "write everything to an MCAP file that stays readable whatever happens (Ctrl-C, a lost device, "
        "a full disk).",
        epilog="example: wearbench record ninebar-testbed.toml --speed 2pi --cycles 20 --out s.mcap "
        "--clearance A=0.3mm,B=0.3mm --wear A=new,B=new --operator ana")
    p.add_argument("bench", help="bench file (TOML), or the name of a shipped bench")
    p.add_argument("--out", "-o", required=True, help="MCAP file to write (never replaced unless --force)")
    p.add_argument("--force", action="store_true",
                   help="replace an existing --out session; the old file is kept until the new session has "
                   "recorded its --cycles or --duration (written as OUT.new, renamed at the end) and kept "
                   "as it was when the new one stops early (Ctrl-C, a fault, a full disk)")
    p.add_argument("--speed", help="motor speed, e.g. 2pi (rad/s), 60rpm, 1Hz (default: the bench's)")
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument("--cycles", type=cycle_count,
                      help="complete crank cycles (index to index) to record")
    what.add_argument("--duration", help="time to record, e.g. 30s, 2min")
    p.add_argument("--backend", choices=BACKENDS,
                   help="hardware backend (default: the bench file's [hardware] backend)")
    p.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                   help="backend option overriding the bench file's [hardware.<backend>] table "
                   "(e.g. port=/dev/ttyACM0, interface=socketcan, channel=can0; sim: speedup=inf runs "
                   "as fast as the host can, config=EMULATOR.json); repeatable")
    p.add_argument("--clearance", default="", help="mounted radial clearances, e.g. A=0.3mm,B=0.3mm")
    p.add_argument("--wear", default="", help="wear state per joint, e.g. A=new,B=stage2.npz")
    p.add_argument("--operator", default="", help="who ran the session")
    p.add_argument("--cycles-run", metavar="N", help="cycles the bench had run before this session (e.g. 200000), "
                   "stored in the session; 'wearbench track' reads it")
    p.add_argument("--settle", default="0.5s", help="time held at speed before recording (default 0.5s)")
    p.add_argument("--live", nargs="?", const="127.0.0.1:8765", metavar="HOST:PORT",
                   help="serve the session while it records over the Foxglove WebSocket protocol "
                   "(open it in Foxglove: Open connection, Foxglove WebSocket; default 127.0.0.1:8765); "
                   "a slow or lost viewer never costs the recording a sample")
    p.set_defaults(func=run)


def _option_value(text: str):
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            pass
    return {"true": True, "false": False}.get(text.lower(), text)


def backend_options(items: list[str]) -> dict:
    """``--option KEY=VALUE`` items as the backend's options (numbers and true/false converted)."""
    options = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep:
            raise ValueError(f"--option {item!r}: expected KEY=VALUE")
        options[key.strip()] = _option_value(value.strip())
    return options


def run(args: argparse.Namespace) -> int:
    from wearbench.acquisition.backends import open_rig
    from wearbench.acquisition.recorder import Recorder
    from wearbench.acquisition.session import SessionPlan
    from wearbench.acquisition.session_writer import (
        SessionWriter,
        check_free_space,
        leftover_message,
        lock_session_path,
        unlock_session_path,
    )
    from wearbench.bench.load import load_bench, resolve_bench
    from wearbench.bench.output_file import check_output
    from wearbench.cli.progress import progress

    bench = load_bench(resolve_bench(args.bench))
    out = check_output(args.out, force=args.force, session=True)
    leftover = out.with_name(out.name + ".new")
    if args.force and out.exists() and leftover.exists():
        unlock_session_path(out, lock_session_path(out))  # EBUSY if a recorder is writing it now
        raise FileExistsError(leftover_message(leftover))
    missing = [k for k in ("encoder", "accelerometer") if k not in {s.kind for s in bench.sensors}]
    if missing:
        raise ValueError(f"{bench.path or bench.name}: no [[sensor]] of kind {' or '.join(missing)}; a session "
                         "records an encoder (to count crank cycles) and an accelerometer (see "
                         "'wearbench bench show ninebar-testbed')")
    speed = (motor_speed(args.speed, max_speed=bench.motor.max_speed, source=str(bench.path or bench.name))
             if args.speed else bench.speed)
    clearances = parse_clearances(args.clearance, bench)
    wear = joint_values(args.wear, "--wear", [j.name for j in bench.clearance_joints])
    for joint, state in wear.items():  # what the analysis reads back: 'new' or a file (it travels in the session)
        from wearbench.model.surfaces import JointSurfaces
        from wearbench.validation.theory import UNWORN

        expected = "expected 'new' or a worn-surface .npz file (written by 'wearbench wear')"
        if state.lower() in UNWORN:
            continue
        if Path(state).suffix != ".npz":
            raise ValueError(f"--wear {joint}={state}: neither 'new' nor a worn-surface file; {expected}")
        try:
            JointSurfaces.load(state)
        except (OSError, ValueError) as exc:
            raise ValueError(f"--wear {joint}={state}: {exc}; {expected}") from None
    plan = SessionPlan(
        speed=speed, cycles=args.cycles,
        duration=positive_quantity(args.duration, "time", "--duration", bare_unit="s") if args.duration else None,
        clearances=clearances, wear=wear, operator=args.operator, cycles_run=cycles_run_value(args.cycles_run),
        settle=positive_quantity(args.settle, "time", "--settle", bare_unit="s", allow_zero=True))
    options = backend_options(args.option)
    check_free_space(args.out)  # refuse before the rig starts
    live = None
    if args.live is not None:
        from wearbench.acquisition.live import LiveView, parse_address

        live = LiveView(*parse_address(args.live), name=f"wearbench {bench.name}")
        print(f"live view: {live.url} (Foxglove: Open connection, Foxglove WebSocket)", flush=True)
    try:
        rig = open_rig(bench.with_clearances(clearances) if clearances else bench, args.backend, options)
        try:
            _prepare_emulator(rig, plan.speed)
        except BaseException:
            rig.close()
            raise
    except BaseException:
        if live is not None:
            live.close()
        raise
    unit = "cycles" if plan.cycles is not None else "s"
    with progress() as bar:
        task = bar.add_task(f"record {bench.name}", total=plan.cycles or plan.duration, info="")

        def show(p) -> None:
            done = p.cycles if plan.cycles is not None else p.elapsed
            bar.update(task, completed=min(done, p.target), description=f"{p.phase:9s}",
                       info=f"{done:.1f} {unit}  {p.sample_rate / 1e3:.1f} kS/s  dropped {p.dropped}")

        try:
            writer = SessionWriter(args.out, live=live, replace=args.force)
            result = Recorder(rig, bench, plan, args.out, on_progress=show, writer=writer).run()
        finally:
            rig.close()
            if live is not None:
                live.close()
        done = result.cycles if plan.cycles is not None else result.duration
        bar.update(task, completed=min(done, plan.cycles or plan.duration), description="done     ")
    drops = sum(result.dropped_samples.values())
    repeats = sum(result.repeated_blocks.values())
    if result.path is not None and result.path != out:
        print(f"wearbench record: {out} kept as it was: the new session did not complete "
              f"({result.reason}); it is in {result.path}", file=sys.stderr)
    print(f"{result.path or args.out}: {result.reason}; {result.cycles:.2f} cycles in {result.duration:.2f} s, "
          f"{result.samples.get('acceleration', 0)} acceleration samples, "
          f"{result.samples.get('encoder', 0)} encoder samples, dropped {drops} samples, "
          f"repeated {repeats} blocks, {result.malformed} malformed frames, "
          f"{result.clipped} clipped acceleration samples")
    if live is not None:
        print(f"live view: {live.published} messages published, {live.dropped} not offered to viewers "
              "(queue full)")
    if not result.completed:
        print(f"wearbench record: session stopped early: {result.reason} (the file is complete up to "
              "that point)", file=sys.stderr)
        return 130 if result.reason.startswith("interrupted") else 1
    return 0


def _prepare_emulator(rig, speed: float) -> None:
    """The sim backend's in-process emulator computes its signal table now (compiling the model's
    kernels on a first run, a minute or two, said by the compile note), before the session: in it,
    the recorder takes Ctrl-C as a stop it checks between reads, and a Ctrl-C during the table was held
    until the table was done. Here the command's own Ctrl-C handling ends it at once. Other backends:
    nothing to do."""
    device = getattr(rig.drive, "device", None)
    if rig.backend == "sim" and device is not None:
        device.prepare(speed)


def cycles_run_value(text: str | None) -> float | None:
    """``--cycles-run``: a whole number of cycles >= 0 (``200000``, ``2e5``, ``200_000``), or None."""
    if text is None:
        return None
    try:
        value = float(text.replace("_", "").replace(",", ""))
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value >= 0):
        raise ValueError(f"--cycles-run {text!r}: expected the cycles the bench had run before this session, "
                         "a number >= 0 (e.g. 200000)")
    return value
