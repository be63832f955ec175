"""Parameter sweeps of a bench: a grid of operating points, optional wear stages and realisations per
point, one task per (point, realisation) on :mod:`wearbench.compute`, a tidy results table.

A sweep varies parameters of :data:`PARAMETERS` ("clearance", "clearance.<joint>", "speed",
"wear_coefficient") over given values; each run wears the point's clearance joints for ``stages``
stages (none: the unworn bench) and simulates the dynamics of every state (before wear, after each
stage), keeping the statistics of :data:`STATISTICS` after ``settle`` revolutions. A realisation
with a seed is the bench drawn within its tolerances (:func:`~wearbench.model.realisation.draw_realisation`:
masses, inertias, geometry, friction, restitution, true motor speed); without one, the nominal
bench. Imports the model contract, its wear and realisation modules, the compute layer, and
matplotlib in :func:`plot_sweep` only; no CLI code.
"""

from __future__ import annotations

import itertools
import math
import re
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields, replace
from pathlib import Path

import numpy as np
import pandas as pd
from wearbench.bench.content import bench_key
from wearbench.bench.units import QuantityError, parse_quantity
from wearbench.compute import Task, TaskFailure, run_tasks, task_key
from wearbench.model.wear_stages import StagePlan
from wearbench.studies import tasks_source_digest

__all__ = ["PARAMETERS", "STATISTICS", "Axis", "Parameter", "SweepResult", "SweepSpec", "format_value",
           "parse_axis", "plot_sweep", "run_point", "run_sweep"]


@dataclass(frozen=True)
class Parameter:
    """A sweepable parameter: its dimension (bench/units.py), printed unit and table column."""

    dimension: str
    unit: str        # printed (plots, reports)
    column: str      # SI column of the results table
    bare_unit: str | None = None  # unit of a bare number, where one is unambiguous


PARAMETERS: dict[str, Parameter] = {
    "clearance": Parameter("length", "mm", "clearance_m"),  # every clearance joint
    "speed": Parameter("angular_speed", "rad/s", "speed_rad_s", bare_unit="rad/s"),
    "wear_coefficient": Parameter("wear_coefficient", "1/Pa", "wear_coefficient_1_Pa", bare_unit="1/Pa"),
}
_JOINT_CLEARANCE = re.compile(r"^clearance\.(?P<joint>\w+)$")  # one joint's clearance

# statistic -> unit; "<joint>" stands for each clearance joint
STATISTICS: dict[str, str] = {"peak_slider_acc": "m/s^2", "rms_slider_acc": "m/s^2", "peak_fn_<joint>": "N",
                              "max_depth_<joint>": "m"}


def parameter(name: str) -> Parameter:
    """The :class:`Parameter` of ``name`` ("clearance.A" is joint A's clearance)."""
    if name in PARAMETERS:
        return PARAMETERS[name]
    m = _JOINT_CLEARANCE.match(name)
    if m:
        return Parameter("length", "mm", f"clearance_{m['joint']}_m")
    raise ValueError(f"unknown parameter {name!r}; expected one of {[*PARAMETERS, 'clearance.<joint>']}")


@dataclass(frozen=True)
class Axis:
    """One varied parameter and its values (SI)."""

    name: str
    values: tuple[float, ...]

    @property
    def parameter(self) -> Parameter:
        return parameter(self.name)


