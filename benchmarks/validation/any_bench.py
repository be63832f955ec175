"""Does identification name the states of any bench at any speed? Emulated non-twin sessions of each
case (a bench at a crank speed) identified against ensembles of the analysis resolved for it.

Per case: ``--seeds`` truths per candidate state (a bench drawn from the bench file's tolerances with a
seed the theory does not use, through the emulator's sensor chain: ``synthetic.truths.record_state``,
``--cycles`` cycles each), ensembles of ``--realisations`` x ``--ensemble-cycles`` per state
(``EnsembleSettings.for_bench``, in this process), identified by the same workflow as ``wearbench
identify`` (``assess_sessions``, no calibration). Reported: the resolved analysis, the top-1 rate, the
named rate, the verdicts, the mean posterior of the truth, and the notes the sessions got.

The default cases: the shipped slider-crank at its own 5000 rpm and at 120 rpm, the same bench at 120
rpm with a 500 g accelerometer (its own 50,000 g sensor records in 15 m/s^2 steps), the shipped
four-bar at 1 Hz and a lab's four-bar at 1.5 Hz (``tests/data/lab-fourbar.toml``). The test bed is
not a case: its analysis at 1 Hz is the one it had (tests/validation/measurement/test_scaling.py).

    python -m benchmarks.validation.any_bench [--seeds 501,...] [--realisations 16] [--json PATH]
"""

from __future__ import annotations

import argparse
import collections
import math
import tempfile
import time
from pathlib import Path

from wearbench.bench.load import load_bench, parse_bench, resolve_bench
from wearbench.compute.options import Compute
from wearbench.synthetic.truths import record_state, slug
from wearbench.validation.inference.ensemble import EnsembleSize
from wearbench.validation.measurement.scaling import hertz, resolve_analysis
from wearbench.validation.workflows.assess import assess_sessions

from benchmarks.result_json import Run, column, table, write_result

ROOT = Path(__file__).resolve().parents[2]
RPM = 2 * math.pi / 60


def fine_sensor(bench):
    """The bench with a 500 g accelerometer at 10 mV/g (and its name marked) instead of its own."""
    text = bench.source.replace(f'name = "{bench.name}"', f'name = "{bench.name}-500g"', 1)
    text = text.replace('range = "50000 g"', 'range = "500 g"', 1).replace('"0.1 mV/g"', '"10 mV/g"', 1)
    return parse_bench(text, bench.path)


CASES = {
    "slider-crank 5000 rpm": lambda: load_bench(resolve_bench("slider-crank")),
    "slider-crank 120 rpm": lambda: load_bench(resolve_bench("slider-crank")).with_speed(120 * RPM),
    "slider-crank 120 rpm with a 500 g sensor": lambda: fine_sensor(load_bench(resolve_bench("slider-crank"))).with_speed(
        120 * RPM),
    "fourbar 1 Hz": lambda: load_bench(resolve_bench("fourbar")),
    "lab four-bar 1.5 Hz": lambda: load_bench(ROOT / "tests" / "data" / "lab-fourbar.toml"),
}


def note_kind(note: str) -> str:
    """A session's note by what it says (the sessions' own numbers left out)."""
    if "resolution" in note:
        return "the accelerometer's range too coarse for the motion (its resolution note)"
    if note.startswith("departs from"):
        return "departs from its nearest candidate (the consistency note)"
    return note.split(":")[0]


