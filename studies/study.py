"""The paper's two parameter studies on a bench (section 5), and the staging-convergence study.

- Wear study (5.1): clearance 0.6 mm, -5 pi rad/s, two wear stages; dynamics before, after first
  and after second wear.
- Clearance study (5.2): 0.1 / 0.3 / 0.45 mm at -6 pi rad/s, one wear stage; dynamics before and
  after wear; the table shaped like the paper's Table 3 (max contact force per joint).
- Wear convergence: the same total cycles worn with the surface-update depth cap refined k = 1, 2, 4, ...

Cases run as tasks of :mod:`wearbench.model.compute` (a local cluster by default, results cached by
content). Imports the model contract, the wear modules and matplotlib (through
``wear_report``/``study_plots``); no CLI code.
"""

from __future__ import annotations

import itertools
import json
import math
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import pandas as pd
from wearbench.bench.content import bench_key
from wearbench.compute import Task, TaskFailure, run_tasks, task_key
from wearbench.model.wear_stages import StagePlan, WearRun, convergence, run_stages

__all__ = ["PAPER", "Case", "CaseResult", "StudyConfig", "run_case", "run_study", "staging_convergence",
           "table3", "trends"]

# Published values (the paper, section 5 and Table 3), its own unknown geometry: for trends only.
PAPER = {
    "wear_study": {  # 0.6 mm, -5 pi rad/s: before / first wear / second wear
        "peak_slider_acc": [463.2, 2333.0, 3231.0],
        "peak_fn": {"A": [2912.0, 6602.0, 11230.0], "B": [3032.0, 11690.0, 15340.0]},
        "max_depth": {"A": [4.73e-5, 1.16e-4], "B": [1.47e-5, 2.67e-4]},
    },
    "clearance_study": {  # -6 pi rad/s, (before, after) per clearance in mm
        "peak_fn": {"A": {0.1: (1322.0, 1327.0), 0.3: (2086.0, 3289.0), 0.45: (2269.0, 6214.0)},
                    "B": {0.1: (724.4, 1639.0), 0.3: (1507.0, 8849.0), 0.45: (2928.0, 23750.0)}},
        "peak_slider_acc": {0.1: (155.3, 308.4), 0.3: (334.4, 1145.0), 0.45: (597.7, 3289.0)},
        "max_depth": {"A": {0.1: 1.91e-6, 0.3: 3.96e-6, 0.45: 1.22e-5},
                      "B": {0.1: 3.90e-6, 0.3: 1.15e-5, 0.45: 2.58e-5}},
    },
}


@dataclass(frozen=True)
class Case:
    """One operating point: clearance (m, every clearance joint), speed (rad/s), wear stages."""

    name: str
    clearance: float
    speed: float
    stages: int


@dataclass
class CaseResult:
    case: Case
    run: WearRun
    dynamics: dict[str, pd.DataFrame]   # state label -> result table
    summaries: dict[str, dict]          # state label -> simulation summary
    wall_time: float


@dataclass(frozen=True)
class StudyConfig:
    """Cost knobs. ``plan`` shapes each stage; ``dyn_revolutions`` is the length of the dynamics run
    per worn state (Poincare maps get one point per revolution); ``output_rate`` (Hz) of its table."""

    plan: StagePlan = field(default_factory=StagePlan)
    dyn_revolutions: float = 10.0
    output_rate: float | None = None  # Hz; None: the model's default fine grid (peak slider acc)
    workers: int | None = None  # local cluster size (None: the usable cores; 0: in-process)
    scheduler: str | None = None  # a running cluster's address (see wearbench.model.compute)
    wear_case: Case = Case("wear 0.6 mm", 0.6e-3, -5 * math.pi, 2)
    clearance_cases: tuple[Case, ...] = (Case("0.1 mm", 0.1e-3, -6 * math.pi, 1),
                                         Case("0.3 mm", 0.3e-3, -6 * math.pi, 1),
                                         Case("0.45 mm", 0.45e-3, -6 * math.pi, 1))

    @classmethod
    def quick(cls, plan: StagePlan) -> StudyConfig:
        """A cut-down study for tests: one surface update per stage, 1-revolution dynamics runs."""
        return cls(plan=replace(plan, update_depth=1.0, min_updates=1, settle=0), dyn_revolutions=1.0,
                   output_rate=5_000.0)


