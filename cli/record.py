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
        "a full disk). On an emulated bench the labels are checked: the sim backend's emulator plays what "
        "--clearance/--wear say (its truth is set from them), a serial emulator, whose truth is set where it "
        "runs, refuses labels it does not play; the command says which.",
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
                   "as fast as the host can, config=EMULATOR.json replaces the bench's [emulator] table with "
                   "one JSON object of the same keys, values with units as strings, e.g. "
                   "{\"truth\": {\"state\": \"0.6 mm new\", \"seed\": 3}}: reference "
                   "hardware/emulators/config.py); repeatable")
    p.add_argument("--clearance", default="", help="mounted radial clearances, e.g. A=0.3mm,B=0.3mm; on the sim "
                   "backend's emulator they set its truth (it says so), a serial emulator refuses what it does "
                   "not play")
    p.add_argument("--wear", default="", help="wear state per joint, e.g. A=new,B=stage2.npz; on an emulated bench "
                   "as --clearance")
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
    from wearbench.acquisition.emulated_truth import check_labels
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
    worn: dict[str, Path | None] = {}  # the wear labels: a worn-surface file, None for new
    for joint, state in wear.items():  # what the analysis reads back: 'new' or a file (it travels in the session)
        from wearbench.model.surfaces import JointSurfaces
        from wearbench.validation.comparison.theory import UNWORN

        expected = "expected 'new' or a worn-surface .npz file (written by 'wearbench wear')"
        if state.lower() in UNWORN:
            worn[joint] = None
            continue
        if Path(state).suffix != ".npz":
            raise ValueError(f"--wear {joint}={state}: neither 'new' nor a worn-surface file; {expected}")
        try:
            JointSurfaces.load(state)
        except (OSError, ValueError) as exc:
            raise ValueError(f"--wear {joint}={state}: {exc}; {expected}") from None
        worn[joint] = Path(state)
    plan = SessionPlan(
        speed=speed, cycles=args.cycles,
        duration=positive_quantity(args.duration, "time", "--duration", bare_unit="s") if args.duration else None,
        clearances=clearances, wear=wear, operator=args.operator, cycles_run=cycles_run_value(args.cycles_run),
        settle=positive_quantity(args.settle, "time", "--settle", bare_unit="s", allow_zero=True))
    options = backend_options(args.option)
    backend = args.backend or bench.hardware.backend
    truth_note = None
    if backend == "sim":  # the emulator simulates the bench: refuse a bench it cannot turn before it starts
        from wearbench.cli.bench_checks import sweep_turns

        sweep_turns(bench)
        if clearances or worn:
            options["config"], truth_note = set_sim_truth(bench, {**bench.hardware.options.get("sim", {}), **options},
                                                          clearances, worn, from_command_line="config" in options)
    check_free_space(args.out)  # refuse before the rig starts
    live = None
    if args.live is not None:
        from wearbench.acquisition.live import LiveView, parse_address

        live = LiveView(*parse_address(args.live), name=f"wearbench {bench.name}")
        print(f"live view: {live.url} (Foxglove: Open connection, Foxglove WebSocket)", flush=True)
    try:
        # the sim emulator plays the truth set above; another backend's bench is what is wired to it
        rig = open_rig(bench.with_clearances(clearances) if clearances and backend != "sim" else bench, backend,
                       options)
        try:
            checked = check_labels(rig, bench, clearances, worn)  # sim: agrees with the truth just set
            truth_note = truth_note or checked
            _prepare_emulator(rig, plan.speed)
        except BaseException:
            rig.close()
            raise
    except BaseException:
        if live is not None:
            live.close()
        raise
    if truth_note:
        print(f"wearbench record: {truth_note}", flush=True)
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


def set_sim_truth(bench, options: dict, clearances: dict[str, float], worn: dict[str, Path | None], *,
                  from_command_line: bool = True) -> tuple[dict, str]:
    """The sim backend's emulator config with its truth set from the session's labels (``--clearance``
    radial clearances m, ``--wear`` worn-surface files or None for new, by joint), and the sentence
    saying what it plays. The emulator runs in this process, so the labels are the bench it plays: a
    joint not labelled keeps the truth's (its ``config`` option's, else the bench file's
    ``[emulator.truth]``), and so do its seed and delay."""
    import json
    from dataclasses import replace

    from wearbench.hardware.emulators.config import EmulatorConfig

    raw = options.get("config")
    if isinstance(raw, str):  # a JSON file replacing the bench's [emulator] table
        try:
            table = json.loads(Path(raw).read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise ValueError(f"--option config={raw}: expected a JSON file of the [emulator] table ({exc})") from None
        config = EmulatorConfig.from_table(table, bench=bench, source=raw)
        where = f"--option config={raw}" if from_command_line else f"[hardware.sim] config = {raw!r}"
    elif raw is not None:
        config, where = EmulatorConfig.from_table(raw, bench=bench), "the config option"
    else:
        config = EmulatorConfig.from_bench(bench)
        where = "its [emulator.truth]" if "truth" in bench.emulator else "the bench file (no [emulator.truth])"
    truth = config.truth.labelled(bench, clearances, worn)
    if truth is config.truth:
        return config.to_table(), (f"the sim emulator plays what --clearance/--wear say, as {where} already "
                                   f"had it: {truth.describe(bench)}")
    return replace(config, truth=truth).to_table(), (
        f"the sim emulator's truth set from --clearance/--wear: it plays {truth.describe(bench)} "
        f"(instead of {where}: {config.truth.describe(bench)})")


def _prepare_emulator(rig, speed: float) -> None:
    """The sim backend's in-process emulator computes its signal table now (compiling the model's
    kernels on a first run, a minute or two, said by the compile note), before the session: in it,
    the recorder takes Ctrl-C as a stop it checks between reads, and a Ctrl-C during the table was held
    until the table was done. Here the command's own Ctrl-C handling ends it at once. Other backends:
    nothing to do."""
    device = getattr(rig.drive, "device", None)
    if rig.backend == "sim" and device is not None:
        device.prepare(speed)


def cycles_run_value(text: str | None, option: str = "--cycles-run") -> float | None:
    """``--cycles-run``: a number of cycles >= 0 (``200000``, ``2e5``, ``200_000``), or None."""
    if text is None:
        return None
    try:
        value = float(text.replace("_", "").replace(",", ""))
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value >= 0):
        raise ValueError(f"{option} {text!r}: expected the cycles the bench had run before the session, "
                         "a finite number >= 0 (e.g. 200000)")
    return value