def run_case(name: str, bench, seeds: list[int], size: EnsembleSize, cycles: int, folder: Path) -> dict:
    paths, truths = [], []
    for state in bench.states:
        for seed in seeds:
            path = folder / f"{slug(name)}_{slug(state.name)}_{seed}.mcap"
            record_state(bench, state, seed, path, backend="sim", cycles=cycles)
            paths.append(path)
            truths.append(state.name)
    a = resolve_analysis(bench)
    cpu = time.process_time()
    assessed = assess_sessions(paths, settings=size, compute=Compute(workers=0, progress=False), calibration=None)
    cpu = time.process_time() - cpu
    rows = [(t, x.identification) for t, x in zip(truths, assessed, strict=True)]
    notes = collections.Counter(note_kind(n) for _, r in rows for n in set(map(note_kind, r.notes)))
    return {"case": name, "rpm": a.crank_hz * 60, "bands": ", ".join(f"{hertz(lo)}-{hertz(hi)}" for lo, hi in
                                                                      a.features.bands),
            "curve": hertz(a.features.lowpass), "sessions": len(rows),
            "top1": sum(max(r.posterior, key=r.posterior.get) == t for t, r in rows) / len(rows),
            "named": sum(r.verdict == t for t, r in rows) / len(rows),
            "none": sum(r.verdict == "none of the candidates" for _, r in rows),
            "undecided": sum(r.verdict == "undecided" for _, r in rows),
            "p_truth": sum(r.posterior[t] for t, r in rows) / len(rows),
            "held_out": rows[0][1].held_out, "cpu": cpu, "notes": notes}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", default=",".join(CASES), help="comma-separated cases (default: all)")
    ap.add_argument("--seeds", default="501,502,503,504,505,506", help="truth seeds per state")
    ap.add_argument("--realisations", type=int, default=16, help="realisations per state (16)")
    ap.add_argument("--ensemble-cycles", type=int, default=8, help="settled cycles per realisation (8)")
    ap.add_argument("--cycles", type=int, default=20, help="cycles per session (20)")
    ap.add_argument("--json", metavar="PATH", help="also write the result as JSON (docs/results/data/ for the docs)")
    args = ap.parse_args()
    run = Run()
    seeds = [int(s) for s in args.seeds.split(",")]
    size = EnsembleSize(args.realisations, args.ensemble_cycles)
    out = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.cases.split(","):
            r = run_case(name, CASES[name](), seeds, size, args.cycles, Path(tmp))
            out.append(r)
            print(f"{name}: top-1 {r['top1']:.2f}, named {r['named']:.2f} ({r['none']} none, {r['undecided']} "
                  f"undecided) of {r['sessions']}; mean p(truth) {r['p_truth']:.3f}; bands {r['bands']}", flush=True)
    if args.json:
        cols = [column("case"), column("crank", "rpm", ".0f"), column("curve low-pass"), column("impact bands"),
                column("sessions"), column("top-1", None, ".2f"), column("named", None, ".2f"),
                column("none of the candidates"), column("undecided"), column("mean p(truth)", None, ".3f"),
                column("held-out top-1", None, ".2f", "the ensembles' own realisations, held out"),
                column("identification CPU", "s", ".0f")]
        rows = [[r["case"], r["rpm"], r["curve"], r["bands"], r["sessions"], r["top1"], r["named"], r["none"],
                 r["undecided"], r["p_truth"], r["held_out"], r["cpu"]] for r in out]
        findings = [f"{r['case']}: the top state is the truth in {r['top1']:.0%} of {r['sessions']} sessions, named "
                    f"at p >= 0.9 and consistent in {r['named']:.0%}." for r in out]
        notes = [f"{r['case']}: " + ("; ".join(f"{k}: {n} of {r['sessions']} sessions" for k, n in r["notes"].items())
                                     or "no session got a note") for r in out]
        write_result(args.json, question="Does identification name the states of any bench at any speed?",
                     script=__file__, run=run, findings=findings, notes=notes,
                     seeds={"truths": seeds, "realisations": f"1..{args.realisations} per state"},
                     tables=[table(f"emulated non-twin sessions, {args.realisations} realisations x "
                                   f"{args.ensemble_cycles} cycles per state, {args.cycles}-cycle sessions", cols,
                                   rows)])
        print(f"results: {args.json}")


if __name__ == "__main__":
    main()
