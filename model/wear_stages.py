"""Wear stages (paper section 4.3): simulate some crank cycles, accumulate Archard wear, scale it to
a stage, rebuild both surfaces, repeat. Also finer staging and its convergence, and summaries.

Wires :mod:`wearbench.model.wear` (pure laws) to ``build_scene``/``simulate``; imports the model's
public contract only, never its internals, and no plotting or CLI code.

Cost control: the paper accumulates 100 simulated cycles and multiplies by 2000. ``sim_cycles``
may be set lower, after ``settle`` revolutions that are simulated but not counted (the start
transient); the scale factor becomes stage cycles / ``sim_cycles`` so the stage still represents
its stated number of cycles.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
from wearbench.model.surfaces import JointSurfaces
from wearbench.model.wear import WearLaw, accumulate_wear, sliding_distance, worn_volume

__all__ = [
    "Stage",
    "StagePlan",
    "WearRun",
    "convergence",
    "joint_summary",
    "run_stages",
    "stage_label",
    "wear_zones",
]

_TABLE_RATE = 500.0  # Hz: output table of a wear simulation (peak slider acc there is indicative only)
_ORDINALS = ("first", "second", "third", "fourth", "fifth", "sixth", "seventh", "eighth", "ninth", "tenth")


def stage_label(k: int) -> str:
    """"first wear", "second wear", ... for stage ``k`` (1-based); "wear stage k" beyond ten."""
    return f"{_ORDINALS[k - 1]} wear" if 1 <= k <= len(_ORDINALS) else f"wear stage {k}"


@dataclass(frozen=True)
class StagePlan:
    """How to wear: ``stages`` stages of ``stage_cycles`` crank cycles each, every stage simulated
    for ``settle`` uncounted + ``sim_cycles`` counted revolutions and scaled by
    ``stage_cycles / sim_cycles``. ``sliding``/``footprint``: see :class:`WearLaw`.
    """

    stages: int = 2
    stage_cycles: float = 200_000.0
    sim_cycles: float = 100.0
    settle: float = 0.0
    method: str = "default"
    sliding: str = "rotation"
    footprint: str = "hertz"
    split: float | None = None  # None: the bench's [wear] split
    coefficient: float | None = None  # K_n (1/Pa); None: the bench's [wear] coefficient

    def __post_init__(self) -> None:
        if self.stages < 1:
            raise ValueError(f"stages = {self.stages}: expected at least 1")
        if not self.stage_cycles > 0:
            raise ValueError(f"stage cycles = {self.stage_cycles}: expected > 0")
        if not self.sim_cycles > 0:
            raise ValueError(f"simulated cycles = {self.sim_cycles}: expected > 0")
        if self.settle < 0:
            raise ValueError(f"settle revolutions = {self.settle}: expected >= 0")
        if self.coefficient is not None and not self.coefficient >= 0:
            raise ValueError(f"wear coefficient = {self.coefficient}: expected K_n >= 0 (1/Pa)")

    @classmethod
    def from_bench(cls, bench, **overrides) -> StagePlan:
        """The bench's [wear] settings (cycles_per_stage x stage_scale per stage), then overrides."""
        kw = {"stage_cycles": bench.wear.cycles_per_stage * bench.wear.stage_scale,
                  "sim_cycles": float(bench.wear.cycles_per_stage)}
        kw.update({k: v for k, v in overrides.items() if v is not None})
        return cls(**kw)

    @property
    def scale(self) -> float:
        return self.stage_cycles / self.sim_cycles


@dataclass
class Stage:
    """One wear stage: the simulation on the surfaces it started from, and the surfaces after it."""

    index: int                              # 1-based
    label: str
    start: dict[str, JointSurfaces]         # surfaces the stage was simulated on
    increment: dict[str, JointSurfaces]     # wear of this stage (already scaled)
    surfaces: dict[str, JointSurfaces]      # start + increment, labelled
    sim_summary: dict                       # the simulation's summary (on the start surfaces)
    counted_time: float                     # s of simulated time whose contacts were counted
    volume: dict[str, float]                # worn volume of the increment per joint, m^3
    archard_volume: dict[str, float]        # K_n sum(F dS) x scale per joint, m^3
    wall_time: float


