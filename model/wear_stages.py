"""Wear stages (paper section 4.3) worn by short surface updates inside one continuous simulation,
their convergence under refinement at a fixed cycle count, and summaries.

Wires :mod:`wearbench.model.wear` (pure laws) to ``build_scene``/``simulate``; imports the model's
public contract only, never its internals, and no plotting or CLI code.

How the surfaces evolve (after the wear-in-joints studies: Mukras et al., *Wear* 266 (2009) 822;
*J. Tribol.* 132 (2010) 021603; Podra & Andersson, *Wear* 224 (1999) 13): the mechanism runs
continuously; every ``update_revolutions`` simulated revolutions (one by default) the wear they
produced (Archard, spread over the contact arc by the elastic-foundation pressure) is taken as the
wear rate per cycle and applied for as many cycles as keep the depth added to any surface within
``update_depth / refinement`` (and at most 1/(``min_updates`` x ``refinement``) of a stage); the cap
shrinks (x 1/2, down to 1/4) when the sliding-weighted mean contact pressure changed by more than
``pressure_change`` since the previous update and grows back otherwise. The next revolution continues from the last state on the new surfaces (no settling per
update: only the first ``settle`` revolutions are not counted). Stages are checkpoints in that one
run; the cost is the number of simulated revolutions, set by how deep the joints wear, not by the
number of stages or cycles.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
from wearbench.model.surfaces import JointSurfaces, reachable_depth
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
_MIN_GAIN = 0.25  # smallest fraction of the depth cap the pressure-change control goes down to


def stage_label(k: int) -> str:
    """"first wear", "second wear", ... for stage ``k`` (1-based); "wear stage k" beyond ten."""
    return f"{_ORDINALS[k - 1]} wear" if 1 <= k <= len(_ORDINALS) else f"wear stage {k}"


@dataclass(frozen=True)
class StagePlan:
    """How to wear: ``stages`` stages of ``stage_cycles`` crank cycles each, in surface updates of at
    most ``update_depth / refinement`` (m) added depth, each simulated for ``update_revolutions``
    whole motor revolutions; ``settle`` revolutions before the first update are not counted.
    ``pressure_change``: relative change of the mean contact pressure between updates above which
    the depth cap halves. ``min_updates``: at least this many updates per stage (times
    ``refinement``), so shallow wear is still averaged over several revolutions.
    ``max_updates``: guard against a run that cannot progress.
    ``sliding``/``footprint``: see :class:`WearLaw`.
    """

    stages: int = 2
    stage_cycles: float = 200_000.0
    update_depth: float = 4e-6
    refinement: float = 1.0
    update_revolutions: int = 1
    settle: int = 1
    pressure_change: float = 0.25
    min_updates: int = 8
    max_updates: int = 20_000
    method: str = "default"
    sliding: str = "rotation"
    footprint: str = "pressure"
    split: float | None = None  # None: the bench's [wear] split
    coefficient: float | None = None  # K_n (1/Pa); None: the bench's [wear] coefficient

    def __post_init__(self) -> None:
        if self.stages < 1:
            raise ValueError(f"stages = {self.stages}: expected at least 1")
        if not self.stage_cycles > 0:
            raise ValueError(f"stage cycles = {self.stage_cycles}: expected > 0")
        if not self.update_depth > 0:
            raise ValueError(f"update depth = {self.update_depth} m: expected > 0")
        if not self.refinement > 0:
            raise ValueError(f"refinement = {self.refinement}: expected > 0")
        if int(self.update_revolutions) != self.update_revolutions or self.update_revolutions < 1:
            raise ValueError(f"revolutions per update = {self.update_revolutions}: expected a whole number >= 1")
        if int(self.settle) != self.settle or self.settle < 0:
            raise ValueError(f"settle revolutions = {self.settle}: expected a whole number >= 0")
        if self.min_updates < 1:
            raise ValueError(f"min updates = {self.min_updates}: expected at least 1 per stage")
        if not self.pressure_change > 0:
            raise ValueError(f"pressure change = {self.pressure_change}: expected > 0")
        if self.coefficient is not None and not self.coefficient >= 0:
            raise ValueError(f"wear coefficient = {self.coefficient}: expected K_n >= 0 (1/Pa)")

    @classmethod
    def from_bench(cls, bench, **overrides) -> StagePlan:
        """The bench's [wear] stage (cycles_per_stage x stage_scale cycles), then overrides."""
        kw = {"stage_cycles": bench.wear.cycles_per_stage * bench.wear.stage_scale}
        kw.update({k: v for k, v in overrides.items() if v is not None})
        return cls(**kw)

    @property
    def depth_cap(self) -> float:
        """Largest depth (m) one update adds to any surface."""
        return self.update_depth / self.refinement