def run_case(bench, case: Case, config: StudyConfig) -> CaseResult:
    """Wear ``case`` and simulate the dynamics of every state (before, first wear, ...)."""
    from wearbench.model import build_scene, simulate

    t0 = time.perf_counter()
    clear = {j.name: case.clearance for j in bench.clearance_joints}
    run = run_stages(bench, replace(config.plan, stages=case.stages), clearances=clear, speed=case.speed)
    dynamics, summaries = {}, {}
    for label, surfaces in run.states:
        scene = build_scene(bench, clearances=clear, surfaces=surfaces)
        res = simulate(scene, revolutions=config.dyn_revolutions, speed=case.speed, method=config.plan.method,
                       output_rate=config.output_rate, record_contacts=True)
        dynamics[label] = res.table
        summaries[label] = dict(res.summary)
        # peak contact force over every accepted step, not only the output grid
        summaries[label]["peak_fn"] = {j: float(c["fn"].max()) for j, c in res.contacts.items()}
    return CaseResult(case, run, dynamics, summaries, time.perf_counter() - t0)


def _raise_failures(results: list, what: str) -> None:
    failed = [r for r in results if isinstance(r, TaskFailure)]
    if failed:
        raise RuntimeError(f"{what}: {len(failed)} of {len(results)} tasks failed: "
                           + "; ".join(str(f) for f in failed))


def _wear_only(bench, plan: StagePlan, clearances, speed, initial) -> WearRun:
    return run_stages(bench, plan, clearances=clearances, speed=speed, initial=initial)


def staging_convergence(bench, ks: list[float], total_cycles: float, plan: StagePlan, *, clearances=None,
                        speed=None, initial=None, out: str | Path | None = None, workers: int | None = None,
                        scheduler: str | None = None, known: dict[float, WearRun] | None = None) -> list[dict]:
    """Wear the same ``total_cycles`` (in ``plan.stages`` stages) at each refinement k in ``ks``
    (depth cap per surface update ``plan.update_depth / k``); compare max depth, reachable depth and
    worn volume between refinements (:func:`~wearbench.model.wear_stages.convergence`).

    ``known``: runs already made with this plan at refinement k (not run again). ``workers``/
    ``scheduler``: see :func:`~wearbench.model.compute.run_tasks`.
    Writes ``out/convergence.csv`` if ``out`` is given.
    """
    stage = total_cycles / plan.stages
    runs: dict[float, WearRun] = {k: r for k, r in (known or {}).items() if k in ks}
    plans = {k: replace(plan, stage_cycles=stage, refinement=float(k)) for k in ks if k not in runs}
    order = sorted(plans, reverse=True)  # longest first: balanced workers
    tasks = [Task(_wear_only, {"bench": bench, "plan": plans[k], "clearances": clearances, "speed": speed,
                               "initial": initial},
                  task_key("wear-stages", bench_key(bench), plans[k], clearances, speed, initial), f"k={k:g}")
             for k in order]
    if tasks:
        done = run_tasks(tasks, workers=workers, scheduler=scheduler, progress="wear convergence")
        _raise_failures(done, "staging convergence")
        runs.update(zip(order, done, strict=True))
    rows = convergence(runs)
    if out is not None:
        Path(out).mkdir(parents=True, exist_ok=True)
        pd.DataFrame(rows).to_csv(Path(out) / "convergence.csv", index=False)
    return rows


def table3(results: list[CaseResult], after: str = "first wear") -> pd.DataFrame:
    """Max contact force (N) per joint, before and after wear, per clearance: the paper's Table 3."""
    rows = {}
    for r in results:
        mm = round(r.case.clearance * 1e3, 3)
        for j in r.run.clearances:
            rows.setdefault(f"clearance {j}", {})[(f"{mm:g} mm", "before wear")] = r.summaries["before wear"]["peak_fn"][j]
            rows[f"clearance {j}"][(f"{mm:g} mm", "after wear")] = r.summaries[after]["peak_fn"][j]
    df = pd.DataFrame(rows).T
    df.columns = pd.MultiIndex.from_tuples(df.columns)
    return df


def _peak_rows(results: list[CaseResult]) -> list[dict]:
    """One row per case and state: peak slider acceleration, peak contact force and max depth per joint."""
    rows = []
    for r in results:
        states = dict(r.run.states)
        for label, s in r.summaries.items():
            rows.append({"case": r.case.name, "clearance_mm": r.case.clearance * 1e3, "speed_rad_s": r.case.speed,
                         "state": label, "peak_slider_acc": s["peak_slider_acc"],
                         **{f"peak_fn_{j}": v for j, v in s["peak_fn"].items()},
                         **{f"max_depth_{j}": max(states[label][j].max_depth) for j in r.run.clearances}})
    return rows