@dataclass
class WearRun:
    """A sequence of stages on one bench at one operating point."""

    bench_name: str
    speed: float
    clearances: dict[str, float]
    plan: StagePlan
    initial: dict[str, JointSurfaces]
    stages: list[Stage] = field(default_factory=list)

    @property
    def states(self) -> list[tuple[str, dict[str, JointSurfaces]]]:
        """(label, surfaces) for the initial state and after each stage."""
        first = "before wear" if all(s.cycles == 0 for s in self.initial.values()) else "initial"
        return [(first, self.initial)] + [(s.label, s.surfaces) for s in self.stages]

    @property
    def final(self) -> dict[str, JointSurfaces]:
        return self.stages[-1].surfaces if self.stages else self.initial


def _clearances(bench, clearances: Mapping[str, float | None] | None) -> dict[str, float]:
    worn = bench.with_clearances(clearances) if clearances else bench
    return {j.name: j.clearance.radial_clearance for j in worn.clearance_joints}


def run_stages(bench, plan: StagePlan | None = None, *, clearances: Mapping[str, float] | None = None,
               speed: float | None = None, initial: Mapping[str, JointSurfaces] | None = None,
               on_stage: Callable[[Stage], None] | None = None) -> WearRun:
    """Wear the clearance joints of ``bench`` stage by stage (paper section 4.3, Fig. 5).

    clearances: {joint: m} overrides; speed: motor speed (rad/s, default the bench's);
    initial: surfaces to start from (default unworn, ``bench.wear.regions`` regions).
    Each stage: build the scene on the current surfaces, simulate ``plan.settle + plan.sim_cycles``
    motor revolutions recording contacts, accumulate wear over the counted part, multiply by
    ``plan.scale``, add to both surfaces. Raises the model's ``SimulationError`` unchanged.
    """
    from wearbench.model import build_scene, simulate

    plan = plan or StagePlan.from_bench(bench)
    speed = bench.speed if speed is None else float(speed)
    if speed == 0:
        raise ValueError("wear stages: speed = 0 rad/s: the mechanism must turn to wear")
    clear = _clearances(bench, clearances)
    if not clear:
        raise ValueError(f"{bench.name}: no clearance joints, nothing to wear")
    geometry = bench.with_clearances(clear)
    overrides = {k: v for k, v in (("split", plan.split), ("coefficient", plan.coefficient)) if v is not None}
    laws = {j: WearLaw.from_bench(geometry, j, sliding=plan.sliding, footprint=plan.footprint, **overrides)
            for j in clear}
    n = bench.wear.regions
    current = {j: (initial or {}).get(j) or JointSurfaces.unworn(n) for j in clear}
    for j, s in current.items():
        if s.bearing.size != s.journal.size:
            raise ValueError(f"joint {j}: bearing has {s.bearing.size} regions, journal {s.journal.size}")
    run = WearRun(bench.name, speed, clear, plan, dict(current))
    period = 2 * math.pi / abs(speed)
    t_count = plan.settle * period
    for k in range(1, plan.stages + 1):
        t0 = time.perf_counter()
        scene = build_scene(bench, clearances=clear, surfaces=current)
        # coarse table (the wear needs only the per-step contact record): saves memory and time
        result = simulate(scene, revolutions=plan.settle + plan.sim_cycles, speed=speed,
                          method=plan.method, record_contacts=True, output_rate=_TABLE_RATE)
        summary = dict(result.summary)
        summary["peak_fn"] = {j: float(result.contacts[j]["fn"].max()) for j in clear}  # every step
        label = stage_label(k)
        increment, after, volume, archard = {}, {}, {}, {}
        for j in clear:
            rec = result.contacts[j]
            rec = rec[rec["t"].to_numpy() >= t_count - 1e-12]
            law = laws[j]
            inc = accumulate_wear(rec, law, current[j].bearing.size, cycles=plan.sim_cycles)
            inc = inc.scaled(plan.scale, label=label)
            increment[j] = inc
            after[j] = current[j] + inc
            after[j].label = label
            after[j].meta = {"joint": j, "bench": bench.name, "speed_rad_s": f"{speed:.6g}",
                             "clearance_m": f"{clear[j]:.6g}", "sliding": plan.sliding,
                             "footprint": plan.footprint, "split": f"{law.split:g}",
                             "coefficient_per_pa": f"{law.coefficient:.6g}"}
            volume[j] = worn_volume(inc, law)
            fn = np.maximum(rec["fn"].to_numpy(), 0.0)
            ds = sliding_distance(rec["dt"].to_numpy(), rec["omega_rel"].to_numpy(), rec["vt"].to_numpy(),
                                  law.bearing_radius, plan.sliding)
            archard[j] = float(law.coefficient * np.sum(fn * ds) * plan.scale)  # eq. 15: V = K_n F S
        stage = Stage(k, label, current, increment, after, summary,
                      float(plan.sim_cycles * period), volume, archard, time.perf_counter() - t0)
        run.stages.append(stage)
        current = after
        if on_stage is not None:
            on_stage(stage)
    return run