@dataclass
class Stage:
    """One wear stage: the surfaces it started from, its wear and the surfaces after it."""

    index: int                              # 1-based
    label: str
    start: dict[str, JointSurfaces]         # surfaces at the start of the stage
    increment: dict[str, JointSurfaces]     # wear of this stage
    surfaces: dict[str, JointSurfaces]      # start + increment, labelled
    sim_summary: dict                       # summary of the stage's first simulated update (start surfaces)
    counted_time: float                     # s of simulated time whose contacts were counted
    volume: dict[str, float]                # worn volume of the increment per joint, m^3
    archard_volume: dict[str, float]        # K_n sum(F dS) x cycles represented, per joint, m^3
    wall_time: float
    updates: int = 0                        # surface updates in the stage
    revolutions: float = 0.0                # motor revolutions simulated in the stage (with settling)


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

    @property
    def revolutions(self) -> float:
        """Motor revolutions simulated for the whole run (its cost)."""
        return float(sum(s.revolutions for s in self.stages))


def _clearances(bench, clearances: Mapping[str, float | None] | None) -> dict[str, float]:
    worn = bench.with_clearances(clearances) if clearances else bench
    return {j.name: j.clearance.radial_clearance for j in worn.clearance_joints}


def _continue_from(scene, final) -> tuple[np.ndarray, np.ndarray] | None:
    """The state at the end of whole motor revolutions as a state at t = 0: every body angle moved
    back by the whole turns it made (cranks at integer ratios return to their start phase)."""
    if final is None:
        return None
    q, v = final[0].copy(), final[1].copy()
    turns = np.round((q[2::3] - scene.q0[2::3]) / (2 * math.pi))
    q[2::3] -= 2 * math.pi * turns
    return q, v


def _mean_pressure(rec, law: WearLaw) -> float:
    """Sliding-weighted mean Hertz pressure (Pa) of a contact record: what drives the wear rate."""
    fn = np.maximum(rec["fn"].to_numpy(float), 0.0)
    ds = sliding_distance(rec["dt"].to_numpy(float), rec["omega_rel"].to_numpy(float), rec["vt"].to_numpy(float),
                          law.bearing_radius, law.sliding)
    w = float(np.sum(ds * (fn > 0)))
    return float(np.sum(law.pressure(fn) * ds) / w) if w > 0 else 0.0


def _simulate_update(scene, plan: StagePlan, speed: float, fresh: bool, state):
    """Simulate one update: ``plan.update_revolutions`` revolutions (after ``plan.settle`` more when
    ``fresh``, the run's start) from ``state`` (None: the assembled start), recording the contacts; a run
    that cannot continue from the last state (its projection fails: driver ratios) settles afresh.
    Returns (result, settle revolutions run)."""
    from wearbench.model import SimulationError, simulate

    revs = float(plan.update_revolutions)
    settle = plan.settle if fresh else 0
    try:
        return simulate(scene, revolutions=settle + revs, speed=speed, method=plan.method, record_contacts=True,
                        output_rate=_TABLE_RATE, initial=state), settle
    except SimulationError as exc:
        if fresh or exc.quantity != "initial state":
            raise
    settle = plan.settle  # cannot continue (driver ratios): settle afresh
    return simulate(scene, revolutions=settle + revs, speed=speed, method=plan.method, record_contacts=True,
                    output_rate=_TABLE_RATE), settle


def _rates(result, laws: Mapping[str, WearLaw], current: Mapping[str, JointSurfaces], plan: StagePlan,
           counted_from: float):
    """Per joint, from the contacts recorded after ``counted_from`` (s) over ``plan.update_revolutions``
    revolutions: the wear per cycle (surfaces), the Archard volume per cycle (m^3, eq. 15) and the
    sliding-weighted mean pressure (Pa)."""
    revs = float(plan.update_revolutions)
    rate, volume_rate, pressure = {}, {}, {}
    for j, law in laws.items():
        rec = result.contacts[j]
        rec = rec[rec["t"].to_numpy() >= counted_from - 1e-12]
        inc = accumulate_wear(rec, law, current[j].bearing.size, surfaces=current[j])
        rate[j] = inc.scaled(1.0 / revs)
        fn = np.maximum(rec["fn"].to_numpy(), 0.0)
        ds = sliding_distance(rec["dt"].to_numpy(), rec["omega_rel"].to_numpy(), rec["vt"].to_numpy(),
                              law.bearing_radius, plan.sliding)
        volume_rate[j] = float(law.coefficient * np.sum(fn * ds)) / revs  # eq. 15 per cycle
        pressure[j] = _mean_pressure(rec, law)
    return rate, volume_rate, pressure


