"""Where does the test suite's time go? Runs pytest on the suite (as CI does) and tabulates its wall
time, the time by test folder and the slowest tests, from pytest's JUnit XML (``--junitxml``: per
test, its setup, call and teardown together, and the CPU ``tests/conftest.py`` records as the
property ``cpu``: what a test computes, where its time minus its CPU is waiting). ``--schedule``
also writes each test file's time to ``tests/durations.json``, the order in which
``tests/conftest.py`` hands files to the workers (heaviest first).

The run's wall time depends on the machine and what else runs on it: the result names both (its
``environment``). ``--pytest-args`` passes options through, e.g. ``-m "not slow"`` for the developer
loop, and ``--question`` names that run on its results page.

    python -m benchmarks.compute.suite_durations [--pytest-args ARGS] [--question TEXT] [--top 25] [--json PATH]
        [--schedule]
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pytest-args", default="", help="options passed to pytest (quoted), e.g. '-m \"not slow\"'")
    ap.add_argument("--question", default=QUESTION, help=f"the results page's title ({QUESTION!r})")
    ap.add_argument("--top", type=int, default=25, help="slowest tests listed (25)")
    ap.add_argument("--json", metavar="PATH", help="also write the result (docs/results/data/ for the docs)")
    ap.add_argument("--schedule", action="store_true",
                    help=f"also write each test file's seconds to {SCHEDULE.relative_to(ROOT)} (the workers' order)")
    args = ap.parse_args()
    run = Run()
    with tempfile.TemporaryDirectory() as tmp:
        junit = Path(tmp) / "junit.xml"
        cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", f"--junitxml={junit}",
               *shlex.split(args.pytest_args)]
        t0, c0 = time.monotonic(), resource.getrusage(resource.RUSAGE_CHILDREN)
        done = subprocess.run(cmd, cwd=ROOT, check=False)
        wall, c1 = time.monotonic() - t0, resource.getrusage(resource.RUSAGE_CHILDREN)
        # pytest, its workers and every process they started and waited for (commands, clusters)
        cpu = (c1.ru_utime - c0.ru_utime) + (c1.ru_stime - c0.ru_stime)
        if not junit.exists():
            raise SystemExit(f"pytest wrote no JUnit XML (exit {done.returncode})")
        cases = read_junit(junit)
    by_folder: dict[str, list[tuple[float, float]]] = collections.defaultdict(list)
    by_file: dict[str, float] = collections.defaultdict(float)
    for file, _, s, c in cases:
        by_folder[str(Path(file).parent)].append((s, c))
        by_file[file] += s
    folders = sorted(by_folder.items(), key=lambda kv: -sum(s for s, _ in kv[1]))
    slowest = sorted(cases, key=lambda c: -c[2])[:args.top]
    total, total_cpu = sum(c[2] for c in cases), sum(c[3] for c in cases)
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
                                   [[n, s, c] for _, n, s, c in slowest])],
                     notes=["One run on the machine named below; wall times on a busy machine are longer."])
        print(f"results: {args.json}")
    if args.schedule:  # after the result, which records whether the checkout was clean
        SCHEDULE.write_text(json.dumps({f: round(s, 1) for f, s in sorted(by_file.items())}, indent=1) + "\n")
        print(f"schedule: {SCHEDULE.relative_to(ROOT)} ({len(by_file)} files)")
    raise SystemExit(done.returncode)


if __name__ == "__main__":
    main()
