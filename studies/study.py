"""The paper's two parameter studies on a bench (section 5) as ensemble statistics, and the
staging-convergence study.

- Wear study (5.1): clearance 0.6 mm, -5 pi rad/s, two wear stages; dynamics before, after first
  and after second wear.
- Clearance study (5.2): 0.1 / 0.3 / 0.45 mm at -6 pi rad/s, one wear stage; dynamics before and
  after wear; the table shaped like the paper's Table 3 (max contact force per joint).
- Wear convergence: the same total cycles worn with the surface-update depth cap refined k = 1, 2, 4, ...

A study quantity is not the peak of one run (one impact of a chaotic motion) but a statistic over
many realisations, drawn as the identification's ensembles draw them
(:mod:`wearbench.model.realisation`: the bench within its tolerances, a random start). Each
realisation gives its run's max (the largest of its per-cycle maxima: the paper's "max" of one run)
and its typical cycle (the median per-cycle maximum); a cell is their geometric mean over the
realisations. The wear stage is an ensemble too: a few wear runs of each case from drawn benches
and starts, a few realisations on each run's surfaces. The interval is two-level: before wear the
realisations are the independent units; after wear the wear runs are (the mean log of each run's
realisations), so a Student-t interval over a handful of runs carries both the spread of the wear
and that of the realisations, with the few runs' degrees of freedom. Each of the paper's trends is
answered from the interval of the ratio it is about (Welch, or paired over the same wear runs), at a
level shared out over the finding's ratios: agrees, disagrees, or not resolved at this ensemble size.

Wear runs and realisations run as tasks of :mod:`wearbench.compute` (a local cluster by default,
results cached by content). Imports the model contract, the wear modules and matplotlib (through
``wear_report``/``study_plots``); no CLI code.
"""

from __future__ import annotations

import itertools
import json
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
import pandas as pd
from wearbench.bench.content import bench_key
from wearbench.compute import Task, TaskFailure, compute_client, run_tasks, task_key
from wearbench.model.wear_stages import StagePlan, WearRun, convergence, run_stages
from wearbench.studies import tasks_source_digest

__all__ = ["PAPER", "STATISTICS", "Case", "CaseResult", "Cell", "StudyConfig", "cell_statistics", "cell_units",
           "cycle_maxima", "run_study", "staging_convergence", "study_realisation", "trends", "verdict",
           "wear_realisation"]

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

# Statistics of one realisation's per-cycle maxima (its ``cycles`` crank cycles after settling). "max"
# answers the paper's "max": the paper reports the largest value of one simulated run a few
# revolutions long, and a realisation is such a run; a cell is the geometric mean of that max over the
# realisations (its typical run), which converges as the ensemble grows, unlike the largest value of
# the whole ensemble. "median": the typical cycle. Both depend on ``cycles`` as the paper's max depends
# on its run's length; ratios between cells of one study share it.
STATISTICS = {"max": np.max, "median": np.median}
MAX_STATISTIC = "max"


@dataclass(frozen=True)
class Case:
    """One operating point: clearance (m, every clearance joint), speed (rad/s), wear stages."""

    name: str
    clearance: float
    speed: float
    stages: int


@dataclass(frozen=True)
class StudyConfig:
    """Sizes and cost knobs. ``plan`` shapes each wear stage. Every (case, state) cell gets
    ``realisations`` realisations (after wear: spread evenly over the ``wear_runs`` runs, at least
    2 per run) of ``cycles`` crank cycles after ``settle`` dropped motor revolutions; realisation i
    uses seed ``seed + i``, wear run w seed ``seed + 100000 + w``. ``output_rate`` (Hz): the table
    the per-cycle maxima are taken from (None: the model's 20 kHz). Intervals at ``level``."""

    plan: StagePlan = field(default_factory=StagePlan)
    realisations: int = 40
    cycles: int = 8
    settle: float = 2.0
    wear_runs: int = 20
    seed: int = 1
    output_rate: float | None = None
    level: float = 0.95
    workers: int | None = None  # local cluster size (None: the usable cores; 0: in-process)
    scheduler: str | None = None  # a running cluster's address (see wearbench.compute)
    wear_case: Case = Case("wear 0.6 mm", 0.6e-3, -5 * math.pi, 2)
    clearance_cases: tuple[Case, ...] = (Case("0.1 mm", 0.1e-3, -6 * math.pi, 1),
                                         Case("0.3 mm", 0.3e-3, -6 * math.pi, 1),
                                         Case("0.45 mm", 0.45e-3, -6 * math.pi, 1))

    def __post_init__(self) -> None:
        if self.wear_runs < 1 or self.realisations < 2 or self.cycles < 1:
            raise ValueError(f"study: realisations = {self.realisations}, cycles = {self.cycles}, wear runs = "
                             f"{self.wear_runs}: expected at least 2 realisations of at least 1 cycle and 1 wear run")
        if not self.settle >= 0:
            raise ValueError(f"study: settle = {self.settle} revolutions: expected >= 0")
        if not 0.5 < self.level < 1:
            raise ValueError(f"study: level = {self.level}: expected a level between 0.5 and 1")

    @property
    def per_run(self) -> int:
        """Realisations on each wear run's surfaces (after wear)."""
        return max(2, math.ceil(self.realisations / self.wear_runs))

    @classmethod
    def quick(cls, plan: StagePlan, **sizes) -> StudyConfig:
        """A cut-down study for tests: one surface update per stage, 2 wear runs per case, 4
        realisations of 3 cycles per cell."""
        return cls(plan=replace(plan, update_depth=1.0, min_updates=1, settle=0),
                   **{"realisations": 4, "cycles": 3, "settle": 1.0, "wear_runs": 2,
                      "output_rate": 5_000.0, **sizes})


