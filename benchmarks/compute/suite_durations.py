"""Where does the test suite's time go? Runs pytest on the suite (as CI does) and tabulates its wall
time, the time by test folder and the slowest tests, from pytest's JUnit XML (``--junitxml``: per
test, its setup, call and teardown together, and the CPU ``tests/conftest.py`` records as the
property ``cpu``: what a test computes, where its time minus its CPU is waiting). ``--schedule``
also writes each test file's time to ``tests/durations.json``, the order in which
``tests/conftest.py`` hands files to the workers (heaviest first). ``--simulations`` also logs every
simulation the run makes, in every process (``simulation_log/sitecustomize.py``), and tabulates their
CPU by what asked for them: theory ensembles, estimator wear runs, the emulator's truth tables, ...

The run's wall time depends on the machine and what else runs on it: the result names both (its
``environment``). ``--pytest-args`` passes options through, e.g. ``-m "not slow"`` for the developer
loop, and ``--question`` names that run on its results page.

    python -m benchmarks.compute.suite_durations [--pytest-args ARGS] [--question TEXT] [--top 25] [--json PATH]
        [--schedule] [--simulations]
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import resource
import shlex
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from pathlib import Path

from benchmarks.result_json import ROOT, Run, column, table, write_result

SCHEDULE = ROOT / "tests" / "durations.json"
QUESTION = "Where does the test suite's time go?"
SIMULATION_LOG = Path(__file__).with_name("simulation_log")  # a sitecustomize for every process of the run
# the module that asked for a simulation -> what it is, first match (the caller is the nearest frame
# outside the model: a library module, a test, or a library the call came through)
ASKED_BY = (("validation/inference/ensemble", "theory ensembles (identify, estimator realisations)"),
            ("validation/estimation", "estimator wear runs"),
            ("hardware/emulators", "the emulator's truth tables (recording)"),
            ("studies/", "studies and sweeps"),
            ("synthetic/", "synthetic lives and truths"),
            ("compute/", "cost estimates and worker warm-up"),
            ("tests/", "tests' own simulations"))


def read_junit(path: Path) -> list[tuple[str, str, float, float]]:
    """Each test case of a JUnit XML file: (file, test id, seconds, CPU seconds), skipped cases included."""
    out = []
    for case in ET.parse(path).getroot().iter("testcase"):
        module = case.get("classname", "")
        parts = module.split(".")
        # the classname is the module path (and a class); its file is the longest prefix under tests/
        file = next((p for k in range(len(parts), 0, -1)
                     if (ROOT / (p := "/".join(parts[:k]) + ".py")).is_file()), module)
        cpu = next((float(p.get("value")) for p in case.iter("property") if p.get("name") == "cpu"), 0.0)
        out.append((file, f"{file}::{case.get('name', '')}", float(case.get("time", 0.0)), cpu))
    return out


def simulation_table(log: Path, tests_cpu: float) -> tuple[list[list], float]:
    """The logged simulations' CPU by what asked for them (the outermost logged call of each: a truth
    table's own run is the table's), as rows (what, calls, CPU s, share of the tests' CPU), and their total."""
    calls: dict[str, list[float]] = collections.defaultdict(list)
    lines = log.read_text(encoding="utf-8").splitlines() if log.exists() else []
    for record in map(json.loads, lines):
        if record["depth"] == 0:
            what = next((label for where, label in ASKED_BY if where in record["caller"]), "other")
            calls[what].append(record["cpu"])
    rows = sorted(([w, len(c), sum(c), sum(c) / tests_cpu if tests_cpu else 0.0] for w, c in calls.items()),
                  key=lambda r: -r[2])
    return rows, sum(r[2] for r in rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pytest-args", default="", help="options passed to pytest (quoted), e.g. '-m \"not slow\"'")
    ap.add_argument("--question", default=QUESTION, help=f"the results page's title ({QUESTION!r})")
    ap.add_argument("--top", type=int, default=25, help="slowest tests listed (25)")
    ap.add_argument("--json", metavar="PATH", help="also write the result (docs/results/data/ for the docs)")
    ap.add_argument("--schedule", action="store_true",
                    help=f"also write each test file's seconds to {SCHEDULE.relative_to(ROOT)} (the workers' order)")
    ap.add_argument("--simulations", action="store_true",
                    help="also log every simulation of the run and tabulate its CPU by what asked for it")
    args = ap.parse_args()
    run = Run()
    with tempfile.TemporaryDirectory() as tmp:
        junit, log = Path(tmp) / "junit.xml", Path(tmp) / "simulations.jsonl"
        cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", f"--junitxml={junit}",
               *shlex.split(args.pytest_args)]
        env = dict(os.environ)
        if args.simulations:
            path = os.pathsep.join(filter(None, [str(SIMULATION_LOG), env.get("PYTHONPATH")]))
            env.update(PYTHONPATH=path, PYTEST_PLUGINS="sitecustomize", WEARBENCH_SIMULATION_LOG=str(log))
        t0, c0 = time.monotonic(), resource.getrusage(resource.RUSAGE_CHILDREN)
        done = subprocess.run(cmd, cwd=ROOT, env=env, check=False)
        wall, c1 = time.monotonic() - t0, resource.getrusage(resource.RUSAGE_CHILDREN)
        # pytest, its workers and every process they started and waited for (commands, clusters)
        cpu = (c1.ru_utime - c0.ru_utime) + (c1.ru_stime - c0.ru_stime)
        if not junit.exists():
            raise SystemExit(f"pytest wrote no JUnit XML (exit {done.returncode})")
        cases = read_junit(junit)
        total_cpu = sum(c[3] for c in cases)
        simulations, simulated = simulation_table(log, total_cpu) if args.simulations else ([], 0.0)
    by_folder: dict[str, list[tuple[float, float]]] = collections.defaultdict(list)
    by_file: dict[str, float] = collections.defaultdict(float)
    for file, _, s, c in cases:
        by_folder[str(Path(file).parent)].append((s, c))
        by_file[file] += s
    folders = sorted(by_folder.items(), key=lambda kv: -sum(s for s, _ in kv[1]))
    slowest = sorted(cases, key=lambda c: -c[2])[:args.top]
    total = sum(c[2] for c in cases)
    top_share = sum(c[2] for c in slowest) / total if total else 0.0
    cores = os.cpu_count() or 1
    floor = (f"the run used {cpu / 60:.1f} min of CPU (user and system, every process it waited for): on "
             f"{cores} cores no order of these tests takes less than {cpu / cores / 60:.1f} min of wall time")
    tests_cpu = (f"the tests computed for {total_cpu / 60:.1f} min of their summed {total / 60:.1f} min (the rest "
                 "is waiting: on devices, clocks, and processes a test killed or a cluster's workers)")
    print(f"pytest exit {done.returncode}: {len(cases)} tests, wall {wall:.0f} s; the {len(slowest)} slowest hold "
          f"{top_share:.0%} of the summed test time; {tests_cpu}; {floor}")
    for _, name, s, c in slowest:
        print(f"{s:8.1f} s  {c:8.1f} s CPU  {name}")
    simulated_line = (f"simulations took {simulated / 60:.1f} min of the tests' {total_cpu / 60:.1f} min of CPU "
                      f"({simulated / total_cpu if total_cpu else 0:.0%}; each in its own thread, outermost calls only)")
    if args.simulations:
        print(simulated_line)
        for what, n, c, share in simulations:
            print(f"{c:8.1f} s CPU  {share:4.0%}  {n:5d} calls  {what}")
    if args.json:
        label = args.pytest_args or "the whole suite"
        write_result(args.json, question=args.question, script=__file__, run=run, seeds={},
                     findings=[(f"pytest {label}: {len(cases)} tests in {wall / 60:.1f} min of wall time "
                               f"(exit {done.returncode}); the {len(slowest)} slowest tests hold {top_share:.0%} "
                               "of the summed test time."), tests_cpu[0].upper() + tests_cpu[1:] + ".",
                               floor[0].upper() + floor[1:] + "."],
                     tables=[table("by test folder", [column("folder"), column("tests"), column("time", "s", ".0f"),
                                                      column("CPU", "s", ".0f"), column("share", None, ".0%")],
                                   [[f, len(v), sum(s for s, _ in v), sum(c for _, c in v),
                                     sum(s for s, _ in v) / total] for f, v in folders]),
                             table(f"the {len(slowest)} slowest tests (setup, call and teardown)",
                                   [column("test"), column("time", "s", ".1f"), column("CPU", "s", ".1f")],
                                   [[n, s, c] for _, n, s, c in slowest])]
                     + ([table("simulations by what asked for them (CPU of the calling thread)",
                               [column("asked by"), column("calls"), column("CPU", "s", ".0f"),
                                column("share of the tests' CPU", None, ".0%")], simulations)]
                        if args.simulations else []),
                     notes=["One run on the machine named below; wall times on a busy machine are longer."]
                     + ([simulated_line[0].upper() + simulated_line[1:] + "."] if args.simulations else []))
        print(f"results: {args.json}")
    if args.schedule:  # after the result, which records whether the checkout was clean
        SCHEDULE.write_text(json.dumps({f: round(s, 1) for f, s in sorted(by_file.items())}, indent=1) + "\n")
        print(f"schedule: {SCHEDULE.relative_to(ROOT)} ({len(by_file)} files)")
    raise SystemExit(done.returncode)


if __name__ == "__main__":
    main()