def _gain(gain: float, pressure: Mapping[str, float], last_p: Mapping[str, float] | None, plan: StagePlan) -> float:
    """The depth cap's gain after an update: halved (down to _MIN_GAIN) when the mean pressure changed by
    more than ``plan.pressure_change`` since the last update, else grown back by half (up to 1)."""
    if last_p is None:
        return gain
    change = max((abs(pressure[j] / last_p[j] - 1) for j in pressure if last_p[j] > 0), default=0.0)
    return max(_MIN_GAIN, gain / 2) if change > plan.pressure_change else min(1.0, gain * 1.5)


def _update_cycles(rate: Mapping[str, JointSurfaces], left: float, gain: float, plan: StagePlan) -> float:
    """Cycles one update represents: at most 1/(min_updates x refinement) of a stage and the depth cap
    (times the gain) at the fastest-wearing surface, the rest of the stage when only a sliver would stay."""
    peak_rate = max(max(r.max_depth) for r in rate.values())
    cycles = min(left, plan.stage_cycles / (plan.min_updates * plan.refinement))
    if peak_rate > 0:
        cycles = min(cycles, gain * plan.depth_cap / peak_rate)
    if left - cycles < 1e-6 * plan.stage_cycles:  # no sliver of a last update
        cycles = left
    return cycles


def _close_stage(run: WearRun, k: int, current: dict[str, JointSurfaces], start: Mapping[str, JointSurfaces],
                 laws: Mapping[str, WearLaw], total: Mapping[str, float], bench_name: str) -> tuple:
    """The surfaces after stage k (labelled, with their provenance) into ``current``; returns (increment,
    after, volume) per joint: the stage's wear, the surfaces after it, the increment's worn volume."""
    label, plan = stage_label(k), run.plan
    increment, after, volume = {}, {}, {}
    for j, law in laws.items():
        after[j] = JointSurfaces(current[j].bearing, current[j].journal, total[j], label,
                                 {"joint": j, "bench": bench_name, "speed_rad_s": f"{run.speed:.6g}",
                                  "clearance_m": f"{run.clearances[j]:.6g}", "sliding": plan.sliding,
                                  "footprint": plan.footprint, "split": f"{law.split:g}",
                                  "coefficient_per_pa": f"{law.coefficient:.6g}",
                                  "update_depth_m": f"{plan.depth_cap:.3g}"})
        current[j] = after[j]
        increment[j] = JointSurfaces(np.maximum(after[j].bearing - start[j].bearing, 0.0),
                                     np.maximum(after[j].journal - start[j].journal, 0.0),
                                     plan.stage_cycles, label)
        volume[j] = worn_volume(increment[j], law)
    return increment, after, volume