@dataclass
class CaseResult:
    """One case for the figures: its first wear run and one realisation's table per state."""

    case: Case
    run: WearRun
    dynamics: dict[str, pd.DataFrame]   # state label -> result table
    summaries: dict[str, dict]          # state label -> simulation summary
    wall_time: float


@dataclass
class Cell:
    """One (case, state) of the study: per-cycle maxima ``peaks[quantity]`` shaped (wear runs,
    realisations per run, cycles); before wear there is one group. ``by_run``: the realisations are
    grouped by the wear run whose surfaces they share (after wear), so the runs are the units."""

    case: Case
    state: str
    peaks: dict[str, np.ndarray]
    failures: list[str] = field(default_factory=list)
    by_run: bool = False


# ------------------------------------------------------------------------------------------------
# tasks (run on workers)


def wear_realisation(bench, plan: StagePlan, case: Case, seed: int) -> WearRun:
    """Wear ``case`` on the realisation of ``bench`` drawn with ``seed``: its bench within the
    tolerances, its true motor speed and its random start (the identification's draw)."""
    from wearbench.model import build_scene
    from wearbench.model.realisation import draw_realisation, realisation_start

    real = draw_realisation(bench, seed)
    clear = {j.name: case.clearance for j in bench.clearance_joints}
    speed = case.speed * real.speed_scale
    scene = build_scene(real.bench.with_speed(speed), clearances=clear)
    return run_stages(real.bench, replace(plan, stages=case.stages), clearances=clear, speed=speed,
                      start=realisation_start(real, scene, speed))


def cycle_maxima(motor: np.ndarray, values: Mapping[str, np.ndarray], cycles: int) -> dict[str, np.ndarray]:
    """Maxima of each of ``values`` over each whole motor revolution (from the first sample), the
    first ``cycles`` of them (fewer if fewer are whole)."""
    turns = np.abs(motor - motor[0]) / (2 * math.pi)
    n = min(int(cycles), math.floor(turns[-1] + 1e-9))
    if n < 1:
        raise ValueError(f"cycle maxima: {turns[-1]:.3g} motor revolutions: no whole cycle")
    bounds = np.searchsorted(turns, np.arange(n + 1), side="left")
    return {k: np.array([np.max(v[bounds[i]:max(bounds[i + 1], bounds[i] + 1)]) for i in range(n)])
            for k, v in values.items()}


def study_realisation(bench, clearances: Mapping[str, float], surfaces, seed: int, speed: float, cycles: int,
                      settle: float, output_rate: float | None, keep_table: bool) -> dict:
    """One realisation (seed) of ``bench`` with ``clearances`` and worn ``surfaces`` (None: new):
    per-cycle maxima of the contact force per clearance joint (``fn_<joint>``) and of the slider's
    |acceleration| (``acc``); with ``keep_table`` also its table and summary (for the figures)."""
    from wearbench.bench.schema import WearState
    from wearbench.model.realisation import simulate_state

    run = simulate_state(bench, WearState("study", dict(clearances)), seed, revolutions=cycles + 0.25,
                         settle=settle, speed=speed, output_rate=output_rate, surfaces=surfaces)
    values = {f"fn_{j}": run.table[f"{j}_fn"].to_numpy() for j in clearances}
    values["acc"] = np.abs(run.acc)
    out = {"peaks": cycle_maxima(run.motor_angle, values, cycles), "wall_time_s": run.summary.get("wall_time_s")}
    if keep_table:
        out["table"] = run.table
        out["summary"] = {"peak_fn": {j: float(run.table[f"{j}_fn"].max()) for j in clearances},
                          "peak_slider_acc": float(np.abs(run.acc).max())}
    return out


# ------------------------------------------------------------------------------------------------
# statistics


def _quantities(joints: Sequence[str]) -> list[str]:
    return [*(f"fn_{j}" for j in joints), "acc"]


def cell_units(x: np.ndarray, statistic: str, by_run: bool) -> np.ndarray:
    """The independent units of a cell's (W, M, C) per-cycle maxima, on a log scale: the log of each
    realisation's ``statistic`` over its cycles (W * M units), or with ``by_run`` each wear run's
    mean of them (W units: realisations on one run's surfaces share them)."""
    logs = np.log(STATISTICS[statistic](x, axis=2))
    return logs.mean(axis=1) if by_run else logs.reshape(-1)


