"""A measured session as validation sees it: acceleration and encoder in pandas, cut into cycles.

Holds ``MeasuredSession`` (time signals, cycle table, crank-angle view, recorded conditions) and
``load_session`` (from a session MCAP via wearbench.acquisition.session_file.read_session). The
session carries what was recorded, as the reader gives it: its sample rate (the rate its blocks were
recorded at), its clip level and each sample's ``clipped`` flag (the acquisition's clip rule on the
recorded range, applied by the reader); it owns its gaps (the acquisition's rule) and each sample's
crank angle, direction and cycle (``cycles.crank_turns``); features, windows and identification take
them from here.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from wearbench.acquisition.sequence import gaps
from wearbench.validation.measurement.chain_delay import StatedDelay, stated_delay
from wearbench.validation.measurement.cycles import (
    CrankTurns,
    angle_view,
    crank_turns,
    cut_cycles,
    reference_angle,
)
from wearbench.validation.measurement.features import (
    CycleFeatures,
    FeatureSpec,
    cycle_features,
    sample_rate,
)
from wearbench.validation.measurement.scaling import resolve_analysis

__all__ = ["RESOLUTION_STEPS", "MeasuredSession", "load_session", "stream_start"]

RESOLUTION_STEPS = 20  # a crank-angle curve spanning fewer steps of the recorded resolution gets a note


def stream_start(acc: pd.DataFrame, fs: float) -> float:
    """When an accelerometer stream (a session's ``acceleration``, sampled at ``fs`` Hz) began (s): its
    first sample, less the blocks before it (sequence numbers count blocks from the stream's start)."""
    t0 = float(acc["time"].iloc[0])
    if "sequence" not in acc.columns:
        return t0
    seq = acc["sequence"].to_numpy()
    block = int(np.count_nonzero(seq == seq[0]))
    return t0 - int(seq[0]) * block / fs


@dataclass
class MeasuredSession:
    """Acceleration (time, acc, clipped) and encoder (time, angle, speed, index) of one session, device clock.

    fs: acceleration sample rate (Hz): the rate the session's blocks were recorded at (``load_session``
    gives the reader's); a session built from frames in Python without one has no recording to take it
    from and gets ``features.sample_rate`` of its sample times. clip_level: |a| (m/s^2) from which the
    reader flagged a sample clipped (the acquisition's rule on the recorded range; None when the
    session recorded no range); the flags are the acceleration's ``clipped`` column (all False when a
    frame built in Python has none). cycles: ``cut_cycles`` table; angles: ``angle_view`` of the
    acceleration (cycle, angle, value); gaps: acceleration time steps the acquisition counts as gaps
    (``acquisition.sequence.gaps``: dropped samples), windows spanning one are not scored;
    crank_angle: the encoder's crank angle (rad, unwrapped) at each acceleration sample; turns: its
    ``crank_turns`` (direction, progress and cycle index per sample, cycles from crank angle 0 as the
    features count them).
    """

    label: str
    acceleration: pd.DataFrame
    encoder: pd.DataFrame
    bench: Any = None  # wearbench.bench.schema.Bench or None
    clearances: dict[str, float] = field(default_factory=dict)
    wear_state: dict[str, str] = field(default_factory=dict)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    path: Path | None = None
    surface_files: dict[str, bytes] = field(default_factory=dict)  # joint -> worn-surface .npz embedded
    finished: bool = True  # False: the file was cut short (read up to its last complete chunk)
    problem: str | None = None  # why the file is not finished
    bench_problem: str | None = None  # the loader's words for why the recorded bench does not load (None: it loads,
    # or none is recorded)
    speed_tolerance: float = 0.02
    points_per_rev: int = 720
    fs: float | None = None  # Hz, as recorded (see the class docstring)
    clip_level: float | None = None  # m/s^2, as the reader applied it (see the class docstring)

    def __post_init__(self) -> None:
        for name, frame, cols in (("acceleration", self.acceleration, ("time", "acc")),
                                  ("encoder", self.encoder, ("time", "angle"))):
            missing = [c for c in cols if c not in frame.columns]
            if missing:
                raise ValueError(f"session {self.label}: {name} lacks column(s) {missing}")
        self.acceleration = self.acceleration.sort_values("time", kind="stable").reset_index(drop=True)
        if "clipped" not in self.acceleration.columns:
            self.acceleration["clipped"] = False
        self.encoder = self.encoder.sort_values("time", kind="stable").reset_index(drop=True)
        t = self.acceleration["time"].to_numpy(float)
        if t.size < 16:
            raise ValueError(f"session {self.label}: only {t.size} acceleration samples")
        if self.encoder["angle"].isna().all():
            raise ValueError(f"session {self.label}: the encoder angle is missing (no counts per revolution "
                             "in the bench or calibration)")
        if self.fs is None:  # built from frames, not read from a recording: the rate of its times
            self.fs = sample_rate(t)
        elif not 0 < self.fs < np.inf:
            raise ValueError(f"session {self.label}: fs = {self.fs!r} Hz: expected the positive sample rate "
                             "the session was recorded at")
        if self.clip_level is not None and not np.isfinite(self.clip_level):
            self.clip_level = None
        self.gap_times = t[:-1][gaps(np.diff(t), self.fs)]
        self.crank_angle = np.interp(t, self.encoder["time"].to_numpy(float), self.encoder["angle"].to_numpy(float))
        self.turns: CrankTurns = crank_turns(self.crank_angle)
        self.direction = self.turns.direction
        self.start_angle = reference_angle(self.encoder)
        self.cycles = cut_cycles(self.encoder, start_angle=self.start_angle,
                                 speed_tolerance=self.speed_tolerance)
        self.angles = angle_view(t, self.acceleration["acc"].to_numpy(float), self.encoder, self.cycles,
                                 start_angle=self.start_angle, points_per_rev=self.points_per_rev)

    @property
    def clipped(self) -> np.ndarray:
        """Which acceleration samples the reader flagged clipped (bool per sample)."""
        return self.acceleration["clipped"].to_numpy(bool)

    @property
    def samples(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Acceleration sample times (s), the crank angle at each (rad) and the samples (m/s^2)."""
        return self.acceleration["time"].to_numpy(float), self.crank_angle, self.acceleration["acc"].to_numpy(float)

    def to_dataframe(self) -> pd.DataFrame:
        """The acceleration samples as a table: device time (s), acceleration (m/s^2), the encoder's
        crank angle at each (rad, unwrapped) and the crank cycle it falls in (from crank angle 0)."""
        return pd.DataFrame({"time": self.acceleration["time"].to_numpy(float),
                             "acceleration": self.acceleration["acc"].to_numpy(float),
                             "crank_angle": self.crank_angle, "cycle": self.turns.cycle})

    @property
    def gaps(self) -> int:
        return int(self.gap_times.size)

    @property
    def steady_speed(self) -> float:
        """Mean crank speed (rad/s, signed) over the steady cycles."""
        steady = self.cycles[self.cycles["steady"]]
        if steady.empty:
            raise ValueError(f"session {self.label}: no steady complete crank cycle in the record")
        return float(2 * np.pi * len(steady) / (steady["t_end"] - steady["t_start"]).sum()) * self.direction

    @property
    def encoder_joint(self) -> str | None:
        """The joint of the crank the encoder reads (the bench's); None for a session without a bench."""
        return None if self.bench is None else self.bench.encoder_driver.joint

    @property
    def motor_speed(self) -> float:
        """Motor speed (rad/s) that turns the encoder's crank at the measured steady speed."""
        crank = self.steady_speed
        ratio = self.bench.encoder_driver.ratio if self.bench is not None else 0.0
        return crank / ratio if ratio else crank

    @property
    def commanded_speed(self) -> float:
        """The commanded motor speed (rad/s) as recorded in the session's metadata, else the measured one."""
        raw = self.metadata.get("session", {}).get("speed_rad_s")
        return float(raw) if raw is not None else self.motor_speed

    @property
    def stream_start(self) -> float:
        """When the accelerometer's stream began (s, device clock): :func:`stream_start`."""
        return stream_start(self.acceleration, self.fs)

    def features(self, spec: FeatureSpec | None = None) -> CycleFeatures:
        """Cycle features of the session, from its samples at :meth:`feature_angle`, its recorded
        sample rate and its samples' ``clipped`` flags (the reader's); ``spec``: default its bench's own
        at its commanded speed (``scaling.resolve_analysis``)."""
        spec = spec or resolve_analysis(self.bench, self.commanded_speed).features
        t, _, acc = self.samples
        return cycle_features(t, self.feature_angle(spec), acc, spec, clipped=self.clipped, fs=self.fs)

    def feature_angle(self, spec: FeatureSpec) -> np.ndarray:
        """The crank angle (rad) each acceleration sample is binned at for features of ``spec``: the
        encoder's at its time stamp, or, where the bench's stated chain delay moves a feature
        (:meth:`feature_delay`), the encoder's that much before it (when the sample was measured)."""
        t, angle, _ = self.samples
        delay = self.feature_delay(spec)
        if delay is None:
            return angle
        return np.interp(t - delay, self.encoder["time"].to_numpy(float), self.encoder["angle"].to_numpy(float))

    def resolution_note(self, features: CycleFeatures, steps: float = RESOLUTION_STEPS) -> str | None:
        """A note when the session's mean crank-angle curve (``features``' curve block) spans fewer
        than ``steps`` steps of its recorded resolution (the range over 32768, the protocols' int16
        LSB): the accelerometer's range is too coarse for the motion at this speed, and quantisation
        reshapes the curve the features compare (None otherwise, or without a recorded range)."""
        if self.clip_level is None or features.cycles < 1:
            return None
        lsb = self.clip_level / 32767.0
        span = float(np.ptp(features.curve.mean(axis=0)))
        if span >= steps * lsb:
            return None
        return (f"the session's crank-angle curve spans {span:.3g} m/s^2, {span / lsb:.1f} steps of its "
                f"{lsb:.3g} m/s^2 resolution (its {lsb * 32768 / 9.80665:,.0f} g range over 32768): the "
                "accelerometer's range is too coarse for the motion at this speed, and quantisation changes the "
                "features; a sensor with a smaller range sees it")

    def feature_delay(self, spec: FeatureSpec) -> np.ndarray | None:
        """The accelerometer's stated delay behind the encoder (s, per acceleration sample: its
        ``[sensor.chain]``, clock drift included) where it matters to features of ``spec``: where the
        chain's own delay reaches a hundredth of a crank-angle bin at the session's crank speed (at 5000 rpm a 27 us
        chain is 0.8 degrees, a twenty-fifth of a 20 degree bin; the test bed's 0.27 ms at 1 Hz is 0.1
        degree, a two-hundredth); None below that, or without a statement."""
        stated = self.stated_delay()
        if stated is None:
            return None
        t = self.acceleration["time"].to_numpy(float)
        delay = np.asarray(stated.at(t - self.stream_start), dtype=float)
        crank_hz = abs(self.commanded_speed * (self.bench.encoder_driver.ratio or 1.0)) / (2 * np.pi)
        if not crank_hz > 0 or abs(stated.constant) * crank_hz * spec.bins < 0.01:
            return None
        return delay

    def stated_delay(self, band: tuple[float, float] = (1.0, 100.0)) -> StatedDelay | None:
        """The accelerometer delay the session's bench states (its ``[sensor.chain]``), its filters'
        group delay averaged over ``band`` (Hz); None without a statement."""
        if self.bench is None:
            return None
        try:
            chain = self.bench.sensor("accelerometer").chain
        except KeyError:
            return None
        return stated_delay(chain, band) if chain is not None else None


def load_session(path: str | Path, *, label: str | None = None) -> MeasuredSession:
    """Read a session MCAP (tolerates unfinished files) into a ``MeasuredSession``; the label of an
    unfinished one (a killed recorder, a file cut short) says so: ``NAME (unfinished)``."""
    from wearbench.acquisition.session_file import read_session

    path = Path(path)
    s = read_session(path)
    if s.acceleration.empty:
        raise ValueError(f"{path}: the session holds no acceleration samples")
    if s.encoder.empty:
        raise ValueError(f"{path}: the session holds no encoder samples")
    if label is None:
        label = path.stem if s.finished else f"{path.stem} (unfinished)"
    return MeasuredSession(label=label, acceleration=s.acceleration[["time", "acc", "clipped"]],
                           encoder=s.encoder, bench=s.bench, clearances=dict(s.clearances),
                           wear_state=dict(s.wear_state), metadata=dict(s.metadata), path=path,
                           surface_files=dict(s.surface_files), finished=s.finished, problem=s.problem,
                           bench_problem=s.bench_problem,
                           fs=s.sample_rate, clip_level=s.clip_level)
