"""`wearbench taptest`: measure the accelerometer's latency behind the encoder with taps at rest."""

from __future__ import annotations

import argparse
import json
import sys

from wearbench.bench.schema import BACKENDS
from wearbench.cli.options import positive_quantity
from wearbench.cli.record import backend_options


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "taptest", help="measure the accelerometer's latency behind the encoder (tap test)",
        description="With the cranks at rest, a tapper strikes the slider TAPS times; the drive latches each "
        "trigger on the encoder's clock (touch probe) and the session (a normal MCAP file) records the "
        "accelerometer's response. Each tap's response is fitted against the response the bench's "
        "[sensor.chain] statement predicts (its filters, 1-100 Hz, least squares in gain and shift); what "
        "the statement leaves out, less its clock drift, is the latency. Prints it per tap, the median "
        "with its interval, and the [sensor.chain] line to enter. --session analyses a recorded tap session.",
        epilog="example: wearbench taptest mybench.toml --out taps.mcap --taps 10; "
        "wearbench taptest mybench.toml --session taps.mcap --write-latency")
    p.add_argument("bench", help="bench file (TOML), or the name of a shipped bench")
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument("--out", "-o", help="record a tap session to this MCAP file (never replaced unless --force)")
    what.add_argument("--session", help="analyse this recorded tap session instead of recording one")
    p.add_argument("--force", action="store_true", help="replace an existing --out session or --json file")
    p.add_argument("--taps", type=int, default=10, help="taps to record (default 10)")
    p.add_argument("--interval", default="0.5s", help="time between taps (default 0.5s)")
    p.add_argument("--width", default="0.2ms", help="the tap's half-sine pulse width (default 0.2ms)")
    p.add_argument("--peak", help="the tap's peak acceleration, e.g. 100g (default: a quarter of the range)")
    p.add_argument("--backend", choices=BACKENDS, help="hardware backend (default: the bench file's)")
    p.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                   help="backend option, as for 'wearbench record' (sim: speedup=inf); repeatable")
    p.add_argument("--write-latency", action="store_true",
                   help="write the measured latency into BENCH's accelerometer [sensor.chain] (only that key "
                   "changes, comments are kept; a shipped bench is never changed)")
    p.add_argument("--json", metavar="FILE", help="also write every number to FILE (JSON; never replaced unless --force)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from wearbench.bench.load import BENCH_DIR, load_bench, resolve_bench
    from wearbench.bench.output_file import check_output
    from wearbench.validation.measurement.tap_test import tap_test

    path = resolve_bench(args.bench)
    bench = load_bench(path)
    if args.write_latency and path.resolve().parent == BENCH_DIR.resolve():
        raise ValueError(f"--write-latency: {args.bench} is a shipped bench, never changed; copy it first "
                         f"('wearbench bench copy {path.stem} mybench.toml') and give the copy")
    if args.json:
        check_output(args.json, force=args.force, option="--json")
    session = args.session
    if session is None:
        session = _record(bench, args)
    result = tap_test(session, bench)
    print(f"{'tap':>4s} {'latch s':>9s} {'shift ms':>9s} {'drift ms':>9s} {'latency ms':>11s} {'gain':>6s} "
          f"{'snr':>7s} {'match':>7s}")
    for t in result.taps:
        print(f"{t.number:4d} {t.latch:9.4f} {t.shift * 1e3:9.4f} {t.drift * 1e3:9.4f} {t.latency * 1e3:11.4f} "
              f"{t.gain:6.3f} {t.snr:7.0f} {t.match:7.4f}")
    print(f"{bench.name}: {result.describe()}")
    print(f"enter under the accelerometer's [sensor.chain]:  {result.line()}")
    if result.coverage < 0.95:
        print(f"wearbench taptest: {len(result.taps)} taps give only a {result.coverage:.0%} interval for the median; "
              "6 or more give 95 %", file=sys.stderr)
    if args.json:
        from wearbench.bench.output_file import output_file

        with output_file(args.json, force=args.force, option="--json") as tmp, open(tmp, "w", encoding="utf-8") as f:
            json.dump(result.to_dict(), f, indent=1)
    if args.write_latency:
        from wearbench.bench.chain_latency import set_chain_latency

        set_chain_latency(path, result.latency * 1e3)
        print(f"{path}: [sensor.chain] {result.line()} written (nothing else changed)")
    return 0


def _record(bench, args: argparse.Namespace) -> str:
    from wearbench.acquisition.backends import open_rig
    from wearbench.acquisition.recorder import Recorder
    from wearbench.acquisition.session import SessionPlan
    from wearbench.acquisition.session_writer import SessionWriter
    from wearbench.bench.output_file import check_output
    from wearbench.bench.units import parse_quantity

    check_output(args.out, force=args.force, session=True)
    if args.taps < 1:
        raise ValueError(f"--taps {args.taps}: expected a whole number >= 1")
    plan = SessionPlan(0.0, taps=args.taps,
                       tap_interval=positive_quantity(args.interval, "time", "--interval", bare_unit="s"),
                       tap_width=positive_quantity(args.width, "time", "--width", bare_unit="s"),
                       tap_peak=parse_quantity(args.peak, "acceleration") if args.peak else None)
    rig = open_rig(bench, args.backend, backend_options(args.option))
    try:
        result = Recorder(rig, bench, plan, args.out, writer=SessionWriter(args.out, replace=args.force)).run()
    finally:
        rig.close()
    print(f"{result.path or args.out}: {result.reason}; {args.taps} taps in {result.duration:.2f} s", flush=True)
    if not result.completed:
        print(f"wearbench taptest: the tap session stopped early: {result.reason}", file=sys.stderr)
    return str(result.path or args.out)