def wear_zones(depth: np.ndarray, fraction: float = 0.1, min_gap_deg: float = 5.0,
               min_width_deg: float = 2.0) -> list[tuple[float, float]]:
    """Angular zones (deg, start, end in [0, 360]) where ``depth`` exceeds ``fraction`` of its max.

    Like the paper's "[0 deg, 110 deg], [200 deg, 272 deg]" (section 5.1): zones separated by gaps
    narrower than ``min_gap_deg`` are merged, zones narrower than ``min_width_deg`` dropped. A zone
    crossing 0 deg is reported as two ([0, b] and [a, 360]) as the paper does. Empty if unworn.
    """
    peak = float(depth.max()) if depth.size else 0.0
    if peak <= 0:
        return []
    width = 360.0 / depth.size
    idx = np.flatnonzero(depth > fraction * peak)
    zones: list[list[float]] = []
    for i in idx:
        lo, hi = i * width, (i + 1) * width
        if zones and lo - zones[-1][1] < min_gap_deg:
            zones[-1][1] = hi
        else:
            zones.append([lo, hi])
    keep = [z for z in zones if z[1] - z[0] >= min_width_deg or z[0] == 0.0 or z[1] >= 360.0 - 1e-9]
    return [(round(float(a), 1), round(float(b), 1)) for a, b in keep]


def joint_summary(s: JointSurfaces, fraction: float = 0.1) -> dict:
    """Max depth (m), its angle (deg) and wear zones per surface of one joint's state."""
    out = {"label": s.label, "cycles": s.cycles}
    n = s.bearing.size
    for side in ("bearing", "journal"):
        d = getattr(s, side)
        i = int(np.argmax(d))
        out[side] = {"max_depth_m": float(d[i]), "max_at_deg": round((i + 0.5) * 360.0 / n, 2),
                     "zones_deg": wear_zones(d, fraction)}
    return out


def convergence(runs: Mapping[int, WearRun], joints: list[str] | None = None) -> list[dict]:
    """Compare the final surfaces of runs with different numbers of stages for the same total cycles.

    ``runs``: {number of stages: WearRun}. The run with the most stages is the reference. Per run
    and joint: max depth of bearing and journal, and the RMS and max of the depth difference
    against the reference relative to the reference's max depth.
    """
    ref_k = max(runs)
    ref = runs[ref_k].final
    rows = []
    for k in sorted(runs):
        fin = runs[k].final
        for j in joints or sorted(fin):
            row = {"stages": k, "stage_cycles": runs[k].plan.stage_cycles, "joint": j,
                   "total_cycles": fin[j].cycles}
            for side in ("bearing", "journal"):
                d, r = getattr(fin[j], side), getattr(ref[j], side)
                peak = max(float(r.max()), 1e-300)
                row[f"{side}_max_m"] = float(d.max())
                row[f"{side}_rms_diff_rel"] = float(np.sqrt(np.mean((d - r) ** 2)) / peak)
                row[f"{side}_max_diff_rel"] = float(np.max(np.abs(d - r)) / peak)
            rows.append(row)
    return rows
