"""`wearbench inspect`: summarise a session MCAP (channels, rates, duration, gaps, drops, metadata)."""

from __future__ import annotations

import argparse
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("inspect", help="summarise a recorded session MCAP file",
                       description="Print the channels, sample rates, duration, time gaps, dropped and "
                       "repeated blocks, events and metadata of a session file (finished or not).")
    p.add_argument("session", help="session MCAP file")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from wearbench.acquisition.summary import format_summary, summarize

    path = Path(args.session)
    if not path.is_file():
        raise OSError(f"{path}: no such file")
    print(format_summary(summarize(path)))
    return 0
