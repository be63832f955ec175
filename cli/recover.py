"""`wearbench recover`: restore every complete chunk of an unfinished session MCAP into a new file."""

from __future__ import annotations

import argparse
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("recover", help="restore an unfinished session MCAP (e.g. after a killed process)",
                       description="Copy every complete record of a session file that was never "
                       "finished into a new, valid MCAP file, and say what was restored.")
    p.add_argument("broken", help="the unfinished MCAP file")
    p.add_argument("--out", "-o", required=True, help="the MCAP file to write (never replaced unless --force)")
    p.add_argument("--force", action="store_true",
                   help="replace an existing --out file (only once the recovered file is complete)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from wearbench.acquisition.recover import recover

    if not Path(args.broken).is_file():
        raise OSError(f"{args.broken}: no such file")
    r = recover(args.broken, args.out, force=args.force)
    state = "was finished" if r.was_finished else f"was not finished ({r.problem})"
    print(f"{r.out}: restored {r.messages} messages from {r.chunks} complete chunks of {r.source} "
          f"(the original {state})")
    return 0