def parse_axis(text: str) -> Axis:
    """``"clearance=0.1mm..0.6mm:6"`` (6 values, ends included), ``"speed=-6pi..-4pi:5"`` or a list
    ``"clearance=0.1mm,0.3mm,0.45mm"`` -> :class:`Axis` in SI."""
    name, eq, spec = text.partition("=")
    name = name.strip()
    if not eq or not spec.strip():
        raise ValueError(f"--vary {text!r}: expected NAME=FROM..TO:COUNT or NAME=V1,V2,... "
                         "(e.g. clearance=0.1mm..0.6mm:6)")
    try:
        par = parameter(name)
    except ValueError as exc:
        raise ValueError(f"--vary {text!r}: {exc}") from None

    def value(v: str) -> float:
        try:
            return parse_quantity(v.strip(), par.dimension, bare_unit=par.bare_unit)
        except QuantityError as exc:
            raise ValueError(f"--vary {text!r}: {exc}") from None

    if ".." in spec:
        span, colon, count = spec.rpartition(":")
        if not colon:
            raise ValueError(f"--vary {text!r}: a range needs a count, e.g. {name}={spec}:5")
        lo, _, hi = span.partition("..")
        try:
            n = int(count)
        except ValueError:
            n = 0
        if n < 1:
            raise ValueError(f"--vary {text!r}: count {count!r}: expected a whole number >= 1")
        a, b = value(lo), value(hi)
        values = (a,) if n == 1 else tuple(float(x) for x in np.linspace(a, b, n))
    else:
        values = tuple(value(v) for v in spec.split(","))
    if len(set(values)) != len(values):
        raise ValueError(f"--vary {text!r}: values repeat")
    return Axis(name, values)


@dataclass(frozen=True)
class SweepSpec:
    """What to run at every grid point: ``stages`` wear stages of ``plan`` (0: unworn only),
    ``realisations`` per point (1: the nominal bench; more: seeds ``seed``, ``seed`` + 1, ...), and
    a dynamics run of ``settle`` + ``revolutions`` motor revolutions per state."""

    axes: tuple[Axis, ...]
    stages: int = 0
    realisations: int = 1
    seed: int = 0
    plan: StagePlan = field(default_factory=StagePlan)
    revolutions: float = 5.0
    settle: float = 1.0
    output_rate: float | None = 5_000.0  # Hz of the dynamics table (peak slider acc is taken on it)

    def __post_init__(self) -> None:
        names = [a.name for a in self.axes]
        if not names or len(set(names)) != len(names):
            raise ValueError(f"sweep axes {names}: expected at least one, each parameter once")
        if self.stages < 0 or self.realisations < 1:
            raise ValueError(f"wear stages = {self.stages}, realisations = {self.realisations}: expected "
                             "stages >= 0 and realisations >= 1")
        if not self.revolutions > 0 or self.settle < 0:
            raise ValueError(f"revolutions = {self.revolutions}, settle = {self.settle}: expected > 0 and >= 0")

    @property
    def seeds(self) -> list[int | None]:
        return [None] if self.realisations == 1 else list(range(self.seed, self.seed + self.realisations))

    def points(self) -> list[dict[str, float]]:
        """Every combination of the axes' values, the first axis slowest."""
        return [dict(zip([a.name for a in self.axes], combo, strict=True))
                for combo in itertools.product(*(a.values for a in self.axes))]


def _apply(bench, values: Mapping[str, float], plan: StagePlan):
    """(clearances {joint: m} or None, speed rad/s, plan) of one grid point. Overlapping axes follow
    one rule, whatever their order: ``clearance.J`` sets joint J over ``clearance`` (every joint)."""
    names = [j.name for j in bench.clearance_joints]
    clear: dict[str, float] = dict.fromkeys(names, values["clearance"]) if "clearance" in values else {}
    for name, v in values.items():
        if m := _JOINT_CLEARANCE.match(name):
            if m["joint"] not in names:
                raise ValueError(f"clearance.{m['joint']}: {bench.name} has no clearance joint {m['joint']!r}; "
                                 f"it has {names}")
            clear[m["joint"]] = v
    if "wear_coefficient" in values:
        plan = replace(plan, coefficient=values["wear_coefficient"])
    return clear or None, values.get("speed", bench.speed), plan


