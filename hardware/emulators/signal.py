"""The accelerometer's physics: slider acceleration versus motor angle, one table per crank speed.

:func:`model_table` runs the multibody model (``wearbench.model.build_scene``/``simulate``) for the
bench with the device's TRUE clearances and worn surfaces at the commanded speed, keeps the last
(steady-state) revolution and resamples it on a uniform grid of motor angle, so the device only
interpolates at 20 kHz. Tables are cached on disk per (bench sha, clearances, surfaces, speed, truth,
settings, model source) in
``$WEARBENCH_CACHE`` (default ``~/.cache/wearbench``)/``emulator``. ``harmonic`` is a kinematic test
pattern, ``none`` a zero signal. Imports numpy and, lazily, the model.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from wearbench.hardware.bench import Bench
from wearbench.hardware.emulators.config import Truth

__all__ = ["SignalTable", "cache_dir", "harmonic_table", "model_table", "signal_table"]

TWO_PI = 2 * np.pi
_MODEL_TABLE_VERSION = "1"


@dataclass(frozen=True, eq=False)
class SignalTable:
    """Slider acceleration (m/s^2) at motor angles ``2 pi i / n`` (i < n) for steady ``speed`` (rad/s)."""

    speed: float
    acc: np.ndarray
    source: str

    def at(self, theta: np.ndarray, speed: np.ndarray | float | None = None) -> np.ndarray:
        """Acceleration at motor angles ``theta`` (rad), periodic linear interpolation; at another
        ``speed`` the table is scaled by (speed/self.speed)^2 (exact for the kinematic part)."""
        n = self.acc.size
        x = np.mod(theta, TWO_PI) * (n / TWO_PI)
        i0 = np.floor(x).astype(np.int64)
        w = x - i0
        out = (1 - w) * self.acc[i0 % n] + w * self.acc[(i0 + 1) % n]
        if speed is not None and self.speed != 0:
            out = out * (np.asarray(speed) / self.speed) ** 2
        return out


def cache_dir() -> Path:
    return Path(os.environ.get("WEARBENCH_CACHE", Path.home() / ".cache" / "wearbench")) / "emulator"


def harmonic_table(speed: float, points: int = 4096) -> SignalTable:
    """Test pattern, not physics: slider-crank kinematics a = -r w^2 (cos t + l cos 2t), r = 0.05 m, l = 0.25."""
    theta = np.arange(points) * (TWO_PI / points)
    acc = -0.05 * speed**2 * (np.cos(theta) + 0.25 * np.cos(2 * theta))
    return SignalTable(speed, acc, "harmonic test pattern")


def _file_sha(path: str | Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _truth_key(truth: Truth) -> dict:
    wear = {j: _file_sha(p) for j, p in sorted(truth.wear.items())}
    return {"clearances": {j: round(c, 12) for j, c in sorted(truth.clearances.items())}, "wear": wear}


def model_table(bench: Bench, truth: Truth, speed: float, *, revolutions: float = 3.0,
                rate: float = 20000.0, cache: bool = True) -> SignalTable:
    """Steady-state slider acceleration of the model at motor ``speed`` (rad/s) for the true state.

    ``rate`` (Hz) is the table's time resolution; the last of ``revolutions`` is kept.
    """
    if speed == 0:
        raise ValueError("model_table: speed 0 has no steady revolution")
    from wearbench.model.digest import model_source_digest
    joints = {j.name: [j.clearance.bearing_radius, j.clearance.journal_radius,
                       _file_sha(j.clearance.surfaces) if j.clearance.surfaces else None]
              for j in bench.clearance_joints}  # a Bench changed in memory keeps its file's sha
    key = json.dumps({"v": _MODEL_TABLE_VERSION, "model": model_source_digest(), "bench": bench.sha256,
                      "joints": joints, "speed": round(speed, 6), "truth": _truth_key(truth),
                      "revolutions": revolutions, "rate": rate}, sort_keys=True)
    path = cache_dir() / f"{bench.name}-{hashlib.sha256(key.encode()).hexdigest()[:20]}.npz"
    if cache and path.exists():
        with np.load(path) as data:
            return SignalTable(float(data["speed"]), data["acc"], str(data["source"]))
    from wearbench.model import build_scene, simulate
    from wearbench.model.surfaces import JointSurfaces, surfaces_from_bench

    surfaces = surfaces_from_bench(bench)
    surfaces.update({j: JointSurfaces.load(p) for j, p in truth.wear.items()})
    clearances = dict(truth.clearances) or None
    scene = build_scene(bench.with_speed(speed), clearances=clearances, surfaces=surfaces or None)
    result = simulate(scene, revolutions=revolutions, speed=speed, output_rate=rate)
    table = result.table
    theta = np.abs(speed) * table["t"].to_numpy()
    acc = table["slider_acc"].to_numpy()
    if not np.all(np.isfinite(acc)):
        raise RuntimeError(f"{bench.name}: model slider acceleration is not finite at speed {speed} rad/s")
    last = theta >= theta[-1] - TWO_PI
    if theta[-1] < TWO_PI or last.sum() < 16:
        raise RuntimeError(f"{bench.name}: model returned {theta[-1] / TWO_PI:.2f} revolutions, too few for a table")
    points = int(np.clip(rate * TWO_PI / abs(speed), 512, 200000))
    grid = np.arange(points) * (TWO_PI / points)
    angle = np.mod(theta[last], TWO_PI) if speed > 0 else np.mod(-theta[last], TWO_PI)
    order = np.argsort(angle)
    values = np.interp(grid, angle[order], acc[last][order], period=TWO_PI)
    source = f"model ({scene.description}) at {speed:g} rad/s"
    out = SignalTable(float(speed), values, source)
    if cache:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp.npz")
        np.savez(tmp, speed=np.array(speed), acc=values, source=np.array(source))
        os.replace(tmp, path)
    return out


def signal_table(kind: str, bench: Bench, truth: Truth, speed: float, *, revolutions: float = 3.0,
                 rate: float = 20000.0, cache: bool = True) -> SignalTable:
    """The table of signal ``kind`` ("model", "harmonic", "none"; "white" is generated per sample)."""
    if kind == "model":
        return model_table(bench, truth, speed, revolutions=revolutions, rate=rate, cache=cache)
    if kind == "harmonic":
        return harmonic_table(speed)
    return SignalTable(speed, np.zeros(16), kind)