def _t_parts(x: np.ndarray, y: np.ndarray | None, paired: bool) -> tuple[float, float, float]:
    """Mean of ``x`` (``y`` None) or of ``x - y``, its standard error and degrees of freedom: paired
    (the same units) on the differences, else Welch's with Satterthwaite's degrees of freedom. Fewer
    than 2 units on a side give an infinite standard error."""
    if y is not None and paired:
        x, y = x - y, None
    sides = [x] if y is None else [x, y]
    diff = float(x.mean() - (0.0 if y is None else y.mean()))
    if min(v.size for v in sides) < 2:
        return diff, math.inf, 1.0
    var = [v.var(ddof=1) / v.size for v in sides]
    se = math.sqrt(sum(var))
    dof = sum(var) ** 2 / sum(u**2 / (v.size - 1) for u, v in zip(var, sides, strict=True)) if se > 0 else 1.0
    return diff, se, dof


def _t_quantile(level: float, dof: float) -> float:
    from scipy import stats as sps

    return float(sps.t.ppf(0.5 * (1 + level), dof))


def _t_interval(x: np.ndarray, y: np.ndarray | None, paired: bool, level: float) -> tuple[float, float, float]:
    """Mean of ``x`` (``y`` None) or of ``x - y`` and its Student-t interval at ``level``
    (:func:`_t_parts`); no interval (-inf, inf) without a standard error."""
    diff, se, dof = _t_parts(x, y, paired)
    if not math.isfinite(se):
        return diff, -math.inf, math.inf
    half = _t_quantile(level, dof) * se
    return diff, diff - half, diff + half


def replication(parts: Sequence[tuple[float, float, float]], level: float) -> dict[str, float]:
    """How a rerun of the same size would judge a finding of ratios with log-ratio estimates, standard
    errors and degrees of freedom ``parts`` (intervals at ``level``).

    A rerun's estimate of each log ratio is predicted as N(d, 2 se^2) (the effect known only through
    this run, flat prior: Goodman's replication probability), the ratios as independent. Returns the
    probability of each of the rerun's verdicts, ``agrees`` (every interval above 1), ``disagrees``
    (any below 1) and ``not resolved``, and ``size_for_90``: the factor on the number of units (wear runs or
    realisations) at which a rerun resolves the finding the way its estimates point with probability
    0.9, were the true ratios the estimated ones (at today's t quantile; inf when no estimate points
    anywhere or the factor exceeds 1000)."""
    from scipy import stats as sps
    from scipy.optimize import brentq

    z = np.array([d / se if math.isfinite(se) and se > 0 else 0.0 for d, se, _ in parts])
    t = np.array([_t_quantile(level, dof) for *_, dof in parts])
    up = sps.norm.cdf((z - t) / math.sqrt(2))
    down = sps.norm.cdf((-z - t) / math.sqrt(2))
    agrees, disagrees = float(np.prod(up)), float(1 - np.prod(1 - down))

    def resolved(f: float) -> float:  # probability the rerun at f times the units resolves the pointed way
        if (z > 0).all():
            return float(np.prod(sps.norm.cdf(z * math.sqrt(f) - t)))
        return float(1 - np.prod(1 - sps.norm.cdf(-z * math.sqrt(f) - t)))

    pointed = bool((z > 0).all() or (z < 0).any())  # every estimate above 1, or one below
    if not pointed or resolved(1000.0) < 0.9:
        size = math.inf
    else:
        size = 0.0 if resolved(1e-9) >= 0.9 else brentq(lambda f: resolved(f) - 0.9, 1e-9, 1000.0)
    return {"agrees": agrees, "disagrees": disagrees, "not resolved": 1 - agrees - disagrees, "size_for_90": size}


def cell_statistics(cell: Cell, level: float) -> dict[str, dict[str, dict]]:
    """{quantity: {statistic: {"value", "lo", "hi", "units", "by_run"}}}: the geometric mean of the
    statistic over the cell's units and its Student-t interval at ``level``; ``units`` (log) for
    the ratios between cells."""
    out = {}
    for q, x in cell.peaks.items():
        out[q] = {}
        for s in STATISTICS:
            u = cell_units(x, s, cell.by_run)
            m, lo, hi = _t_interval(u, None, False, level)
            out[q][s] = {"value": math.exp(m), "lo": math.exp(lo), "hi": math.exp(hi), "units": u,
                         "by_run": cell.by_run}
    return out


def verdict(lo: float, hi: float) -> str:
    """The answer to "the ratio exceeds 1" from its interval [lo, hi]."""
    return "agrees" if lo > 1 else "disagrees" if hi < 1 else "not resolved"


def _combine(verdicts: Sequence[str]) -> str:
    """A trend made of several comparisons agrees when all do and disagrees when any does."""
    if "disagrees" in verdicts:
        return "disagrees"
    return "agrees" if all(v == "agrees" for v in verdicts) else "not resolved"


