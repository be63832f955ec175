"""The accelerometer's physics: its acceleration versus motor angle, one table per crank speed.

Two kinds of model table, both from :func:`wearbench.model.realisation.simulate_state` with the
device's TRUE state (clearances and worn surfaces of ``[emulator.truth]``):

- twin (truth without a seed, :func:`model_table`): the nominal bench started centred, ``settle``
  revolutions dropped and the next one kept and looped, so every cycle is the same: the theory's
  own revolution, as the emulator always played it (kept for comparison);
- run (truth with a seed, :func:`run_table`): the bench drawn from its ``[tolerances]`` with that
  seed (masses, lengths, contact, speed error and ripple, start state), ``revolutions`` whole
  revolutions after ``settle``, played by unwrapped motor angle, so consecutive cycles differ as
  the chaotic impacts of a real bench do. Device angle 0 (power-up) is the first whole revolution
  of the run. A session longer than the run wraps to its start; the last quarter revolution before
  the wrap is a raised-cosine crossfade from the run's end into the samples that precede its start,
  so the played signal stays continuous and a cycle boundary keeps its crank angle.

Every model table also holds ``lateral``: the force the rest of the mechanism puts on the sensor's
body perpendicular to its guide (and to the sensor axis), divided by the body's mass (m/s^2)
(:func:`~wearbench.hardware.emulators.carriage.lateral_force`): what drives the carriage's lateral mode, whose acceleration reaches the
sensor through its cross-axis sensitivity (:mod:`wearbench.hardware.emulators.sensor`). On the
model's ideal guide that force is exactly minus the guide's lateral reaction (the body does not
move sideways), and it comes from the ideal pins' reactions the model writes to its table.

Tables are resampled on a uniform grid of motor angle (the device only interpolates at 20 kHz) and
cached on disk in ``$WEARBENCH_CACHE`` (default ``~/.cache/wearbench``)/``emulator``, keyed on the
content of every model parameter (:func:`table_key`). ``harmonic`` is a kinematic test pattern,
``none`` a zero signal. Imports numpy, the bench schema and config, and lazily the model.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from wearbench.bench.content import cache_folder, canonical
from wearbench.bench.schema import Bench
from wearbench.hardware.emulators.carriage import lateral_force
from wearbench.hardware.emulators.config import Truth

__all__ = ["FADE", "SignalTable", "cache_dir", "harmonic_table", "model_table", "run_table", "signal_table",
           "table_key"]

TWO_PI = 2 * np.pi
FADE = 0.25 * TWO_PI  # rad of motor angle: the crossfade before a long run wraps to its start
_MODEL_TABLE_VERSION = "2"
_COLUMNS = ("acc", "lateral")  # what a model table holds (part of its key)

@dataclass(frozen=True, eq=False)
class SignalTable:
    """The accelerometer's acceleration (m/s^2, along its axis) at motor progress ``period i / n`` (i < n) for steady commanded
    ``speed`` (rad/s). Progress is ``direction x motor angle`` modulo ``period`` (2 pi: one looped
    revolution; a long run: its whole revolutions). ``lateral``: the lateral force on the sensor's body
    over its mass (m/s^2) on the same grid (module docstring; None: a table without it)."""

    speed: float
    acc: np.ndarray
    source: str
    period: float = TWO_PI
    direction: int = 1
    lateral: np.ndarray | None = None

    def at(self, theta: np.ndarray, speed: np.ndarray | float | None = None) -> np.ndarray:
        """Acceleration at motor angles ``theta`` (rad), periodic linear interpolation; at another
        ``speed`` the table is scaled by (speed/self.speed)^2 (exact for the kinematic part)."""
        return self._interpolate(self.acc, theta, speed)

    def lateral_at(self, theta: np.ndarray, speed: np.ndarray | float | None = None) -> np.ndarray:
        """``lateral`` at motor angles ``theta`` as :meth:`at` interpolates the acceleration."""
        if self.lateral is None:
            raise ValueError(f"signal table ({self.source}) holds no lateral force: a cross-axis sensor needs "
                             "the accelerometer on a body sliding on a prismatic guide fixed to the frame")
        return self._interpolate(self.lateral, theta, speed)

    def _interpolate(self, values: np.ndarray, theta: np.ndarray, speed: np.ndarray | float | None) -> np.ndarray:
        n = values.size
        x = np.mod(self.direction * np.asarray(theta, dtype=np.float64), self.period) * (n / self.period)
        i0 = np.floor(x).astype(np.int64)
        w = x - i0
        out = (1 - w) * values[i0 % n] + w * values[(i0 + 1) % n]
        if speed is not None and self.speed != 0:
            out = out * (np.asarray(speed) / self.speed) ** 2
        return out

    @property
    def revolutions(self) -> float:
        return self.period / TWO_PI


def cache_dir() -> Path:
    return cache_folder("emulator")


def harmonic_table(speed: float, points: int = 4096) -> SignalTable:
    """Test pattern, not physics: slider-crank kinematics a = -r w^2 (cos t + l cos 2t), r = 0.05 m, l = 0.25."""
    theta = np.arange(points) * (TWO_PI / points)
    acc = -0.05 * speed**2 * (np.cos(theta) + 0.25 * np.cos(2 * theta))
    return SignalTable(speed, acc, "harmonic test pattern")


def _sensor_name(bench: Bench) -> str:
    """The accelerometer's name in the bench file (what messages call it)."""
    return next((s.name for s in bench.sensors if s.kind == "accelerometer"), "the accelerometer")


