"""`wearbench calibrate`: fit a bench's sensor path from sessions of a state the lab knows.

Thin front of ``wearbench.validation.workflows.measure.calibrate_sessions``; stores the calibration where
``identify`` and ``estimate`` find it (``wearbench.validation.inference.calibration``).
"""

from __future__ import annotations

import argparse

from wearbench.cli.compute import (
    add_compute_arguments,
    add_size_arguments,
    compute_options,
    ensemble_size,
)
from wearbench.cli.options import add_force_argument


def add_calibration_arguments(p: argparse.ArgumentParser) -> None:
    """``--calibration`` and ``--mount`` of the commands that use a bench's sensor-path calibration."""
    p.add_argument("--calibration", default="auto", metavar="FILE|none",
                   help="sensor-path calibration ('wearbench calibrate'): default the stored one of the session's "
                   "bench, sensor and --mount, else the prior of an unmeasured mount; 'none' never uses one")
    p.add_argument("--mount", default="", help="mount label of the calibration to use (default none)")


def calibration_options(args: argparse.Namespace) -> dict:
    """{"calibration", "mount"} for the validation API from the parsed options."""
    return {"calibration": None if args.calibration == "none" else args.calibration, "mount": args.mount}


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "calibrate", help="fit the bench's sensor path (and keep its offsets) from sessions of a known state",
        description="Compare sessions recorded in a state the lab knows (right after assembly: new joints, known "
        "clearance) with that state's theory ensemble: fit the sensor path's low-frequency gain and "
        "impact-band gains with their uncertainty, and keep the sessions' mean cycle features, which hold the "
        "bench's own offsets (its tolerances, its whole sensor path, a mount mode inside an impact band "
        "included). The result is stored under a key of the bench, the accelerometer's recorded calibration "
        "and --mount; later 'identify' and 'estimate' of that bench use the fitted path instead of the "
        "unmeasured mount's prior and say so.")
    p.add_argument("sessions", nargs="+", metavar="SESSION.mcap", help="sessions of the bench in the known state")
    p.add_argument("--state", required=True, help="the known state: a [[state]] name of the bench (or --candidates)")
    p.add_argument("--candidates", metavar="STATES.toml", help="file of [[state]] tables (default: the bench's)")
    p.add_argument("--mount", default="", help="label of the sensor mount, when one bench has several (default none)")
    p.add_argument("--ensembles", metavar="FILE.npz", help="ensembles saved by 'wearbench ensemble' (no simulation)")
    p.add_argument("--dir", metavar="DIR", help="where calibrations live (default $WEARBENCH_CALIBRATIONS or "
                   "~/.local/share/wearbench/calibrations)")
    add_force_argument(p, "replace a stored calibration of this bench, sensor and mount, and store one the sessions "
                       "doubt (far from --state, or identified as another state)")
    add_size_arguments(p, design=False)
    add_compute_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from wearbench.validation.inference.calibration import (
        check_calibration_output,
        save_calibration,
    )
    from wearbench.validation.workflows.measure import calibrate_sessions

    cal = calibrate_sessions(args.sessions, args.state, candidates=args.candidates, ensembles=args.ensembles,
                             settings=ensemble_size(args, window=None), mount=args.mount,
                             before=lambda key: check_calibration_output(key, args.dir, force=args.force),
                             compute=compute_options(args), force=args.force)
    path = save_calibration(cal, args.dir, force=args.force)
    print(cal.describe())
    sd = cal.path.theta_cov.diagonal() ** 0.5
    print(f"uncertainty (1 sd): gain {sd[0]:.3f}, bands " + ", ".join(f"{10 * v:.1f} dB" for v in sd[1:]))
    print(f"bench offsets: the mean features of {cal.cycles} cycles are stored too")
    for doubt in cal.doubts:
        print(f"warning: {doubt} (stored with --force; the doubt is stored with it)")
    print(f"calibration: {path}")
    return 0
