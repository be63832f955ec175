"""Crank cycles of a record: cut from the encoder angle and index pulse, resampled by crank angle,
and grouped into the five-cycle windows the paper compares.

Holds ``crank_turns`` (the one derivation of a record's direction of rotation, crank progress and
cycle index per sample), ``cut_cycles`` (cycle table), ``angle_view`` (signal per cycle on a uniform
crank-angle grid), ``WindowSpec``/``parse_windows`` and ``choose_windows``. Pure numpy/pandas;
imports nothing from wearbench.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

__all__ = ["CrankTurns", "WindowSpec", "angle_view", "choose_windows", "crank_turns", "cut_cycles", "parse_windows",
           "reference_angle"]

TWO_PI = 2.0 * np.pi


@dataclass(frozen=True)
class CrankTurns:
    """A record's crank, sample by sample: ``direction`` of rotation (+1 or -1, from the first and
    last angle), ``progress`` (rad, ``direction * angle`` never turning back: a standing or jittering
    crank never counts a cycle twice), ``cycle`` (each sample's cycle index, cycles starting where the
    progress passes ``direction * start_angle + 2 pi k``), and the first and last complete cycle."""

    direction: float
    progress: np.ndarray
    cycle: np.ndarray
    first: int
    last: int


def crank_turns(angle: np.ndarray, *, start_angle: float = 0.0) -> CrankTurns:
    """:class:`CrankTurns` of an unwrapped crank angle (rad, either sense of rotation) per sample;
    cycles start at crank angle ``start_angle`` (0: absolute crank angle, shared by test and theory)."""
    a = np.asarray(angle, dtype=float)
    direction = 1.0 if a[-1] >= a[0] else -1.0
    u = np.maximum.accumulate(a if direction > 0 else -a)
    cycle = np.floor((u - direction * start_angle) / TWO_PI).astype(np.int64)
    return CrankTurns(direction, u, cycle, int(cycle[0]) + 1, int(cycle[-1]) - 1)


def reference_angle(encoder: pd.DataFrame) -> float:
    """Crank angle (rad, in [0, 2 pi)) where cycles start: the circular mean of the encoder angle at
    the index pulses (midway between the sample that shows the pulse and the one before, where the
    pulse fired), or 0 when the record has no index pulse."""
    if "index" not in encoder:
        return 0.0
    flag = encoder["index"].to_numpy(bool)
    i = np.flatnonzero(flag[1:]) + 1
    if i.size == 0:
        return 0.0
    angle = encoder["angle"].to_numpy(float)
    a = 0.5 * (angle[i] + angle[i - 1])
    return float(np.angle(np.mean(np.exp(1j * a))) % TWO_PI)


def cut_cycles(encoder: pd.DataFrame, *, start_angle: float | None = None,
               speed_tolerance: float = 0.02) -> pd.DataFrame:
    """One row per complete crank revolution in the record.

    Columns: cycle (0..), t_start, t_end (s, where the unwrapped angle passes ``start_angle`` + 2 pi k
    in the direction of rotation), speed (mean rad/s, signed), steady (bool: |speed| within
    ``speed_tolerance`` of the median |speed| of all cycles, so run-up and run-down are excluded).
    ``start_angle`` defaults to ``reference_angle(encoder)``.
    """
    t = encoder["time"].to_numpy(float)
    a = encoder["angle"].to_numpy(float)
    ok = np.isfinite(t) & np.isfinite(a)
    t, a = t[ok], a[ok]
    columns = ["cycle", "t_start", "t_end", "speed", "steady"]
    if t.size < 2 or a[-1] == a[0]:
        return pd.DataFrame(columns=columns)
    turns = crank_turns(a)
    direction, u = turns.direction, turns.progress
    ref = start_angle if start_angle is not None else reference_angle(encoder)
    ref_u = direction * ref
    k0 = np.ceil((u[0] - ref_u) / TWO_PI)
    k1 = np.floor((u[-1] - ref_u) / TWO_PI)
    if k1 - k0 < 1:
        return pd.DataFrame(columns=columns)
    marks = ref_u + TWO_PI * np.arange(k0, k1 + 1)
    # first time the (monotone) angle reaches each mark
    idx = np.searchsorted(u, marks, side="left")
    idx = np.clip(idx, 1, u.size - 1)
    u0, u1, t0, t1 = u[idx - 1], u[idx], t[idx - 1], t[idx]
    frac = np.where(u1 > u0, (marks - u0) / np.where(u1 > u0, u1 - u0, 1.0), 0.0)
    times = t0 + np.clip(frac, 0.0, 1.0) * (t1 - t0)
    starts, ends = times[:-1], times[1:]
    speed = direction * TWO_PI / (ends - starts)
    median = np.median(np.abs(speed))
    steady = np.abs(np.abs(speed) - median) <= speed_tolerance * median
    return pd.DataFrame({"cycle": np.arange(starts.size), "t_start": starts, "t_end": ends, "speed": speed,
                         "steady": steady})


def angle_view(time: np.ndarray, values: np.ndarray, encoder: pd.DataFrame, cycles: pd.DataFrame, *,
               start_angle: float, points_per_rev: int = 720) -> pd.DataFrame:
    """``values`` sampled at ``time`` resampled per cycle on a uniform crank-angle grid.

    Columns: cycle, angle (rad from the cycle's start angle, in the direction of rotation, [0, 2 pi)),
    value. The crank angle at each grid point is found from the encoder by linear interpolation.
    """
    te = encoder["time"].to_numpy(float)
    ae = encoder["angle"].to_numpy(float)
    if cycles.empty:
        return pd.DataFrame(columns=["cycle", "angle", "value"])
    turns = crank_turns(ae)
    direction, u = turns.direction, turns.progress
    grid = np.arange(points_per_rev) * (TWO_PI / points_per_rev)
    frames = []
    for row in cycles.itertuples():
        u_start = np.interp(row.t_start, te, u)
        u_start = direction * start_angle + TWO_PI * np.round((u_start - direction * start_angle) / TWO_PI)
        tg = np.interp(u_start + grid, u, te)
        frames.append(pd.DataFrame({"cycle": row.cycle, "angle": grid, "value": np.interp(tg, time, values)}))
    return pd.concat(frames, ignore_index=True)


@dataclass(frozen=True)
class WindowSpec:
    """Which windows to score: ``mode`` "all" (consecutive, non-overlapping) or "random" (``count``
    windows drawn without replacement from every possible start, reproducible with ``seed``)."""

    mode: str = "all"
    count: int = 0
    seed: int = 0
    cycles: int = 5

    @property
    def label(self) -> str:
        if self.mode == "random":
            return f"{self.count} random {self.cycles}-cycle windows (seed {self.seed})"
        return f"all consecutive {self.cycles}-cycle windows"


def parse_windows(text: str, *, cycles: int = 5) -> WindowSpec:
    """``"all"`` or ``"random:COUNT[:SEED]"``."""
    parts = text.strip().lower().split(":")
    if parts == ["all"]:
        return WindowSpec("all", cycles=cycles)
    if parts[0] == "random" and 2 <= len(parts) <= 3:
        try:
            count = int(parts[1])
            seed = int(parts[2]) if len(parts) == 3 else 0
        except ValueError:
            count = 0
        if count >= 1:
            return WindowSpec("random", count, seed, cycles)
    raise ValueError(f"windows {text!r}: expected 'all' or 'random:COUNT[:SEED]', e.g. random:5:0")


def choose_windows(cycles: pd.DataFrame, spec: WindowSpec) -> list[int]:
    """First cycle numbers of the chosen windows; a window is ``spec.cycles`` consecutive steady cycles."""
    if cycles.empty:
        return []
    steady = cycles["steady"].to_numpy(bool)
    n, w = steady.size, spec.cycles
    valid = [s for s in range(n - w + 1) if steady[s: s + w].all()]
    if spec.mode == "random":
        if not valid:
            return []
        rng = np.random.default_rng(spec.seed)
        return sorted(int(s) for s in rng.choice(valid, size=min(spec.count, len(valid)), replace=False))
    chosen, s = [], 0
    valid_set = set(valid)
    while s <= n - w:
        if s in valid_set:
            chosen.append(s)
            s += w
        else:
            s += 1
    return chosen