# ------------------------------------------------------------------------------------------------
# the study


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
    ``scheduler``: see :func:`~wearbench.compute.run_tasks`.
    Writes ``out/convergence.csv`` if ``out`` is given.
    """
    stage = total_cycles / plan.stages
    runs: dict[float, WearRun] = {k: r for k, r in (known or {}).items() if k in ks}
    plans = {k: replace(plan, stage_cycles=stage, refinement=float(k)) for k in ks if k not in runs}
    order = sorted(plans, reverse=True)  # longest first: balanced workers
    tasks = [Task(_wear_only, {"bench": bench, "plan": plans[k], "clearances": clearances, "speed": speed,
                               "initial": initial},
                  task_key("wear-stages", tasks_source_digest(_wear_only), bench_key(bench), plans[k], clearances, speed, initial), f"k={k:g}")
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


def _labels(case: Case) -> list[str]:
    from wearbench.model.wear_stages import stage_label

    return ["before wear", *(stage_label(k) for k in range(1, case.stages + 1))]


def _mm(case: Case) -> float:
    return round(case.clearance * 1e3, 3)


def _cells(groups: Mapping[tuple[str, str], list[list]], cases: Sequence[Case], joints: Sequence[str]) -> list[Cell]:
    """Cells from results grouped by (case, state): a list per wear run of realisation results
    (TaskFailure where one failed); runs trimmed to equal realisations and cycles."""
    cells = []
    for case in cases:
        for label in _labels(case):
            runs = groups[(case.name, label)]
            good = [[r for r in run if not isinstance(r, TaskFailure)] for run in runs]
            failed = [str(r) for run in runs for r in run if isinstance(r, TaskFailure)]
            m = min(len(g) for g in good)
            if m < 2:
                raise RuntimeError(f"study {case.name}, {label}: fewer than 2 realisations succeeded on a "
                                   f"surface; " + "; ".join(failed[:3]))
            c = min(len(r["peaks"]["acc"]) for g in good for r in g)
            peaks = {q: np.array([[r["peaks"][q][:c] for r in g[:m]] for g in good]) for q in _quantities(joints)}
            cells.append(Cell(case, label, peaks, failed, by_run=label != "before wear"))
    return cells


def _wear_rows(runs: Mapping[str, list[WearRun]], cases: Sequence[Case]) -> list[dict]:
    """One row per case, wear run, stage and joint: max depth (m) of bearing and journal and the worn
    volume (m^3, both surfaces) up to that stage."""
    rows = []
    for case in cases:
        for w, run in enumerate(runs[case.name]):
            for k, (label, states) in enumerate(run.states[1:], start=1):
                for j in run.clearances:
                    bearing, journal = states[j].max_depth
                    rows.append({"case": case.name, "clearance_mm": _mm(case), "wear_run": w + 1, "state": label,
                                 "joint": j, "bearing_max_depth_m": bearing, "journal_max_depth_m": journal,
                                 "max_depth_m": max(bearing, journal),
                                 "volume_m3": float(sum(st.volume[j] for st in run.stages[:k]))})
    return rows


def _depth_runs(wear: pd.DataFrame) -> dict[tuple[str, str], dict[str, np.ndarray]]:
    """{(case, state): {joint: max depth (m) of each wear run, in run order}}."""
    out: dict[tuple[str, str], dict[str, np.ndarray]] = {}
    for (case, label, j), g in wear.groupby(["case", "state", "joint"], sort=False):
        out.setdefault((case, label), {})[j] = g.sort_values("wear_run")["max_depth_m"].to_numpy(float)
    return out


def run_study(bench, out: str | Path, config: StudyConfig) -> dict:
    """Run the wear study and the clearance study as ensembles, write tables, JSON and figures.

    Writes under ``out``: ``wear/`` (the first wear run's surfaces, depths.csv, summary.json,
    figures 6-8; further runs under ``wear/run<k>/``), ``clearance_<mm>/`` likewise,
    ``peaks.csv`` (every realisation's per-cycle maxima), ``cells.csv`` (every cell's statistics
    with intervals), ``wear_runs.csv`` (max depth and worn volume per wear run), ``table3.csv`` (the
    Table 3 analogue, the max of a run), ``trends.csv``, ``table3.md`` (the report: ours beside the
    paper's, the trends' verdicts), ``study.json`` and the figures 9-32 analogues (one realisation
    per state) under ``figures/``. Returns the summary dict.
    """
    from wearbench.studies.study_plots import plot_case_dynamics
    from wearbench.studies.wear_report import write_run

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    cases = [config.wear_case, *config.clearance_cases]
    joints = [j.name for j in bench.clearance_joints]
    physics = (tasks_source_digest(wear_realisation, cycle_maxima, study_realisation), bench_key(bench), asdict(bench.tolerances))
    sizes = {"cycles": config.cycles, "settle": config.settle, "output_rate": config.output_rate}

    def realisation(case: Case, surfaces, seed: int, keep: bool, label: str) -> Task:
        clear = {j: case.clearance for j in joints}
        kwargs = {"bench": bench, "clearances": clear, "surfaces": surfaces, "seed": seed, "speed": case.speed,
                  **sizes, "keep_table": keep}
        return Task(study_realisation, kwargs, task_key("study-realisation", *physics, clear, surfaces, seed,
                                                        round(case.speed, 9), sizes, keep), label)

    wear_tasks = [Task(wear_realisation, {"bench": bench, "plan": config.plan, "case": c,
                                          "seed": config.seed + 100_000 + w},
                       task_key("study-wear", *physics, config.plan, c, config.seed + 100_000 + w),
                       f"{c.name} wear run {w + 1}") for c in cases for w in range(config.wear_runs)]
    new_tasks = [realisation(c, None, config.seed + i, i == 0, f"{c.name} before wear #{i}")
                 for c in cases for i in range(config.realisations)]
    groups: dict[tuple[str, str], list[list]] = {}
    with compute_client(config.scheduler, config.workers):
        done = run_tasks(wear_tasks + new_tasks, progress="study: wear runs, new surfaces")
        _raise_failures(done[:len(wear_tasks)], f"study of {bench.name}: wear runs")
        runs = {c.name: done[i * config.wear_runs:(i + 1) * config.wear_runs] for i, c in enumerate(cases)}
        new = done[len(wear_tasks):]
        for i, c in enumerate(cases):
            groups[(c.name, "before wear")] = [new[i * config.realisations:(i + 1) * config.realisations]]
        worn_tasks, owners = [], []
        for c in cases:
            for w, run in enumerate(runs[c.name]):
                for label, surfaces in run.states[1:]:
                    for i in range(config.per_run):
                        worn_tasks.append(realisation(c, surfaces, config.seed + w * config.per_run + i,
                                                      w == 0 and i == 0, f"{c.name} {label} run {w + 1} #{i}"))
                        owners.append((c.name, label, w))
        worn = run_tasks(worn_tasks, progress="study: worn surfaces")
    for (case, label, w), r in zip(owners, worn, strict=True):
        runs_of = groups.setdefault((case, label), [])
        while len(runs_of) <= w:
            runs_of.append([])
        runs_of[w].append(r)
    cells = _cells(groups, cases, joints)

    stats = {(c.case.name, c.state): cell_statistics(c, config.level) for c in cells}
    wear = pd.DataFrame(_wear_rows(runs, cases))
    depth = _depth_runs(wear)
    tr = trends(stats, depth, config, joints)

    for c in cases:
        folder = out / ("wear" if c is config.wear_case else f"clearance_{c.clearance * 1e3:g}mm")
        for w, run in enumerate(runs[c.name]):
            write_run(run, folder if w == 0 else folder / f"run{w + 1}", plots=w == 0)
    figures = out / "figures"
    figures.mkdir(exist_ok=True)
    kept = {}
    for (case, label), runs_of in groups.items():
        first = runs_of[0][0]
        if not isinstance(first, TaskFailure):
            kept[(case, label)] = first
    for c in cases:
        if all((c.name, label) in kept for label in _labels(c)):
            result = CaseResult(c, runs[c.name][0], {lbl: kept[(c.name, lbl)]["table"] for lbl in _labels(c)},
                                {lbl: kept[(c.name, lbl)]["summary"] for lbl in _labels(c)}, 0.0)
            if c is config.wear_case:
                plot_case_dynamics(result, bench, figures)
            else:
                plot_case_dynamics(result, bench, figures, clearance_study=True, suffix=f"_{c.clearance * 1e3:g}mm")

    peak_rows = []
    for cell in cells:
        w_, m_, c_ = cell.peaks["acc"].shape
        for w in range(w_):
            for i in range(m_):
                for k in range(c_):
                    peak_rows.append({"case": cell.case.name, "clearance_mm": _mm(cell.case), "state": cell.state,
                                      "wear_run": w + 1 if cell.state != "before wear" else 0, "realisation": i,
                                      "cycle": k, **{q: float(cell.peaks[q][w, i, k]) for q in cell.peaks}})
    pd.DataFrame(peak_rows).to_csv(out / "peaks.csv", index=False)
    cell_rows = _cell_rows(cells, stats, config.wear_case)
    pd.DataFrame(cell_rows).to_csv(out / "cells.csv", index=False)
    wear.to_csv(out / "wear_runs.csv", index=False)
    t3 = table3(cell_rows)
    t3.to_csv(out / "table3.csv")
    pd.DataFrame([{k: v for k, v in t.items() if k != "comparisons"} for t in tr]).to_csv(out / "trends.csv",
                                                                                        index=False)
    counts = {v: sum(t["verdict"] == v for t in tr) for v in ("agrees", "disagrees", "not resolved")}
    task_s = {"wear_runs": round(sum(st.wall_time for rs in runs.values() for r in rs for st in r.stages), 1),
              "realisations": round(sum(float(r.get("wall_time_s") or 0.0) for rs in groups.values() for g in rs
                                        for r in g if not isinstance(r, TaskFailure)), 1)}
    summary = {
        "bench": bench.name, "wall_time_s": round(time.perf_counter() - t0, 1), "task_time_s": task_s,
        "sizes": {"realisations": config.realisations, "per_wear_run": config.per_run, "cycles": config.cycles,
                  "settle": config.settle, "wear_runs": config.wear_runs, "seed": config.seed,
                  "level": config.level,
                  "output_rate_hz": config.output_rate or 20_000.0},
        "plan": {"stage_cycles": config.plan.stage_cycles, "update_depth_m": config.plan.depth_cap,
                 "settle": config.plan.settle},
        "max_statistic": MAX_STATISTIC, "trend_counts": counts, "trends": tr, "cells": cell_rows,
        "wear_runs": wear.to_dict(orient="records"),
        "failures": {f"{c.case.name} {c.state}": c.failures for c in cells if c.failures},
    }
    (out / "table3.md").write_text(report_markdown(summary, config) + "\n")
    (out / "study.json").write_text(json.dumps(summary, indent=2, default=float) + "\n")
    return summary


def _cell_rows(cells: Sequence[Cell], stats: Mapping, wear_case: Case) -> list[dict]:
    """One row per cell, quantity and statistic: value, interval and the paper's "max" where it has one."""
    rows = []
    for cell in cells:
        w, m, c = cell.peaks["acc"].shape
        for q, by_stat in stats[(cell.case.name, cell.state)].items():
            for s, v in by_stat.items():
                rows.append({"study": "wear" if cell.case == wear_case else "clearance",
                             "case": cell.case.name, "clearance_mm": _mm(cell.case), "speed_rad_s": cell.case.speed,
                             "state": cell.state, "quantity": q, "statistic": s, "value": v["value"], "lo": v["lo"],
                             "hi": v["hi"], "units": v["units"].size, "paper_max": _paper_value(cell.case, cell.state, q),
                             "wear_runs": w if cell.state != "before wear" else 0, "realisations": w * m,
                             "cycles": w * m * c, "failures": len(cell.failures)})
    return rows