def table_key(bench: Bench, truth: Truth, speed: float, *, kind: str, revolutions: int, settle: float,
              rate: float) -> str:
    """SHA-256 over everything a model table depends on: the bench as drawn for the truth's seed with
    the true clearances in place, as the run simulates it (every body, joint, contact law, material,
    point, driver, sensor axis; a bench changed in memory is keyed on what it holds, and a rig's
    clearance labels that the truth replaces key no other table), the drawn speed error, ripple and
    start spread, the true clearances and the content of the worn-surface files, the seed, speed,
    revolutions, settling, rate, the columns the table holds and the model's results digest."""
    from wearbench.model.digest import model_results_digest
    from wearbench.model.realisation import draw_realisation

    real = draw_realisation(bench, truth.seed)
    simulated = real.bench.with_clearances(truth.clearances)  # what state_scene builds from it
    key = {"v": _MODEL_TABLE_VERSION, "kind": kind, "model": model_results_digest(), "bench": canonical(simulated),
           "draw": canonical(real.describe()), "clearances": canonical(dict(truth.clearances)),
           "wear": canonical({j: Path(p) for j, p in truth.wear.items()}), "seed": truth.seed,
           "speed": canonical(float(speed)), "revolutions": revolutions, "settle": canonical(float(settle)),
           "rate": canonical(float(rate)), "columns": list(_COLUMNS)}
    return hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()


def _cached(path: Path, cache: bool) -> SignalTable | None:
    if cache and path.exists():
        with np.load(path) as data:
            lateral = data["lateral"] if "lateral" in data.files else None
            return SignalTable(float(data["speed"]), data["acc"], str(data["source"]), float(data["period"]),
                               int(data["direction"]), lateral if lateral is None or lateral.size else None)
    return None


def _store(path: Path, table: SignalTable, cache: bool) -> SignalTable:
    if cache:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp.npz")
        np.savez(tmp, speed=np.array(table.speed), acc=table.acc, source=np.array(table.source),
                 period=np.array(table.period), direction=np.array(table.direction),
                 lateral=np.zeros(0) if table.lateral is None else table.lateral)
        os.replace(tmp, path)
    return table


def model_table(bench: Bench, truth: Truth, speed: float, *, settle: float = 2.0, rate: float = 20000.0,
                cache: bool = True) -> SignalTable:
    """Twin: the nominal model in the true state at motor ``speed`` (rad/s), the revolution after
    ``settle`` looped: the theory's own revolution, sample for sample (where the orbit is not exactly
    periodic, the loop's seam jumps, as a twin always did). ``rate`` (Hz): time resolution."""
    if speed == 0:
        raise ValueError("model_table: speed 0 has no steady revolution")
    twin = dataclasses.replace(truth, seed=None)
    key = table_key(bench, twin, speed, kind="twin", revolutions=1, settle=settle, rate=rate)
    path = cache_dir() / f"{bench.name}-twin-{key[:20]}.npz"
    if (hit := _cached(path, cache)) is not None:
        return hit
    from wearbench.model.realisation import simulate_state

    run = simulate_state(bench, twin.state(), None, revolutions=1.0, settle=settle, speed=speed, output_rate=rate)
    if not np.all(np.isfinite(run.acc)):
        raise RuntimeError(f"{bench.name}: model acceleration of {_sensor_name(bench)} is not finite at speed "
                           f"{speed} rad/s")
    rel = np.abs(run.motor_angle - run.motor_angle[0])
    if run.t.size < 16 or rel[-1] < TWO_PI * (1 - 2 / run.t.size):
        raise RuntimeError(f"{bench.name}: model returned too short a revolution for a table ({run.t.size} samples)")
    one = rel < TWO_PI - 0.5 * TWO_PI / run.t.size  # one revolution; its end (its start again) left out
    angle = np.mod(run.motor_angle[one], TWO_PI)
    order = np.argsort(angle)
    n = int(np.clip(rate * TWO_PI / abs(speed), 512, 200000))
    grid = np.arange(n) * (TWO_PI / n)
    values = np.interp(grid, angle[order], run.acc[one][order], period=TWO_PI)
    lateral = lateral_force(run.realisation.bench, run.table)
    if lateral is not None:
        lateral = np.interp(grid, angle[order], lateral[one][order], period=TWO_PI)
    source = f"model twin ({run.summary['description']}) at {speed:g} rad/s, one revolution looped"
    return _store(path, SignalTable(float(speed), values, source, lateral=lateral), cache)


