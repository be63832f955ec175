"""Theory for a measured session: simulate it, or load a given result, and look it up by crank angle.

Holds ``TheoryCurve`` (slider acceleration as a function of crank angle, taken from a steady part of
a simulation table), ``load_theory`` (a results table from parquet/CSV) and ``simulate_theory`` (the
bench simulated at a measured speed with recorded clearances and worn surfaces). Imports
wearbench.model lazily (only when simulating) and nothing from acquisition.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

__all__ = ["TheoryCurve", "load_theory", "resolve_surfaces", "simulate_theory"]

TWO_PI = 2.0 * np.pi


@dataclass(frozen=True)
class TheoryCurve:
    """Slider acceleration of a simulation, addressed by the absolute crank angle of ``joint``.

    ``at(angle)`` maps measured (unwrapped, absolute) crank angles onto the simulation by whole turns
    and interpolates the theory there. ``periodic``: the last simulated revolution (the settled
    steady state, as the bench emulator plays it) repeated every turn; otherwise the LAST
    revolutions the simulation covers, keeping each window's angle span contiguous (needs a
    simulation at least as long as a window).
    """

    label: str
    joint: str
    u: np.ndarray  # direction * crank angle, increasing (rad)
    acc: np.ndarray  # m/s^2 at u
    direction: float  # +1 or -1: sense of crank rotation
    speed: float  # mean crank speed of the simulation (rad/s, signed)
    table: pd.DataFrame
    periodic: bool = True

    @classmethod
    def from_table(cls, table: pd.DataFrame, joint: str | None, label: str = "theory", *,
                   periodic: bool = True) -> TheoryCurve:
        """``table`` with columns t, theta_<joint>, slider_acc (the model's result table); ``joint``
        None (a session without its bench): the table's one crank-angle column."""
        if joint is None:
            cranks = [c.removeprefix("theta_") for c in table.columns if c.startswith("theta_")]
            if len(cranks) != 1:
                raise ValueError(f"theory {label!r}: the session names no encoder crank (no bench) and the table "
                                 f"has crank angles {cranks}; expected exactly one theta_<joint> column")
            joint = cranks[0]
        col = f"theta_{joint}"
        missing = [c for c in ("t", col, "slider_acc") if c not in table.columns]
        if missing:
            raise ValueError(f"theory {label!r}: missing column(s) {missing}; expected t, {col}, slider_acc "
                             f"(the model's result table), got {list(table.columns)[:12]}")
        t = table["t"].to_numpy(float)
        a = table[col].to_numpy(float)
        acc = table["slider_acc"].to_numpy(float)
        if t.size < 4 or not np.all(np.isfinite(acc)) or not np.all(np.isfinite(a)):
            raise ValueError(f"theory {label!r}: needs at least 4 finite rows, got {t.size}")
        direction = 1.0 if a[-1] > a[0] else -1.0
        u = direction * a
        if np.any(np.diff(u) <= 0):
            raise ValueError(f"theory {label!r}: crank angle {col} is not strictly monotonic; a theory for "
                             "validation must turn the crank steadily")
        speed = (a[-1] - a[0]) / (t[-1] - t[0])
        if periodic:
            if u[-1] - u[0] < TWO_PI:
                raise ValueError(f"theory {label!r}: covers {(u[-1] - u[0]) / TWO_PI:.2f} revolutions; needs one")
            keep = u >= u[-1] - TWO_PI
            u, acc = u[keep], acc[keep]
        return cls(label, joint, u, acc, direction, float(speed), table, periodic)

    @property
    def revolutions(self) -> float:
        return float((self.u[-1] - self.u[0]) / TWO_PI)

    def at(self, angle: np.ndarray, *, direction: float) -> np.ndarray:
        """Theory at measured crank angles ``angle`` (rad, unwrapped, absolute; one contiguous span)."""
        if direction != self.direction:
            raise ValueError(f"theory {self.label!r}: the crank turns the other way ({self.direction:+.0f}) than "
                             f"in the measurement ({direction:+.0f}); check the encoder sign and the bench speed")
        u = direction * np.asarray(angle, dtype=float)
        if self.periodic:
            return np.interp(u, self.u, self.acc, period=TWO_PI)
        lo, hi = float(u.min()), float(u.max())
        if hi - lo > self.u[-1] - self.u[0]:
            raise ValueError(f"theory {self.label!r}: covers {self.revolutions:.2f} revolutions, a window needs "
                             f"{(hi - lo) / TWO_PI:.2f}; simulate more revolutions")
        turns = np.ceil((hi - self.u[-1]) / TWO_PI)  # whole turns that put the span's end inside
        return np.interp(u - TWO_PI * turns, self.u, self.acc)


def load_theory(path: str | Path) -> pd.DataFrame:
    """A simulation result table saved as parquet (or CSV): columns t, theta_<joint>, slider_acc, ..."""
    path = Path(path)
    if not path.exists():
        raise OSError(f"theory {path}: no such file")
    if path.suffix.lower() == ".csv":
        return pd.read_csv(path)
    try:
        return pd.read_parquet(path)
    except Exception as exc:  # pyarrow raises several types for a bad file
        raise ValueError(f"theory {path}: not a readable parquet results table ({exc})") from exc


UNWORN = ("", "new", "none", "unworn", "before wear")  # wear-state labels of an unworn joint


def resolve_surfaces(wear_state: Mapping[str, str], base: Path | None = None,
                     embedded: Mapping[str, bytes] | None = None) -> dict[str, Any] | None:
    """Worn surfaces named by a session's wear state: {joint: JointSurfaces} for entries that are
    paths of saved surfaces (.npz); entries like "new" or "" mean unworn. Unknown labels raise.
    ``embedded`` ({joint: .npz bytes}, the copies a session carries as attachments) is used when
    the file is no longer where the wear state says."""
    import tempfile

    from wearbench.model.surfaces import JointSurfaces

    surfaces: dict[str, Any] = {}
    for joint, state in wear_state.items():
        s = str(state).strip()
        if s.lower() in UNWORN:
            continue
        p = Path(s)
        if not p.is_absolute() and base is not None and not p.exists():
            p = base / p
        if p.suffix == ".npz" and p.exists():
            surfaces[joint] = JointSurfaces.load(p)
            continue
        if p.suffix == ".npz" and embedded and joint in embedded:
            with tempfile.TemporaryDirectory() as tmp:
                copy = Path(tmp, p.name)
                copy.write_bytes(embedded[joint])
                surfaces[joint] = JointSurfaces.load(copy)
            continue
        raise ValueError(f"wear state of joint {joint}: {s!r} is neither 'new' nor a saved surface file (.npz); "
                         "pass the theory explicitly (--theory, or surfaces=...)")
    return surfaces or None


def simulate_theory(bench, *, speed: float, clearances: Mapping[str, float | None] | None = None,
                    surfaces: Mapping[str, Any] | None = None, revolutions: float = 8.0,
                    output_rate: float | None = None) -> pd.DataFrame:
    """Simulate ``bench`` at motor speed ``speed`` (rad/s) with the given clearances/surfaces; the table."""
    from wearbench.model import build_scene, simulate  # the model is only needed here

    scene = build_scene(bench.with_speed(speed), clearances=dict(clearances) if clearances else None,
                        surfaces=dict(surfaces) if surfaces else None)
    result = simulate(scene, revolutions=revolutions, speed=speed, output_rate=output_rate)
    return result.table