def run_point(bench, values: Mapping[str, float], seed: int | None, spec: SweepSpec) -> list[dict]:
    """One run: the realisation ``seed`` of ``bench`` at grid point ``values`` (SI), worn for
    ``spec.stages`` stages; rows {state, statistic, value, unit} for every state."""
    from wearbench.model import build_scene, simulate
    from wearbench.model.realisation import draw_realisation
    from wearbench.model.wear_stages import run_stages

    real = draw_realisation(bench, seed)
    clear, commanded, plan = _apply(real.bench, values, spec.plan)
    speed = commanded * real.speed_scale
    if speed == 0:
        raise ValueError("speed 0 rad/s: a sweep point needs a turning motor")
    if spec.stages:
        run = run_stages(real.bench, replace(plan, stages=spec.stages), clearances=clear, speed=speed)
        states = run.states
    else:
        states = [("before wear", None)]
    t_settle = spec.settle * 2 * math.pi / abs(speed)
    rows = []
    for label, surfaces in states:
        scene = build_scene(real.bench, clearances=clear, surfaces=surfaces)
        res = simulate(scene, revolutions=spec.settle + spec.revolutions, speed=speed, method=plan.method,
                       output_rate=spec.output_rate, record_contacts=True)
        kept = res.table[res.table["t"] >= t_settle - 1e-12]
        acc = kept["slider_acc"].to_numpy()
        stats = [("peak_slider_acc", float(np.max(np.abs(acc))), "m/s^2"),
                 ("rms_slider_acc", float(np.sqrt(np.mean(acc**2))), "m/s^2")]
        for j, c in (res.contacts or {}).items():
            fn = c["fn"].to_numpy()[c["t"].to_numpy() >= t_settle - 1e-12]
            stats.append((f"peak_fn_{j}", float(fn.max()) if fn.size else 0.0, "N"))
            if surfaces is not None:
                stats.append((f"max_depth_{j}", float(max(surfaces[j].max_depth)), "m"))
        rows += [{"state": label, "statistic": s, "value": v, "unit": u} for s, v, u in stats]
    return rows


@dataclass
class SweepResult:
    """The tidy table (one row per run, state and statistic), the failed runs, and the wall time."""

    table: pd.DataFrame
    failures: list[tuple[dict, TaskFailure]]  # (run row: run, parameters, realisation, seed), failure
    wall_time: float

    def failures_table(self) -> pd.DataFrame:
        return pd.DataFrame([{**run, "error": f.error} for run, f in self.failures])


def run_sweep(bench, spec: SweepSpec, *, workers: int | None = None, scheduler: str | None = None,
              progress: str | None = None, cache: bool = True) -> SweepResult:
    """Run every (grid point, realisation) of ``spec`` as a task; see :func:`run_point`.

    Table columns: run, one SI column per varied parameter (``Parameter.column``), realisation, seed
    (-1: nominal), state, statistic, value, unit. Failed runs are listed, never hiding the others.
    """
    t0 = time.perf_counter()
    part = bench_key(bench)  # what the bench is, not where its file lies
    # the key is the computation: the point's applied clearances, speed and plan, not its axis names
    how = {f.name: getattr(spec, f.name) for f in fields(spec)
           if f.name not in ("axes", "realisations", "seed", "plan")}
    runs, tasks = [], []
    for point in spec.points():
        for r, seed in enumerate(spec.seeds):
            run = {"run": len(runs), **{parameter(n).column: v for n, v in point.items()},
                   "realisation": r, "seed": -1 if seed is None else seed}
            runs.append(run)
            label = " ".join(f"{n}={format_value(n, v)}" for n, v in point.items()) + (f" seed={seed}" if seed is not None
                                                                                  else "")
            tasks.append(Task(run_point, {"bench": bench, "values": point, "seed": seed, "spec": spec},
                              task_key("sweep-point", tasks_source_digest(run_point, _apply), part, _apply(bench, point, spec.plan),
                                       seed, how), label))
    results = run_tasks(tasks, workers=workers, scheduler=scheduler, progress=progress, cache=cache)
    rows, failures = [], []
    for run, res in zip(runs, results, strict=True):
        if isinstance(res, TaskFailure):
            failures.append((run, res))
        else:
            rows += [{**run, **row} for row in res]
    columns = ["run", *(a.parameter.column for a in spec.axes), "realisation", "seed", "state", "statistic",
               "value", "unit"]
    return SweepResult(pd.DataFrame(rows, columns=columns), failures, time.perf_counter() - t0)