def _paper_value(case: Case, state: str, quantity: str) -> float | None:
    """The paper's published maximum for this cell, if it has one (same clearance, speed and state)."""
    labels = ["before wear", "first wear", "second wear"]
    if state not in labels:
        return None
    k = labels.index(state)
    mm, pi_speed = _mm(case), round(case.speed / math.pi, 6)
    if mm == 0.6 and pi_speed == -5:
        p = PAPER["wear_study"]
        return p["peak_slider_acc"][k] if quantity == "acc" else p["peak_fn"].get(quantity[3:], [None] * 3)[k]
    if pi_speed == -6 and k < 2:
        p = PAPER["clearance_study"]
        table = p["peak_slider_acc"] if quantity == "acc" else p["peak_fn"].get(quantity[3:], {})
        return table[mm][k] if mm in table else None
    return None


def table3(cell_rows: Sequence[dict]) -> pd.DataFrame:
    """The paper's Table 3 analogue: max contact force (N, the geometric mean of the realisations' max) per
    joint, before and after wear, per clearance of the clearance study (wear cases at -6 pi rad/s)."""
    rows: dict[str, dict] = {}
    for r in cell_rows:
        if r["statistic"] != MAX_STATISTIC or not r["quantity"].startswith("fn_") or r["study"] != "clearance":
            continue
        state = "before wear" if r["state"] == "before wear" else "after wear"
        rows.setdefault(f"clearance {r['quantity'][3:]}", {})[(f"{r['clearance_mm']:g} mm", state)] = r["value"]
    df = pd.DataFrame(rows).T
    df.columns = pd.MultiIndex.from_tuples(df.columns)
    return df