def run_table(bench: Bench, truth: Truth, speed: float, *, revolutions: int = 40, settle: float = 2.0,
              rate: float = 20000.0, cache: bool = True) -> SignalTable:
    """Non-twin: ``revolutions`` whole revolutions of the bench drawn with ``truth.seed`` at commanded
    motor ``speed`` (rad/s; the realisation turns at its own speed error and ripple) after
    ``settle``, by motor angle, with the crossfade of the module docstring at the wrap."""
    if truth.seed is None:
        raise ValueError("run_table: the truth has no seed (a twin plays model_table)")
    if speed == 0:
        raise ValueError("model table: speed 0 has no steady revolution")
    n_rev = int(revolutions)
    if n_rev < 1 or n_rev != revolutions:
        raise ValueError(f"model table: revolutions = {revolutions}: expected a whole number >= 1")
    kind = f"seed{truth.seed}"
    key = table_key(bench, truth, speed, kind=kind, revolutions=n_rev, settle=settle, rate=rate)
    path = cache_dir() / f"{bench.name}-{kind}-{key[:20]}.npz"
    if (hit := _cached(path, cache)) is not None:
        return hit
    from wearbench.model.realisation import simulate_state

    # 2 more revolutions than played: the table starts at a whole revolution past settling + FADE
    run = simulate_state(bench, truth.state(), truth.seed, revolutions=n_rev + 2.0, settle=settle, speed=speed,
                         output_rate=rate)
    if not np.all(np.isfinite(run.acc)):
        raise RuntimeError(f"{bench.name}: model acceleration of {_sensor_name(bench)} is not finite at speed "
                           f"{speed} rad/s")
    direction = 1 if speed > 0 else -1
    progress = direction * run.motor_angle
    if np.any(np.diff(progress) <= 0):
        i = int(np.argmax(np.diff(progress) <= 0))
        raise RuntimeError(f"{bench.name} ({kind}): the motor angle of the run turns back at t = {run.t[i]:.4f} s "
                           "after settling; a table needs a monotonic motor")
    start = TWO_PI * math.ceil((progress[0] + FADE) / TWO_PI)
    period = n_rev * TWO_PI
    if progress[-1] < start + period:
        raise RuntimeError(f"{bench.name} ({kind}): the run ends at motor angle {progress[-1]:.3f} rad, before "
                           f"the {n_rev} revolutions from {start:.3f} rad it must hold")
    n = int(np.clip(rate * TWO_PI / abs(speed), 512, 200000)) * n_rev
    p = np.arange(n) * (period / n)
    fade = p >= period - FADE
    w = 0.5 - 0.5 * np.cos(np.pi * (p[fade] - (period - FADE)) / FADE)

    def played(column: np.ndarray) -> np.ndarray:
        values = np.interp(start + p, progress, column)
        values[fade] = (1 - w) * values[fade] + w * np.interp(start + p[fade] - period, progress, column)
        return values

    lateral = lateral_force(run.realisation.bench, run.table)
    real = run.realisation
    source = (f"model run of {bench.name} drawn with seed {truth.seed} (speed x{real.speed_scale:.5f}, ripple "
              f"{real.ripple:.2e}) in state {truth.state().name!r}, {n_rev} revolutions at {speed:g} rad/s")
    return _store(path, SignalTable(float(speed), played(run.acc), source, period, direction,
                                    None if lateral is None else played(lateral)), cache)


def signal_table(kind: str, bench: Bench, truth: Truth, speed: float, *, revolutions: int = 40,
                 settle: float = 2.0, rate: float = 20000.0, cache: bool = True) -> SignalTable:
    """The table of signal ``kind`` ("model", "harmonic", "none"; "white" is generated per sample);
    "model" is :func:`run_table` for a truth with a seed, else :func:`model_table` (twin)."""
    if kind == "model":
        if truth.seed is not None:
            return run_table(bench, truth, speed, revolutions=revolutions, settle=settle, rate=rate, cache=cache)
        return model_table(bench, truth, speed, settle=settle, rate=rate, cache=cache)
    if kind == "harmonic":
        return harmonic_table(speed)
    return SignalTable(speed, np.zeros(16), kind)
