"""Per-cycle features of the accelerometer's signal that survive chaos, addressed by crank angle.

Impacts in clearance joints are chaotic: two realisations of one state part within tens of
milliseconds, so one trajectory is never compared sample by sample with another. What a state
fixes is the statistics of each crank cycle at each crank angle. A cycle becomes a vector of
blocks over ``bins`` equal crank-angle bins (absolute crank angle of the encoder joint, so test
and theory share the bins):

- ``curve``: the mean, in each bin, of the acceleration low-passed at ``lowpass`` Hz (zero-phase
  Butterworth): the kinematics and the slow dynamics, m/s^2.
- ``energy``: one block per band of ``bands`` (Hz): log10 of the mean square, in each bin, of the
  acceleration band-passed to that band: how hard the joints impact there, and with which
  spectrum (worn, more conformal surfaces make longer, lower-pitched impacts). Bands above about
  1 kHz are left out on purpose: a real accelerometer's mounting resonance changes them and the
  model knows nothing of it. ``floor`` (m^2/s^4) keeps the logarithm finite in quiet bins.

The defaults were chosen by measurement (``benchmarks/validation/identify.py`` and the README's
identification section): 20 degree bins and three impact bands separate the test bed's new and
first-wear states where 10 degree bins of one 100-1000 Hz band did not. They are the test bed's at
its 1 Hz crank: a spec is in hertz, and ``scaling.resolve_analysis`` gives every bench's at its speed
(crank orders, the sensor chain's cap).

Pure numpy/scipy; imports only ``wearbench.validation.measurement.filters``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy import signal
from wearbench.validation.measurement.cycles import crank_turns
from wearbench.validation.measurement.filters import FilterSpec, apply_filter

__all__ = ["CycleFeatures", "FeatureSpec", "cycle_features", "sample_rate"]

TWO_PI = 2.0 * np.pi


@dataclass(frozen=True)
class FeatureSpec:
    """What a cycle's feature vector holds (see the module docstring)."""

    bins: int = 18                            # crank-angle bins per revolution (20 deg)
    lowpass: float = 50.0                     # Hz
    bands: tuple[tuple[float, float], ...] = ((50.0, 150.0), (150.0, 400.0), (400.0, 1000.0))  # Hz
    floor: float = 1.0                        # m^2/s^4 added before the logarithm

    def __post_init__(self) -> None:
        bands = tuple((float(lo), float(hi)) for lo, hi in self.bands)
        if self.bins < 1 or not bands or any(not 0 < lo < hi for lo, hi in bands):
            raise ValueError(f"features: bins = {self.bins}, bands = {self.bands}: expected at least one bin "
                             "and one band (lo, hi) Hz with 0 < lo < hi")
        object.__setattr__(self, "bands", bands)

    @classmethod
    def from_dict(cls, data: dict) -> FeatureSpec:
        """The inverse of :meth:`to_dict` (lists from JSON back to tuples); a file of an earlier
        version holds one ``band``."""
        data = dict(data)
        bands = data.pop("bands", None) or [data.pop("band")]
        return cls(**{**data, "bands": tuple(tuple(b) for b in bands)})

    def to_dict(self) -> dict:
        return asdict(self)

    @property
    def size(self) -> int:
        return (1 + len(self.bands)) * self.bins


@dataclass(frozen=True)
class CycleFeatures:
    """Features of the complete cycles of one record: ``values`` (cycles, size) = [curve | energy of
    each band]."""

    spec: FeatureSpec
    values: np.ndarray
    clipped: np.ndarray  # (cycles,) samples flagged clipped in each cycle (0 if unknown)

    @property
    def cycles(self) -> int:
        return int(self.values.shape[0])

    @property
    def curve(self) -> np.ndarray:
        return self.values[:, : self.spec.bins]

    @property
    def energy(self) -> np.ndarray:
        """(cycles, bands, bins) log10 band energies."""
        return self.values[:, self.spec.bins:].reshape(self.cycles, len(self.spec.bands), self.spec.bins)


def _band(x: np.ndarray, fs: float, band: tuple[float, float]) -> np.ndarray:
    lo, hi = band
    hi = min(hi, 0.45 * fs)
    if not 0 < lo < hi:
        raise ValueError(f"features: band {band} Hz does not fit below the Nyquist frequency {fs / 2:g} Hz")
    sos = signal.butter(4, (lo, hi), btype="bandpass", fs=fs, output="sos")
    return signal.sosfiltfilt(sos, x, padtype="odd", padlen=min(x.size - 1, int(10 * fs / lo)))


def sample_rate(t: np.ndarray) -> float:
    """The sample rate (Hz) of uniformly sampled times ``t`` (s): 1 / the median step. A measured
    session's is its own (``MeasuredSession.fs``): callers on the measured path pass it."""
    return float(1.0 / np.median(np.diff(t)))