def trends(wear: CaseResult, clearance: list[CaseResult]) -> list[dict]:
    """The paper's qualitative findings (sections 5.1, 5.2) checked on our results: {finding, paper, ours,
    detail}; ``paper`` is True for each (the paper reports them), ``ours`` whether our run shows it."""
    out = []

    def add(finding: str, ours: bool, detail: str) -> None:
        out.append({"finding": finding, "paper": True, "ours": bool(ours), "detail": detail})

    labels = [lbl for lbl, _ in wear.run.states]
    acc = [wear.summaries[lbl]["peak_slider_acc"] for lbl in labels]
    add("wear raises the peak slider acceleration, second wear more than first",
        all(b > a for a, b in itertools.pairwise(acc)), f"{[round(a, 1) for a in acc]} m/s^2 over {labels}")
    for j in wear.run.clearances:
        fn = [wear.summaries[lbl]["peak_fn"][j] for lbl in labels]
        add(f"wear raises the peak contact force at {j}", all(b > a for a, b in itertools.pairwise(fn)),
            f"{[round(f) for f in fn]} N")
    final = wear.run.final
    depth = {j: max(final[j].max_depth) for j in final}
    if {"A", "B"} <= set(depth):
        add("B wears deeper than A (after second wear)", depth["B"] > depth["A"],
            f"A {depth['A']:.3g} m, B {depth['B']:.3g} m")
    cl = sorted(clearance, key=lambda r: r.case.clearance)
    for j in wear.run.clearances:
        after = [r.summaries["first wear"]["peak_fn"][j] for r in cl]
        before = [r.summaries["before wear"]["peak_fn"][j] for r in cl]
        add(f"contact force at {j} grows after wear at every clearance",
            all(a > b for a, b in zip(after, before, strict=True)),
            f"before {[round(x) for x in before]} N, after {[round(x) for x in after]} N")
        add(f"contact force at {j} after wear grows with clearance",
            all(b > a for a, b in itertools.pairwise(after)), f"{[round(x) for x in after]} N")
        d = [max(r.run.final[j].max_depth) for r in cl]
        add(f"wear depth at {j} grows with clearance", all(b > a for a, b in itertools.pairwise(d)),
            f"{[f'{x:.3g}' for x in d]} m")
    acc_after = [r.summaries["first wear"]["peak_slider_acc"] for r in cl]
    add("peak slider acceleration after wear grows with clearance",
        all(b > a for a, b in itertools.pairwise(acc_after)), f"{[round(x, 1) for x in acc_after]} m/s^2")
    return out


def run_study(bench, out: str | Path, config: StudyConfig, *, on_case=None) -> dict:
    """Run the wear study and the clearance study (in parallel), write tables, JSON and figures.

    Writes under ``out``: ``wear/`` (surfaces, depths.csv, summary.json, figures 6-8),
    ``clearance_<mm>/`` likewise, ``table3.csv``, ``table3.md`` (ours beside the paper's),
    ``peaks.csv`` (peak slider acceleration, contact forces, depths per case and state),
    ``trends.json`` and the figures 9-32 analogues under ``figures/``. Returns the summary dict.
    """
    from wearbench.studies.study_plots import plot_case_dynamics
    from wearbench.studies.wear_report import write_run

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    cases = [config.wear_case, *config.clearance_cases]
    t0 = time.perf_counter()
    tasks = [Task(run_case, {"bench": bench, "case": c, "config": config},
                  task_key("study-case", bench_key(bench), c, replace(config, workers=None, scheduler=None)),
                  c.name) for c in cases]

    def finished(i: int, r) -> None:
        if on_case is not None and not isinstance(r, TaskFailure):
            on_case(r)

    done = run_tasks(tasks, workers=config.workers, scheduler=config.scheduler, on_result=finished)
    _raise_failures(done, f"study of {bench.name}")
    results: dict[str, CaseResult] = {c.name: r for c, r in zip(cases, done, strict=True)}
    wear = results[config.wear_case.name]
    clear = [results[c.name] for c in config.clearance_cases]
    write_run(wear.run, out / "wear")
    for r in clear:
        write_run(r.run, out / f"clearance_{r.case.clearance * 1e3:g}mm")
    figures = out / "figures"
    figures.mkdir(exist_ok=True)
    plot_case_dynamics(wear, bench, figures)
    for r in clear:
        plot_case_dynamics(r, bench, figures, clearance_study=True, suffix=f"_{r.case.clearance * 1e3:g}mm")
    t3 = table3(clear)
    t3.to_csv(out / "table3.csv")
    peaks = pd.DataFrame(_peak_rows([wear, *clear]))
    peaks.to_csv(out / "peaks.csv", index=False)
    tr = trends(wear, clear)
    (out / "table3.md").write_text(table3_markdown(t3, clear) + "\n\n" + wear_markdown(wear) + "\n\n"
                                   + trends_markdown(tr) + "\n")
    summary = {
        "bench": bench.name, "wall_time_s": round(time.perf_counter() - t0, 1),
        "plan": {"stage_cycles": config.plan.stage_cycles, "update_depth_m": config.plan.depth_cap,
                 "settle": config.plan.settle, "dyn_revolutions": config.dyn_revolutions},
        "table3": {r: {f"{a} {b}": float(v) for (a, b), v in t3.loc[r].items()} for r in t3.index},
        "peaks": peaks.to_dict(orient="records"), "trends": tr,
        "case_wall_time_s": {n: round(r.wall_time, 1) for n, r in results.items()},
    }
    (out / "study.json").write_text(json.dumps(summary, indent=2, default=float) + "\n")
    return summary