def run_stages(bench, plan: StagePlan | None = None, *, clearances: Mapping[str, float] | None = None,
               speed: float | None = None, initial: Mapping[str, JointSurfaces] | None = None,
               on_stage: Callable[[Stage], None] | None = None,
               on_update: Callable[[float, dict[str, JointSurfaces]], None] | None = None,
               start: tuple[np.ndarray, np.ndarray] | None = None) -> WearRun:
    """Wear the clearance joints of ``bench`` through ``plan.stages`` stages (paper section 4.3).

    clearances: {joint: m} overrides; speed: motor speed (rad/s, default the bench's);
    initial: surfaces to start from (default unworn, ``bench.wear.regions`` regions).
    One continuous simulation, surfaces updated between revolutions as the module docstring says.
    ``on_update(cycles worn so far, surfaces)`` is called after every update, ``on_stage`` after
    every stage. start: (q, v) at t = 0 of the first simulated revolution instead of the assembled
    state (a realisation's start, :func:`~wearbench.model.realisation.realisation_start`); the first
    ``plan.settle`` revolutions are still not counted. Raises the model's ``SimulationError`` unchanged.
    """
    from wearbench.model import SimulationError, build_scene

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
    revs = float(plan.update_revolutions)
    state, fresh = start, True  # fresh: the next simulation starts the run (settles first)
    gain, last_p = 1.0, None
    worn_before = {j: s.cycles for j, s in current.items()}
    for k in range(1, plan.stages + 1):
        t0 = time.perf_counter()
        start = dict(current)
        left = plan.stage_cycles
        archard = dict.fromkeys(clear, 0.0)
        updates, simulated, counted, first_summary = 0, 0.0, 0.0, None
        while left > 1e-9 * plan.stage_cycles:
            if updates >= plan.max_updates:
                raise SimulationError(f"wear stage {k}: {updates} surface updates and still {left:.6g} cycles "
                                      f"to go (cap {plan.depth_cap:.3g} m per update)", t=counted,
                                      quantity="wear update")
            scene = build_scene(bench, clearances=clear, surfaces=current)
            result, settle = _simulate_update(scene, plan, speed, fresh, state)
            state = _continue_from(scene, getattr(result, "final", None))
            fresh = state is None
            simulated += settle + revs
            counted += revs * period
            if first_summary is None:
                first_summary = dict(result.summary)
                first_summary["peak_fn"] = {j: float(result.contacts[j]["fn"].max()) for j in clear}
            rate, volume_rate, pressure = _rates(result, laws, current, plan, settle * period)
            gain = _gain(gain, pressure, last_p, plan)
            last_p = pressure
            cycles = _update_cycles(rate, left, gain, plan)
            for j in clear:
                after = current[j] + rate[j].scaled(cycles)
                after.cycles = current[j].cycles + cycles
                current[j] = after
                archard[j] += volume_rate[j] * cycles
            left -= cycles
            updates += 1
            if on_update is not None:
                on_update(plan.stage_cycles * k - left, current)
        total = {j: worn_before[j] + plan.stage_cycles * k for j in clear}
        increment, after, volume = _close_stage(run, k, current, start, laws, total, bench.name)
        stage = Stage(k, stage_label(k), start, increment, after, first_summary or {}, counted, volume, archard,
                      time.perf_counter() - t0, updates, simulated)
        run.stages.append(stage)
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


def joint_summary(s: JointSurfaces, fraction: float = 0.1, *, clearance: float | None = None) -> dict:
    """Max depth (m), its angle (deg) and wear zones per surface of one joint's state; with the
    joint's radial ``clearance`` (m) also the depth a circular counter-body can reach."""
    out = {"label": s.label, "cycles": s.cycles}
    n = s.bearing.size
    for side in ("bearing", "journal"):
        d = getattr(s, side)
        i = int(np.argmax(d))
        out[side] = {"max_depth_m": float(d[i]), "max_at_deg": round((i + 0.5) * 360.0 / n, 2),
                     "zones_deg": wear_zones(d, fraction)}
        if clearance is not None:
            out[side]["reachable_depth_m"] = reachable_depth(d, clearance)
    return out


def convergence(runs: Mapping[float, WearRun], joints: list[str] | None = None) -> list[dict]:
    """Compare the final surfaces of runs refined by different factors over the same total cycles.

    ``runs``: {refinement: WearRun} (refinement r: depth cap per update divided by r). Per run and
    joint: max depth and reachable depth (what a circular counter-body of the joint's clearance can
    touch, :func:`~wearbench.model.surfaces.reachable_depth`) of bearing and journal, worn volume,
    surface updates and simulated revolutions, and each quantity's change against the next coarser
    run (``*_change``: |this / coarser - 1|; NaN for the coarsest).
    """
    rows = []
    prev: dict[str, dict] = {}
    for r in sorted(runs):
        run = runs[r]
        fin = run.final
        for j in joints or sorted(fin):
            c = run.clearances[j]
            s = fin[j]
            row = {"refinement": r, "depth_cap_m": run.plan.depth_cap, "joint": j, "total_cycles": s.cycles,
                   "updates": sum(st.updates for st in run.stages), "revolutions": run.revolutions,
                   "wall_time_s": round(sum(st.wall_time for st in run.stages), 2)}
            for side in ("bearing", "journal"):
                d = getattr(s, side)
                row[f"{side}_max_m"] = float(d.max())
                row[f"{side}_reachable_m"] = reachable_depth(d, c)
            row["volume_m3"] = float(sum(st.volume[j] for st in run.stages))
            for key in ("bearing_max_m", "bearing_reachable_m", "journal_max_m", "journal_reachable_m",
                        "volume_m3"):
                old = prev.get(j, {}).get(key)
                row[f"{key[:-2] if key.endswith('_m') else key[:-3]}_change"] = (
                    abs(row[key] / old - 1) if old else float("nan"))
            prev[j] = row
            rows.append(row)
    return rows
