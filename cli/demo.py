"""`wearbench demo`: the whole toolkit end to end on the emulated nine-bar test bed.

For each case (clearance 0.3 and 0.6 mm with new surfaces; 0.3 mm after the first and the second
wear stage) the demo tells the bench emulator the true state, records a session through the
acquisition drivers (the serial protocol on a pseudo-terminal, or the in-process device with
``--quick``), simulates the theory of every case, scores each session's five-cycle windows against
every theory, and writes one report: which state explains each measurement, with figures and JSON.
"""

from __future__ import annotations

import argparse
import math
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path

BENCH = "ninebar-testbed"
WORN = {"first wear": "200k", "second wear": "400k"}  # shipped surfaces: hardware/benches/worn/


@dataclass(frozen=True)
class Case:
    """One true state of the bench: clearance (m) of both clearance joints and a wear stage."""

    clearance: float
    stage: str = "new"
    files: dict[str, Path] = field(default_factory=dict)  # joint -> worn surfaces (.npz)

    @property
    def label(self) -> str:
        return f"{self.clearance * 1e3:.1f} mm {self.stage}"

    @property
    def slug(self) -> str:
        return self.label.replace(" ", "_").replace(".", "p")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "demo", help="record, simulate and compare four bench states on the emulated nine-bar test bed",
        description="The whole toolkit on the built-in simulated bench: for clearance 0.3 and 0.6 mm with "
        "new surfaces and 0.3 mm after the first and second wear stage, record a session from the bench "
        "emulator through the acquisition drivers, simulate the theory of each state, score five-cycle "
        "windows of every session against every theory, and write report.html, scores.json and figures. "
        "About 2 minutes (plus about 1 minute compiling the model the first time).",
        epilog="example: wearbench demo --out demo/   (then open demo/report/report.html)")
    p.add_argument("--out", "-o", type=Path, default=Path("demo"),
                   help="folder for sessions/ (MCAP) and report/ (default: demo/)")
    p.add_argument("--quick", action="store_true",
                   help="one five-cycle window per session, recorded from the in-process emulator as fast "
                   "as the host can (about a minute)")
    p.add_argument("--backend", choices=["serial", "sim"],
                   help="how sessions are recorded: 'serial' runs the emulator on a pseudo-terminal and "
                   "records in real time through the serial driver; 'sim' uses the in-process emulator "
                   "(default: serial, sim with --quick)")
    p.add_argument("--cycles", type=int, help="crank cycles per session (default 12, 7 with --quick)")
    p.set_defaults(func=run)


def demo_cases(worn_dir: Path) -> list[Case]:
    """The paper's test cases: 0.3 and 0.6 mm new, 0.3 mm after the first and the second wear stage."""
    cases = [Case(0.3e-3), Case(0.6e-3)]
    for stage, cycles in WORN.items():
        files = {j: worn_dir / f"{BENCH}_{j}_{cycles}.npz" for j in ("A", "B")}
        cases.append(Case(0.3e-3, stage, files))
    return cases


def emulator_table(bench, case: Case) -> dict:
    """The bench file's ``[emulator]`` table with the case as the device's hidden truth."""
    from wearbench.hardware.emulators.config import EmulatorConfig

    table = EmulatorConfig.from_bench(bench).to_table()
    table["truth"] = {"clearances": {j.name: f"{case.clearance!r} m" for j in bench.clearance_joints},
                      "wear": {j: str(p.resolve()) for j, p in case.files.items()},
                      "wear_stage": case.stage, "accel_delay": "0.2 ms"}
    return table


def record_case(bench, case: Case, out: Path, *, backend: str, cycles: int, on_progress=None):
    """Record one session of ``case`` to ``out`` through the ``backend`` driver; the SessionResult."""
    from wearbench.acquisition.backends import open_rig
    from wearbench.acquisition.recorder import Recorder, SessionPlan

    config = emulator_table(bench, case)
    plan = SessionPlan(speed=bench.speed, cycles=cycles, operator="wearbench demo",
                       clearances={j.name: case.clearance for j in bench.clearance_joints},
                       wear={j: p.name for j, p in case.files.items()})  # beside the session file
    proc = None
    if backend == "serial":
        from wearbench.hardware.emulators.serial_server import start_serial_emulator

        proc, port = start_serial_emulator(bench, config)
        options: dict = {"port": port}
    else:
        options = {"speedup": math.inf, "config": config}
    try:
        rig = open_rig(bench.with_clearances(plan.clearances), backend, options)
        try:
            result = Recorder(rig, bench, plan, out, on_progress=on_progress).run()
        finally:
            rig.close()
    finally:
        if proc is not None:
            proc.terminate()
            proc.wait(timeout=30)
    if not result.completed:
        raise RuntimeError(f"demo: session {out} stopped early: {result.reason} (the file holds what was "
                           "recorded until then)")
    return result