def trends(stats: Mapping, depth: Mapping, config: StudyConfig, joints: Sequence[str]) -> list[dict]:
    """The paper's qualitative findings (sections 5.1, 5.2) as tests on the ensemble statistics.

    Each finding is one or more ratios that the paper has above 1 (ours: the ratio of geometric
    means, its Student-t interval, the paper's ratio): forces and accelerations compare the cells'
    units (:func:`cell_units` of the run's max, the paper's "max"): Welch between cells, paired
    over the wear runs for two stages of the same runs; depths compare the wear runs' max depths,
    paired: B against A in the same runs, and across clearances run w of each case, worn on the same
    drawn bench from the same start (seed ``seed + 100000 + w``); the depth, an accumulation over
    many cycles, follows the drawn bench, the peaks of a chaotic motion do not. A finding of k ratios takes each
    interval at level 1 - (1 - ``config.level``) / k (Bonferroni), so that the chance of a wrong
    "disagrees" (any interval below 1) stays within the level; it agrees when every interval lies
    above 1, disagrees when any lies below 1, and is not resolved otherwise.
    Returns [{finding, verdict, ours (agrees?), detail, comparisons}]."""
    s = MAX_STATISTIC
    out = []

    def ratio(what: str, num: dict, den: dict, paper: float | None, paired: bool = False) -> dict:
        return {"comparison": what, "num": num["units"], "den": den["units"], "paired": paired, "paper_ratio": paper}

    def depth_ratio(what: str, num: np.ndarray, den: np.ndarray, paired: bool, paper: float | None) -> dict:
        return {"comparison": what, "num": np.log(num), "den": np.log(den), "paired": paired, "paper_ratio": paper}

    def add(finding: str, pending: list[dict]) -> None:
        level = 1 - (1 - config.level) / len(pending)
        comparisons, parts = [], []
        for c in pending:
            parts.append(_t_parts(c["num"], c["den"], c["paired"]))
            d, lo, hi = _t_interval(c["num"], c["den"], c["paired"], level)
            r, lo, hi = math.exp(d), math.exp(lo), math.exp(hi)
            comparisons.append({"comparison": c["comparison"], "ratio": r, "lo": lo, "hi": hi, "level": level,
                                "paper_ratio": c["paper_ratio"], "verdict": verdict(lo, hi)})
        v = _combine([c["verdict"] for c in comparisons])
        detail = "; ".join(f"{c['comparison']} {c['ratio']:.2f} [{c['lo']:.2f}, {c['hi']:.2f}]"
                           + (f" (paper {c['paper_ratio']:.2f})" if c["paper_ratio"] else "") for c in comparisons)
        rerun = replication(parts, level)
        out.append({"finding": finding, "paper": True, "verdict": v, "ours": v == "agrees", "detail": detail,
                    "replication": rerun[v], "size_for_90": rerun["size_for_90"], "comparisons": comparisons})

    def paper_ratio(a: float | None, b: float | None) -> float | None:
        return a / b if a and b else None

    wc = config.wear_case
    labels = _labels(wc)
    pw = PAPER["wear_study"]
    pairs = list(itertools.pairwise(labels))
    add("wear raises the peak slider acceleration, second wear more than first",
        [ratio(f"{b} / {a}", stats[(wc.name, b)]["acc"][s], stats[(wc.name, a)]["acc"][s],
               paper_ratio(_paper_value(wc, b, "acc"), _paper_value(wc, a, "acc")), a != labels[0])
         for a, b in pairs])
    for j in joints:
        q = f"fn_{j}"
        add(f"wear raises the peak contact force at {j}",
            [ratio(f"{b} / {a}", stats[(wc.name, b)][q][s], stats[(wc.name, a)][q][s],
                   paper_ratio(_paper_value(wc, b, q), _paper_value(wc, a, q)), a != labels[0]) for a, b in pairs])
    if {"A", "B"} <= set(joints):
        last = labels[-1]
        pd_ = pw["max_depth"]
        add(f"B wears deeper than A (after {last})",
            [depth_ratio(f"depth B / A after {last}", depth[(wc.name, last)]["B"], depth[(wc.name, last)]["A"], True,
                   pd_["B"][-1] / pd_["A"][-1] if wc.stages == len(pd_["A"]) else None)])
    cl = sorted(config.clearance_cases, key=lambda c: c.clearance)
    pc = PAPER["clearance_study"]

    def paper_depth(j: str, c: Case) -> float | None:
        return pc["max_depth"].get(j, {}).get(_mm(c)) if round(c.speed / math.pi, 6) == -6 else None

    for j in joints:
        q = f"fn_{j}"
        add(f"contact force at {j} grows after wear at every clearance",
            [ratio(f"{_mm(c):g} mm after / before", stats[(c.name, 'first wear')][q][s],
                   stats[(c.name, 'before wear')][q][s],
                   paper_ratio(_paper_value(c, "first wear", q), _paper_value(c, "before wear", q))) for c in cl])
        add(f"contact force at {j} after wear grows with clearance",
            [ratio(f"{_mm(b):g} / {_mm(a):g} mm", stats[(b.name, 'first wear')][q][s],
                   stats[(a.name, 'first wear')][q][s],
                   paper_ratio(_paper_value(b, "first wear", q), _paper_value(a, "first wear", q)))
             for a, b in itertools.pairwise(cl)])
        add(f"wear depth at {j} grows with clearance",
            [depth_ratio(f"{_mm(b):g} / {_mm(a):g} mm", depth[(b.name, "first wear")][j],
                         depth[(a.name, "first wear")][j], True, paper_ratio(paper_depth(j, b), paper_depth(j, a)))
             for a, b in itertools.pairwise(cl)])
    add("peak slider acceleration after wear grows with clearance",
        [ratio(f"{_mm(b):g} / {_mm(a):g} mm", stats[(b.name, 'first wear')]["acc"][s],
               stats[(a.name, 'first wear')]["acc"][s],
               paper_ratio(_paper_value(b, "first wear", "acc"), _paper_value(a, "first wear", "acc")))
         for a, b in itertools.pairwise(cl)])
    return out