def table3_markdown(t3: pd.DataFrame, clear: list[CaseResult]) -> str:
    """Our Table 3 beside the paper's (max contact force, N; ours / paper)."""
    paper = PAPER["clearance_study"]["peak_fn"]
    cols = list(t3.columns)
    head = "| joint | " + " | ".join(f"{c} {s}" for c, s in cols) + " |"
    lines = ["Max contact force (N), ours / paper (paper Table 3, -6 pi rad/s)", "", head,
             "|---" * (len(cols) + 1) + "|"]
    for row in t3.index:
        j = row.split()[-1]
        cells = []
        for c, s in cols:
            mm = float(c.split()[0])
            p = paper.get(j, {}).get(mm)
            pv = "" if p is None else f" / {p[0 if s == 'before wear' else 1]:g}"
            cells.append(f"{t3.loc[row, (c, s)]:.0f}{pv}")
        lines.append(f"| {j} | " + " | ".join(cells) + " |")
    acc = PAPER["clearance_study"]["peak_slider_acc"]
    lines += ["", "Peak slider acceleration (m/s^2), ours / paper", "", "| clearance | before wear | after wear |",
              "|---|---|---|"]
    for r in sorted(clear, key=lambda r: r.case.clearance):
        mm = round(r.case.clearance * 1e3, 3)
        p = acc.get(mm, (float("nan"), float("nan")))
        lines.append(f"| {mm:g} mm | {r.summaries['before wear']['peak_slider_acc']:.0f} / {p[0]:g} | "
                     f"{r.summaries['first wear']['peak_slider_acc']:.0f} / {p[1]:g} |")
    return "\n".join(lines)


def wear_markdown(wear: CaseResult) -> str:
    """Wear study (0.6 mm, -5 pi): peaks and depths per state, ours / paper."""
    p = PAPER["wear_study"]
    lines = ["Wear study (0.6 mm, -5 pi rad/s), ours / paper", "",
             "| state | peak slider acc (m/s^2) | " + " | ".join(f"peak F {j} (N) | max depth {j} (m)"
                                                       for j in wear.run.clearances) + " |",
             "|---" * (2 + 2 * len(wear.run.clearances)) + "|"]
    for i, (label, states) in enumerate(wear.run.states):
        s = wear.summaries[label]
        cells = [label, f"{s['peak_slider_acc']:.0f} / {p['peak_slider_acc'][i]:g}" if i < 3 else
                 f"{s['peak_slider_acc']:.0f}"]
        for j in wear.run.clearances:
            pf = p["peak_fn"].get(j, [None] * 3)
            cells.append(f"{s['peak_fn'][j]:.0f}" + (f" / {pf[i]:g}" if i < 3 and pf[i] else ""))
            pd_ = p["max_depth"].get(j, [None, None])
            depth = max(states[j].max_depth)
            cells.append(f"{depth:.3g}" + (f" / {pd_[i - 1]:.3g}" if 1 <= i <= 2 and pd_[i - 1] else ""))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def trends_markdown(tr: list[dict]) -> str:
    lines = ["Paper's findings on our bench", "", "| finding | agrees | ours |", "|---|---|---|"]
    lines += [f"| {t['finding']} | {'yes' if t['ours'] else 'no'} | {t['detail']} |" for t in tr]
    return "\n".join(lines)