def cycle_features(t: np.ndarray, angle: np.ndarray, acc: np.ndarray, spec: FeatureSpec = FeatureSpec(), *,
                   clipped: np.ndarray | None = None, fs: float | None = None) -> CycleFeatures:
    """Features of every complete crank revolution of a record.

    t: sample times (s, uniform rate); angle: unwrapped absolute crank angle at those times (rad;
    either sense of rotation); acc: slider acceleration (m/s^2). A cycle runs from one crossing of
    crank angle 0 (mod 2 pi, in the sense of rotation) to the next; partial cycles at the ends are
    dropped. clipped: which samples are clipped (bool per sample: a session's ``clipped`` column, which
    the session reader flags by the acquisition's clip rule on the recorded range; None: not known,
    none counted). fs: the sample rate (Hz; default :func:`sample_rate` of ``t``).
    """
    t = np.asarray(t, dtype=float)
    angle = np.asarray(angle, dtype=float)
    acc = np.asarray(acc, dtype=float)
    if not t.size == angle.size == acc.size or t.size < 16:
        raise ValueError(f"features: expected equal arrays of at least 16 samples, got {t.size}, {angle.size}, "
                         f"{acc.size}")
    if not np.all(np.isfinite(acc)):
        raise ValueError(f"features: {int(np.sum(~np.isfinite(acc)))} non-finite acceleration samples")
    flags = None if clipped is None else np.asarray(clipped, dtype=bool)
    if flags is not None and flags.shape != acc.shape:
        raise ValueError(f"features: {flags.size} clipped flags for {acc.size} samples; expected one per sample")
    fs = sample_rate(t) if fs is None else fs
    turns = crank_turns(angle)  # cycles from crank angle 0
    u, cycle, first, last = turns.progress, turns.cycle, turns.first, turns.last
    if last < first:
        return CycleFeatures(spec, np.zeros((0, spec.size)), np.zeros(0, dtype=np.int64))
    keep = (cycle >= first) & (cycle <= last)
    # over whole cycles the slider acceleration averages to zero: what remains is sensor bias
    centred = acc - acc[keep].mean()
    curve = apply_filter(centred, fs, FilterSpec(kind="butter", cutoff=spec.lowpass, order=4, remove_bias=False))
    k = cycle[keep] - first
    b = np.minimum((np.mod(u[keep], TWO_PI) * (spec.bins / TWO_PI)).astype(np.int64), spec.bins - 1)
    cells = k * spec.bins + b
    n_cells = (last - first + 1) * spec.bins
    count = np.bincount(cells, minlength=n_cells).astype(float)
    if np.any(count == 0):
        raise ValueError(f"features: a {360 / spec.bins:g} deg crank-angle bin holds no sample at {fs:g} Hz; "
                         "the record is too coarse or the crank stood still")
    blocks = [(np.bincount(cells, curve[keep], n_cells) / count).reshape(-1, spec.bins)]
    for band in spec.bands:
        power = _band(centred, fs, band)[keep] ** 2
        blocks.append(np.log10((np.bincount(cells, power, n_cells) / count).reshape(-1, spec.bins) + spec.floor))
    values = np.hstack(blocks)
    counts = np.zeros(last - first + 1, dtype=np.int64)
    if flags is not None:
        counts = np.bincount(k[flags[keep]], minlength=counts.size)
    return CycleFeatures(spec, values, counts)


def cycle_curves(t: np.ndarray, angle: np.ndarray, acc: np.ndarray, *, grid: int = 720,
                 filter_spec: FilterSpec | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Each complete cycle of a record as a curve on ``grid`` equal crank-angle steps (cycles cut at
    crank angle 0 as in :func:`cycle_features`), and each cycle's peak |acc| after the filter
    (m/s^2; raw peaks depend on the sensor chain's bandwidth, which the model does not have).

    filter_spec: the zero-phase filter applied to the whole record first (default CFC 180);
    the record's mean over whole cycles (sensor bias) is removed.
    """
    t = np.asarray(t, dtype=float)
    acc = np.asarray(acc, dtype=float)
    turns = crank_turns(angle)
    u, cycle, k0, k1 = turns.progress, turns.cycle, turns.first, turns.last
    fs = sample_rate(t)
    if k1 < k0:
        return np.zeros((0, grid)), np.zeros(0)
    whole = (cycle >= k0) & (cycle <= k1)
    filtered = apply_filter(acc - acc[whole].mean(), fs, filter_spec or FilterSpec(remove_bias=False))
    steps = np.arange(grid) * (TWO_PI / grid)
    curves = np.empty((k1 - k0 + 1, grid))
    peaks = np.empty(k1 - k0 + 1)
    for c, k in enumerate(range(k0, k1 + 1)):
        curves[c] = np.interp(k * TWO_PI + steps, u, filtered)
        inside = (u >= k * TWO_PI) & (u < (k + 1) * TWO_PI)
        peaks[c] = float(np.max(np.abs(filtered[inside])))
    return curves, peaks