def format_value(name: str, si: float) -> str:
    """A parameter's SI value in its printed unit, e.g. ``0.3mm``."""
    p = parameter(name)
    from wearbench.bench.units import UNITS

    return f"{si / UNITS[p.dimension][p.unit]:.4g}{p.unit}"


def plot_sweep(result: SweepResult, spec: SweepSpec, out: str | Path) -> list[Path]:
    """One PNG per statistic under ``out``: the statistic against the first varied parameter (mean
    over realisations, min-max band), one line per value of the second, one panel per state."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from wearbench.bench.units import UNITS

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    df = result.table
    if df.empty:
        return []
    x_axis = spec.axes[0]
    xp = x_axis.parameter
    x_scale = UNITS[xp.dimension][xp.unit]
    group_axis = spec.axes[1] if len(spec.axes) > 1 else None
    states = list(dict.fromkeys(df["state"]))
    paths = []
    for stat, sdf in df.groupby("statistic", sort=True):
        fig, axes = plt.subplots(1, len(states), figsize=(4.2 * len(states), 3.4), squeeze=False, sharey=True)
        for ax, state in zip(axes[0], states, strict=True):
            d = sdf[sdf["state"] == state]
            groups = [(None, d)] if group_axis is None else list(d.groupby(group_axis.parameter.column))
            for g, gd in groups:
                agg = gd.groupby(xp.column)["value"].agg(["mean", "min", "max"]).sort_index()
                x = agg.index.to_numpy() / x_scale
                label = None if g is None else format_value(group_axis.name, g)
                line, = ax.plot(x, agg["mean"], marker="o", ms=3, label=label)
                if spec.realisations > 1:
                    ax.fill_between(x, agg["min"], agg["max"], color=line.get_color(), alpha=0.2, lw=0)
            ax.set_title(state, fontsize=9)
            ax.set_xlabel(f"{x_axis.name} ({xp.unit})")
            ax.grid(alpha=0.3)
        axes[0][0].set_ylabel(f"{stat} ({sdf['unit'].iloc[0]})")
        if group_axis is not None:
            axes[0][-1].legend(title=group_axis.name, fontsize=7, title_fontsize=8)
        fig.tight_layout()
        path = out / f"{stat}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths


def write_sweep(result: SweepResult, spec: SweepSpec, out: str | Path, *, plots: bool = True) -> dict:
    """Write ``sweep.parquet``, ``failures.csv`` (if any) and the figures under ``out/plots``;
    return a summary dict (also written as ``sweep.json``)."""
    import json

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    result.table.to_parquet(out / "sweep.parquet", index=False)
    failures = result.failures_table()
    if not failures.empty:
        failures.to_csv(out / "failures.csv", index=False)
    figures = plot_sweep(result, spec, out / "plots") if plots else []
    summary = {"axes": {a.name: list(a.values) for a in spec.axes}, "stages": spec.stages,
               "realisations": spec.realisations, "runs": int(result.table["run"].nunique()) + len(result.failures),
               "failed": len(result.failures), "rows": len(result.table), "wall_time_s": round(result.wall_time, 2),
               "failures": failures.to_dict(orient="records"), "figures": [p.name for p in figures]}
    (out / "sweep.json").write_text(json.dumps(summary, indent=2, default=float) + "\n")
    return summary


def axes_from(texts: Sequence[str]) -> tuple[Axis, ...]:
    """:func:`parse_axis` of each ``--vary`` text."""
    return tuple(parse_axis(t) for t in texts)