def _cell(v: float, lo: float, hi: float, paper: float | None, digits: int = 0) -> str:
    f = f"{{:.{digits}f}}"
    text = f"{f.format(v)} [{f.format(lo)}, {f.format(hi)}]"
    return text + (f" / {paper:g}" if paper else "")


def _size(factor: float) -> str:
    return "beyond 1000x" if not math.isfinite(factor) else "met" if factor <= 1 else f"{factor:.1f}x"


def report_markdown(summary: dict, config: StudyConfig) -> str:
    """The study's report: Table 3 analogue and wear study with intervals beside the paper's values,
    the spread of the wear runs, and the verdict on each of the paper's trends."""
    rows = pd.DataFrame(summary["cells"])
    sz = summary["sizes"]
    pct = f"{100 * config.level:g} %"
    lines = [(f"Study of {summary['bench']}: {sz['realisations']} realisations per state (after wear {sz['per_wear_run']} "
             f"on each of {sz['wear_runs']} wear runs) x {sz['cycles']} cycles, seed {sz['seed']}. Cells: the geometric "
             f"mean over the realisations of each one's max (the largest of its per-cycle maxima: the paper's \"max\" of "
             f"one run) and of its median per-cycle maximum, each [{pct} Student-t interval; after wear over the wear "
             f"runs] / the paper's max."), ""]
    clear = rows[rows["study"] == "clearance"]
    cases = list(dict.fromkeys(clear["case"]))
    for stat in STATISTICS:
        for q, what in [(q, f"contact force {q[3:]} (N)") for q in sorted(set(clear["quantity"])) if q != "acc"] + [
                ("acc", "slider |acceleration| (m/s^2)")]:
            sub = clear[(clear["quantity"] == q) & (clear["statistic"] == stat)]
            lines += [f"Clearance study, {what}, {stat} of per-cycle maxima", "",
                      "| clearance | before wear | after wear |", "|---|---|---|"]
            for case in cases:
                r = sub[sub["case"] == case]
                cells = [_cell(x.value, x.lo, x.hi, x.paper_max if stat == MAX_STATISTIC else None)
                         for x in r.itertuples()]
                lines.append(f"| {case} | " + " | ".join(cells) + " |")
            lines.append("")
    wear = rows[(rows["study"] == "wear") & (rows["statistic"] == MAX_STATISTIC)]
    qs = list(dict.fromkeys(wear["quantity"]))
    lines += [(f"Wear study ({config.wear_case.name}, {config.wear_case.speed / math.pi:g} pi rad/s), max of a run "
              "[interval] / paper"), "", "| state | " + " | ".join(
                  "slider acc (m/s^2)" if q == "acc" else f"force {q[3:]} (N)" for q in qs) + " |",
              "|---" * (len(qs) + 1) + "|"]
    for state in dict.fromkeys(wear["state"]):
        r = wear[wear["state"] == state].set_index("quantity")
        lines.append(f"| {state} | " + " | ".join(_cell(r.loc[q, "value"], r.loc[q, "lo"], r.loc[q, "hi"],
                                                         r.loc[q, "paper_max"]) for q in qs) + " |")
    wr = pd.DataFrame(summary["wear_runs"])
    lines += ["", (f"Wear runs ({sz['wear_runs']} per case, each from its own drawn bench and start): max depth (um) "
              "and worn volume (mm^3) per joint, mean and [min, max] over the runs"), "",
              "| case | state | joint | max depth (um) | worn volume (mm^3) |", "|---|---|---|---|---|"]
    for (case, state, joint), g in wr.groupby(["case", "state", "joint"], sort=False):
        d, v = g["max_depth_m"] * 1e6, g["volume_m3"] * 1e9
        lines.append(f"| {case} | {state} | {joint} | {d.mean():.1f} [{d.min():.1f}, {d.max():.1f}] | "
                     f"{v.mean():.1f} [{v.min():.1f}, {v.max():.1f}] |")
    c = summary["trend_counts"]
    lines += ["", (f"The paper's findings on our bench (intervals of the ratios at {pct} shared out over each finding's "
              f"ratios; a finding agrees when every interval lies above 1, disagrees when one lies below 1): "
              f"{c['agrees']} agree, {c['disagrees']} disagree, {c['not resolved']} not resolved at this size"), "",
              ("A rerun of this size repeats a verdict with the probability in the third column (Goodman's "
               "replication probability: the rerun's estimates predicted from this run's); the fourth is the "
               "factor on the ensemble at which a rerun resolves the finding the way its estimates point "
               "in 9 of 10 reruns, were the true ratios these estimates."), "",
              "| finding | verdict | rerun repeats it | size for 9 in 10 | ours: ratio [interval] (paper's ratio) |",
              "|---|---|---|---|---|"]
    lines += [f"| {t['finding']} | {t['verdict']} | {t['replication']:.2f} | {_size(t['size_for_90'])} | {t['detail']} |"
              for t in summary["trends"]]
    if summary["failures"]:
        lines += ["", "Failed realisations (left out): " + "; ".join(
            f"{k}: {len(v)}" for k, v in summary["failures"].items())]
    return "\n".join(lines)
