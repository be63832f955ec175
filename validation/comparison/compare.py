"""Measurement against theory, window by window: the validation pipeline and its Python API.

Holds ``CompareOptions``, ``compare_session`` (one session: theory, alignment, filtering, scores per
five-cycle window), ``rank_theories`` (which of several candidate theories, e.g. wear stages,
explains a session best) and ``compare_sessions`` (several MCAP files to one report on disk).

Per window (cycles from the encoder's index angle):
1. crank-angle alignment: the theory is looked up at the measured crank angle of every measured
   sample (``TheoryCurve.at``), so speed ripple and start phase are taken out;
2. both signals, over the window plus a margin (filter padding + shift search), get the same
   bias/trend removal (bias: the mean over the window's whole cycles) and the same zero-phase filter;
3. residual time shift (sensor and drive-chain delays, model phase error) by cross-correlation
   with sub-sample refinement, searched over +/- ``max_shift_cycles`` of a cycle (well under half
   a cycle: a periodic signal also correlates one cycle away); reported in s and crank degrees and
   removed from the theory unless ``apply_shift=False``;
4. all metrics of ``validation.metrics.score_window`` on the window itself (margins dropped).
The ISO phase score therefore rates what is left after step 3; the removed shift is reported next
to it. Imports model (lazily, for simulating) and acquisition (lazily, for reading MCAP).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from wearbench.validation.comparison.alignment import estimate_lag, shift_signal
from wearbench.validation.comparison.metrics import WindowScores, aggregate, score_window
from wearbench.validation.comparison.theory import (
    TheoryCurve,
    load_theory,
    resolve_surfaces,
    simulate_theory,
)
from wearbench.validation.measurement.cycles import WindowSpec, choose_windows
from wearbench.validation.measurement.filters import FilterSpec, apply_filter, pad_length
from wearbench.validation.measurement.session import MeasuredSession, load_session

__all__ = ["CompareOptions", "SessionComparison", "TheoryRanking", "WindowResult", "compare_session",
           "rank_theories", "theory_curve"]


@dataclass(frozen=True)
class CompareOptions:
    """How to compare. max_shift_cycles: residual shift search, fraction of a crank cycle; max_delay:
    the same search held to the sensor chain's plausible delay (s; a DAQ's delta-sigma and anti-alias
    filters delay by up to a few ms), so the search never fits the chaos of impacts.
    dtw_band_cycles: DTW band half-width, fraction of a cycle. periodic_theory: compare with the
    theory's last (settled) revolution repeated, as the emulator plays it, instead of its last
    revolutions in a row. revolutions/output_rate: for a simulated theory (output_rate None: the
    measured sample rate)."""

    filter: FilterSpec = field(default_factory=FilterSpec)
    windows: WindowSpec = field(default_factory=WindowSpec)
    max_shift_cycles: float = 0.2
    max_delay: float = 5e-3
    dtw_band_cycles: float = 0.05
    apply_shift: bool = True
    periodic_theory: bool = True
    revolutions: float = 3.0
    output_rate: float | None = None

    def __post_init__(self) -> None:
        if not 0 <= self.max_shift_cycles < 0.5:
            raise ValueError(f"max_shift_cycles = {self.max_shift_cycles}: expected 0 <= value < 0.5 (a periodic "
                             "signal aliases by whole cycles beyond half a cycle)")
        if not 0 <= self.dtw_band_cycles <= 1:
            raise ValueError(f"dtw_band_cycles = {self.dtw_band_cycles}: expected 0..1")
        if not self.max_delay >= 0:
            raise ValueError(f"max_delay = {self.max_delay} s: expected a non-negative delay")

    def to_dict(self) -> dict:
        return {"filter": self.filter.label, "windows": self.windows.label,
                "max_shift_cycles": self.max_shift_cycles, "max_delay_s": self.max_delay,
                "dtw_band_cycles": self.dtw_band_cycles,
                "apply_shift": self.apply_shift, "periodic_theory": self.periodic_theory,
                "detrend": self.filter.detrend,
                "remove_bias": self.filter.remove_bias}


@dataclass
class WindowResult:
    """One scored window: where it is, the shift found, the scores, and the compared signals
    (time from the window start, s; filtered test; filtered, aligned theory; m/s^2)."""

    start_cycle: int
    t_start: float
    t_end: float
    shift_s: float  # residual shift, theory late if > 0
    shift_deg: float  # the same in crank degrees
    scores: WindowScores
    time: np.ndarray
    test: np.ndarray
    theory: np.ndarray

    def to_dict(self) -> dict:
        return {"start_cycle": self.start_cycle, "t_start": self.t_start, "t_end": self.t_end,
                "shift_s": self.shift_s, "shift_deg": self.shift_deg, "scores": self.scores.to_dict()}


@dataclass
class SessionComparison:
    """A session scored against one theory: the windows, the skipped ones and why, the aggregate."""

    label: str
    session: MeasuredSession
    theory: TheoryCurve
    options: CompareOptions
    windows: list[WindowResult]
    skipped: list[tuple[int, str]]

    @property
    def summary(self) -> pd.DataFrame:
        return aggregate([w.scores for w in self.windows])

    @property
    def rating(self) -> float:
        return float(np.mean([w.scores.iso_rating for w in self.windows]))

    def to_dict(self) -> dict:
        s = self.session
        steady = s.cycles[s.cycles["steady"]] if not s.cycles.empty else s.cycles
        return {
            "label": self.label, "path": str(s.path) if s.path else None,
            "clearances_m": s.clearances, "wear_state": s.wear_state,
            "sample_rate_hz": s.fs, "cycles": len(s.cycles), "steady_cycles": len(steady),
            "dropped_sample_gaps": s.gaps, "measured_crank_speed_rad_s": s.steady_speed,
            "theory": {"label": self.theory.label, "crank_speed_rad_s": self.theory.speed,
                       "revolutions": self.theory.revolutions},
            "peak_acc_measured": float(max(np.max(np.abs(w.test)) for w in self.windows)),
            "peak_acc_theory": float(max(np.max(np.abs(w.theory)) for w in self.windows)),
            "windows": [w.to_dict() for w in self.windows],
            "skipped": [{"start_cycle": c, "reason": r} for c, r in self.skipped],
            "summary": self.summary.to_dict(orient="index"),
        }

    def row(self) -> dict:
        """One table row: the session, its windows and the mean of each score over them."""
        return {"session": self.label, "windows": len(self.windows),
                **{k: float(v) for k, v in self.summary["mean"].items()}}




def theory_curve(session: MeasuredSession, theory: Any = None, *, options: CompareOptions = CompareOptions(),
                 surfaces: Mapping[str, Any] | None = None, label: str | None = None) -> TheoryCurve:
    """The theory for ``session``: ``theory`` may be a TheoryCurve, a results DataFrame, an object with
    ``.table`` (SimulationResult), a path to a parquet/CSV table, or None (simulate the session's
    bench at its measured speed with its recorded clearances and worn surfaces)."""
    joint = session.encoder_joint
    if isinstance(theory, TheoryCurve):
        return theory
    if theory is None:
        if session.bench is None:
            raise ValueError(f"session {session.label}: no bench in the file to simulate; pass a theory")
        base = session.path.parent if session.path else None
        worn = surfaces if surfaces is not None else resolve_surfaces(session.wear_state, base,
                                                                         session.surface_files)
        known = {j.name for j in session.bench.clearance_joints}
        clearances = {j: c for j, c in session.clearances.items() if j in known} or None
        rate = options.output_rate or session.fs
        table = simulate_theory(session.bench, speed=session.motor_speed, clearances=clearances,
                                surfaces=worn, revolutions=options.revolutions, output_rate=rate)
        return TheoryCurve.from_table(table, joint, label or "simulated", periodic=options.periodic_theory)
    if isinstance(theory, (str, Path)):
        return TheoryCurve.from_table(load_theory(theory), joint, label or Path(theory).stem,
                                      periodic=options.periodic_theory)
    table = theory.table if hasattr(theory, "table") else theory
    if not isinstance(table, pd.DataFrame):
        raise TypeError(f"theory: expected a results table, SimulationResult, path or None, got {type(theory).__name__}")
    return TheoryCurve.from_table(table, joint, label or "theory", periodic=options.periodic_theory)


def _score_window(session: MeasuredSession, theory: TheoryCurve, start: int, options: CompareOptions,
                  t_all: np.ndarray, acc_all: np.ndarray) -> WindowResult | str:
    cyc = session.cycles
    n_cyc = options.windows.cycles
    t0 = float(cyc["t_start"].iloc[start])
    t1 = float(cyc["t_end"].iloc[start + n_cyc - 1])
    fs = session.fs
    cycle_samples = (t1 - t0) * fs / n_cyc
    max_lag = int(min(options.max_shift_cycles * cycle_samples, options.max_delay * fs))
    margin = (pad_length(options.filter, fs) + max_lag + 8) / fs
    if np.any((session.gap_times >= t0 - margin) & (session.gap_times <= t1 + margin)):
        return "dropped samples in the window"
    i0, i1 = np.searchsorted(t_all, [t0 - margin, t1 + margin])
    c0, c1 = np.searchsorted(t_all, [t0, t1])
    if c1 - c0 < 32:
        return "too few samples"
    t = t_all[i0:i1]
    test = acc_all[i0:i1].copy()
    if not np.all(np.isfinite(test)):
        return f"{int(np.sum(~np.isfinite(test)))} non-finite acceleration samples in the window"
    angle = session.crank_angle[i0:i1]
    try:
        theo = theory.at(angle, direction=session.direction)
    except ValueError as exc:
        return str(exc)
    spec = options.filter
    if spec.remove_bias and not spec.detrend:  # bias over the window's whole cycles, not the margins
        core = slice(c0 - i0, c1 - i0)
        test -= test[core].mean()
        theo = theo - theo[core].mean()
        spec = replace(spec, remove_bias=False)
    test_f = apply_filter(test, fs, spec)
    theo_f = apply_filter(theo, fs, spec)
    lag = estimate_lag(test_f, theo_f, max_lag) if max_lag > 0 else 0.0
    if options.apply_shift and lag != 0.0:
        theo_f = shift_signal(theo_f, lag)
    core = slice(c0 - i0, c1 - i0)
    x, y = test_f[core], theo_f[core]
    scores = score_window(x, y, fs, cycle_samples=cycle_samples, max_lag=max_lag,
                          dtw_band=max(1, int(options.dtw_band_cycles * cycle_samples)), ties="wearbench")
    speed = abs(2 * np.pi * n_cyc / (t1 - t0))
    return WindowResult(start, t0, t1, lag / fs, float(np.degrees(lag / fs * speed)), scores,
                        t[core] - t0, x, y)


def compare_session(session: MeasuredSession | str | Path, theory: Any = None, *,
                    options: CompareOptions = CompareOptions(), surfaces: Mapping[str, Any] | None = None,
                    label: str | None = None, theory_label: str | None = None) -> SessionComparison:
    """Score ``session`` against ``theory`` (see ``theory_curve``) over the chosen windows."""
    if not isinstance(session, MeasuredSession):
        session = load_session(session, label=label)
    curve = theory_curve(session, theory, options=options, surfaces=surfaces, label=theory_label)
    starts = choose_windows(session.cycles, options.windows)
    if not starts:
        raise ValueError(f"session {session.label}: no run of {options.windows.cycles} steady crank cycles "
                         f"({len(session.cycles)} complete cycles recorded)")
    t_all, _, acc_all = session.samples
    windows, skipped = [], []
    for s in starts:
        r = _score_window(session, curve, s, options, t_all, acc_all)
        (windows.append(r) if isinstance(r, WindowResult) else skipped.append((s, r)))
    if not windows:
        raise ValueError(f"session {session.label}: no window could be scored: "
                         + "; ".join(f"cycle {c}: {r}" for c, r in skipped[:3]))
    return SessionComparison(label or session.label, session, curve, options, windows, skipped)


@dataclass
class TheoryRanking:
    """One candidate theory's fit to a session (higher ISO rating = better)."""

    label: str
    rating: float  # mean ISO/TS 18571 rating over windows
    rating_std: float
    comparison: SessionComparison


def rank_theories(session: MeasuredSession | str | Path, candidates: Mapping[str, Any], *,
                  options: CompareOptions = CompareOptions()) -> list[TheoryRanking]:
    """Score ``session`` against each candidate theory; best first. The first entry's label is the
    state (e.g. wear stage or clearance) that best explains the measurement."""
    if not candidates:
        raise ValueError("rank_theories: no candidate theories given")
    if not isinstance(session, MeasuredSession):
        session = load_session(session)
    out = []
    for name, theory in candidates.items():
        c = compare_session(session, theory, options=options, theory_label=name)
        r = np.array([w.scores.iso_rating for w in c.windows])
        out.append(TheoryRanking(name, float(r.mean()), float(r.std(ddof=1)) if r.size > 1 else 0.0, c))
    return sorted(out, key=lambda x: -x.rating)
