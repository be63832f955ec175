"""`wearbench emulate BENCH.toml --serial`: run the bench emulator on a pseudo-terminal.

Prints the port path on the first line and serves until Ctrl-C/SIGTERM. The ``[emulator]`` table of
the bench file configures imperfections, truth and faults; ``--config FILE.json`` replaces it (one JSON
object of the table's keys); ``--state``, ``--seed`` and ``--twin`` set its truth (``emulator_config``),
whose marks its INFO name carries (``hardware/protocol/truth.py``) for a host to check its labels by.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("emulate", help="run an emulated bench device (serial protocol on a pty)",
                       description="Run the emulated bench device of BENCH.toml: the serial protocol on a new "
                       "pseudo-terminal. Prints the port path on the first line and serves until Ctrl-C. "
                       "The bench file's [emulator] table sets imperfections, hidden truth and faults. The truth "
                       "is set here: 'wearbench record --clearance/--wear' against this emulator is refused "
                       "where it disagrees with it (the device name carries marks of the truth, not the truth).")
    p.add_argument("bench", help="bench file (TOML), or the name of a shipped bench")
    p.add_argument("--serial", action="store_true", required=True,
                   help="serve the serial protocol on a new pseudo-terminal and print its path")
    p.add_argument("--config", type=Path, help="JSON file replacing the bench's [emulator] table: one object of "
                   "the same keys, values with units as strings, e.g. {\"truth\": {\"state\": \"0.6 mm new\", "
                   "\"seed\": 3}, \"accelerometer\": {\"noise\": \"0.1 m/s^2\"}} (reference: "
                   "hardware/emulators/config.py)")
    p.add_argument("--sent-log", type=Path, help="append every byte sent to the host to this file (never to a "
                   "recorded session)")
    p.add_argument("--state", help="the true state: a [[state]] name of the bench (default: the table's truth)")
    truth = p.add_mutually_exclusive_group()
    truth.add_argument("--seed", type=int, help="a truth drawn from the bench's [tolerances] with this seed "
                       "(not the model's twin: long run, cycle-to-cycle variation)")
    truth.add_argument("--twin", action="store_true", help="play the nominal model's own revolution looped "
                       "(every cycle identical), for comparison")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from wearbench.bench.load import load_bench, resolve_bench
    from wearbench.bench.output_file import check_output
    from wearbench.hardware.emulators.config import EmulatorConfig
    from wearbench.hardware.emulators.serial_server import serve

    if args.sent_log is not None:  # appended to (nothing in it is lost); bytes after a session's footer break it
        check_output(args.sent_log, force=True, option="--sent-log")
    bench = load_bench(resolve_bench(args.bench))
    if args.config is not None:
        try:
            table = json.loads(args.config.read_text(encoding="utf-8"))
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise ValueError(f"--config {args.config}: not JSON ({exc}); expected one JSON object of the "
                             "[emulator] table's keys") from None
        config = EmulatorConfig.from_table(table, bench=bench, source=args.config)
    else:
        config = EmulatorConfig.from_bench(bench)
    if args.state is not None or args.seed is not None or args.twin:
        from wearbench.hardware.emulators.config import emulator_config

        t = config.truth
        state = args.state if args.state is not None else (t.state() if t.clearances or t.wear else None)
        seed = None if args.twin else (args.seed if args.seed is not None else t.seed)
        config = emulator_config(bench, state, seed, table=config.to_table())

    def announce(path: str) -> None:
        print(path, flush=True)
        print(f"wearbench emulate: {bench.name} serial emulator on {path} (Ctrl-C to stop)",
              file=sys.stderr, flush=True)

    if args.sent_log is None:
        return serve(bench, config, announce=announce)
    with open(args.sent_log, "ab") as log:
        return serve(bench, config, announce=announce, sent_log=log)