def run(args: argparse.Namespace) -> int:
    from wearbench.cli.progress import progress
    from wearbench.hardware.bench import BENCH_DIR, load_bench, shipped_bench
    from wearbench.hardware.emulators.config import EmulatorConfig
    from wearbench.hardware.emulators.device import BenchDevice, table_speed
    from wearbench.model.surfaces import JointSurfaces
    from wearbench.validation import CompareOptions, load_session, rank_theories
    from wearbench.validation.report import write_report
    from wearbench.validation.theory import simulate_theory

    backend = args.backend or ("sim" if args.quick else "serial")
    cycles = args.cycles or (7 if args.quick else 12)
    if cycles < 6:
        raise ValueError(f"--cycles {cycles}: expected at least 6 (a five-cycle window after the first index)")
    bench = load_bench(shipped_bench(BENCH))
    cases = demo_cases(BENCH_DIR / "worn")
    sessions_dir, report_dir = args.out / "sessions", args.out / "report"
    sessions_dir.mkdir(parents=True, exist_ok=True)
    for case in cases:  # sessions name their worn surfaces relative to themselves
        for p in case.files.values():
            shutil.copyfile(p, sessions_dir / p.name)
    options = CompareOptions()
    start = time.monotonic()
    steps = 3 * len(cases) + 1
    with progress() as bar:
        task = bar.add_task("demo", total=steps, info="")

        def stage(text: str) -> None:
            bar.update(task, description=f"{text:30s}", info="")

        theories = {}
        for case in cases:
            stage(f"theory {case.label}")
            clearances = {j.name: case.clearance for j in bench.clearance_joints}
            surfaces = {j: JointSurfaces.load(p) for j, p in case.files.items()} or None
            # at the speed whose table the emulator plays: a twin experiment (see the README)
            theories[case.label] = simulate_theory(bench, speed=table_speed(bench.speed), clearances=clearances,
                                                   surfaces=surfaces, revolutions=options.revolutions,
                                                   output_rate=bench.sensor("accelerometer").sample_rate)
            # the emulator's signal table for this truth, computed here once and cached on disk
            config = EmulatorConfig.from_table(emulator_table(bench, case), bench=bench)
            BenchDevice(bench, config).prepare(bench.speed)
            bar.advance(task)
        def show(p) -> None:
            dropped = f", dropped {p.dropped}" if p.dropped else ""
            bar.update(task, info=f"{p.phase} {p.cycles:.1f}/{cycles}{dropped}")

        paths = {}
        for case in cases:
            stage(f"record {case.label}")
            paths[case.label] = sessions_dir / f"{case.slug}.mcap"
            record_case(bench, case, paths[case.label], backend=backend, cycles=cycles, on_progress=show)
            bar.advance(task)
        rankings, comparisons = {}, []
        for case in cases:
            stage(f"score {case.label}")
            session = load_session(paths[case.label], label=case.label)
            ranks = rank_theories(session, theories, options=options)
            rankings[case.label] = ranks
            comparisons.append(next(r.comparison for r in ranks if r.label == case.label))
            bar.advance(task)
        stage("report")
        report = write_report(comparisons, report_dir, rankings=rankings,
                              title=f"wearbench demo: {bench.name}, measurement against theory")
        bar.advance(task)
    elapsed = time.monotonic() - start
    print(summary_text(report.scores))
    print(f"\nreport: {report.html}\nscores: {report.scores_json}\nsessions: {sessions_dir}/ "
          f"({len(cases)} MCAP files)\n{len(report.figures)} figures; {elapsed:.0f} s")
    return 0


def summary_text(scores: dict) -> str:
    """The report's summary as a plain-text table for the terminal."""
    rows = [("case", "ISO R", "grade", "peak |a| meas.", "peak |a| theory", "best explained by")]
    for s in scores["summary"]:
        rows.append((s["session"], f"{s['iso_rating']:.3f}", s["grade"], f"{s['peak_acc_measured']:.1f} m/s^2",
                     f"{s['peak_acc_theory']:.1f} m/s^2", s.get("best_explained_by") or "-"))
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(c.ljust(w) for c, w in zip(r, widths)) for r in rows)
