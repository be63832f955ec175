"""What an unknown sensor path does to the cycle features, as nuisance parameters of the likelihood.

A real accelerometer sits on a mount or carriage with structural modes of its own (a few hundred Hz
to a few kHz), a sensitivity off by a few %, cable and DAQ filters: a smooth transfer function the
bench file does not state. Through it, the features of ``features.py`` change in two ways that do
not depend on the wear state:

- each impact band's log10 energy moves by an additive offset ``o_k = log10 <|G(f)|^2>`` over the
  band (one number per band, the same at every crank angle: the path is linear and time-invariant);
- the 50 Hz low-passed mean curve is scaled by the sensitivity at low frequency ``g``.

So the features are ``x + A theta`` with ``theta = (g - 1, o_1 .. o_K)`` and ``A`` = [state's mean
curve on the curve block | one indicator column per band block]. With a Gaussian prior
``theta ~ N(m, P)`` the offsets marginalise exactly: the mean moves by ``A m`` and the covariance
gains the low-rank term ``A P A^T`` (:meth:`SensorPath.nuisance`, added once, in
``StateStatistics.covariance``, so identification, its consistency test and the estimator all use it).
What is lost: the absolute level of each band (the crank-angle shape within a band and the ratios
between crank angles are kept); ``benchmarks/validation/identify.py --sensor-paths`` measures it.

The default prior (:meth:`SensorPath.prior`) is that of a second-order mode log-uniform between
0.3 and 3 x the top band's upper edge (:meth:`PathSpread.around`: 300 Hz-3 kHz for the test bed's
1 kHz; the bands move with the crank, ``measurement.scaling``) with damping ratio 0.02-0.1 and a
sensitivity within +/-5 %, averaged over each band by quadrature (a flat spectrum within the band). ``wearbench calibrate`` narrows it to the
posterior of one bench's path from sessions of a known state (:func:`calibrate_path`).

Per-band gains absorb a mode outside the bands and the sensitivity, not a mode inside a band: that
reshapes the band across crank angles (impacts at different crank angles have different spectra,
and a lightly damped mode rings into the next bin). So the ensembles also see the path: each
realisation through its own drawn mount (:class:`PathSpread`, :func:`mount_response`, applied in
``ensemble.realisation_summary``), and the pooled between-bench covariance holds what a path does to
the features; the band-gain prior stays on top (measured in the README, "The sensor path").

Pure numpy; imports only the feature spec.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import signal
from wearbench.validation.measurement.features import FeatureSpec

__all__ = ["PathSpread", "SensorPath", "calibrate_path", "design_matrix", "mount_response"]


def mount_response(acc: np.ndarray, fs: float, mode: float, damping: float, gain: float = 1.0) -> np.ndarray:
    """``acc`` (sampled at ``fs`` Hz) seen through a mount or carriage: a second-order low-pass mode at
    ``mode`` Hz with damping ratio ``damping`` (causal, bilinear with the peak pre-warped to ``mode``, as
    the bench emulator's sensor chain has it) and a sensitivity ``gain``."""
    if not 0 < mode < 0.45 * fs or not damping > 0:
        raise ValueError(f"sensor path: mode {mode:g} Hz, damping {damping:g}: expected 0 < mode < "
                         f"{0.45 * fs:g} Hz (0.45 x the {fs:g} Hz rate) and a positive damping ratio")
    wn = 2.0 * fs * np.tan(np.pi * mode / fs)
    sos = signal.tf2sos(*signal.bilinear([wn * wn], [1.0, 2.0 * damping * wn, wn * wn], fs))
    x = np.asarray(acc, dtype=float)
    y, _ = signal.sosfilt(sos, x, zi=signal.sosfilt_zi(sos) * x[0])
    return gain * y


@dataclass(frozen=True)
class PathSpread:
    """Sensor paths drawn per realisation of a theory ensemble (``EnsembleSettings.sensor_paths``): a
    mount/carriage mode log-uniform in ``mode`` (Hz), damping ratio uniform in ``damping``, sensitivity
    uniform within +/- ``sensitivity``; realisation seed ``s`` draws its own path, so the ensemble's
    spread (and every likelihood, consistency test and estimate built on it) holds the path a bench
    file does not state, its effect on each band's crank-angle shape included (ringing, a mode inside a
    band), which band gains alone cannot absorb."""

    mode: tuple[float, float] = (300.0, 3000.0)
    damping: tuple[float, float] = (0.02, 0.1)
    sensitivity: float = 0.05

    def __post_init__(self) -> None:
        mode = (float(self.mode[0]), float(self.mode[1]))
        damping = (float(self.damping[0]), float(self.damping[1]))
        if not 0 < mode[0] <= mode[1] or not 0 < damping[0] <= damping[1] or not 0 <= self.sensitivity < 0.5:
            raise ValueError(f"sensor paths: mode {self.mode} Hz, damping {self.damping}, sensitivity "
                             f"{self.sensitivity}: expected 0 < low <= high for mode and damping and a "
                             "sensitivity spread in [0, 0.5)")
        object.__setattr__(self, "mode", mode)
        object.__setattr__(self, "damping", damping)

    @classmethod
    def around(cls, spec: FeatureSpec, low: float = 0.3, high: float = 3.0) -> PathSpread:
        """The drawn mounts of an analysis whose features are ``spec``: a mode between ``low`` and ``high``
        x the top band's upper edge (a lab mounts its sensor so that its modes sit near the band it
        analyses, not far below it), damping and sensitivity as the defaults. The test bed's 1 kHz top
        gives the default 300 Hz-3 kHz."""
        top = max(hi for _, hi in spec.bands)
        return cls(mode=(top * low, top * high))

    def draw(self, seed: int) -> tuple[float, float, float]:
        """(mode Hz, damping ratio, sensitivity) of realisation ``seed``."""
        rng = np.random.default_rng([int(seed), 0x4D4F])
        lo, hi = self.mode
        mode = float(np.exp(rng.uniform(np.log(lo), np.log(hi))))
        return mode, float(rng.uniform(*self.damping)), float(1.0 + rng.uniform(-self.sensitivity, self.sensitivity))

    def apply(self, acc: np.ndarray, fs: float, seed: int) -> np.ndarray:
        """``acc`` seen through realisation ``seed``'s drawn path (:func:`mount_response`)."""
        return mount_response(acc, fs, *self.draw(seed))

    @classmethod
    def from_dict(cls, data: dict | None) -> PathSpread | None:
        return None if data is None else cls(tuple(data["mode"]), tuple(data["damping"]), float(data["sensitivity"]))


def design_matrix(spec: FeatureSpec, mean: np.ndarray, columns: slice = slice(None)) -> np.ndarray:
    """``A`` (features, 1 + bands): d features / d theta at a state's ``mean`` (full feature vector)."""
    a = np.zeros((spec.size, 1 + len(spec.bands)))
    a[: spec.bins, 0] = mean[: spec.bins]
    for k in range(len(spec.bands)):
        a[(k + 1) * spec.bins:(k + 2) * spec.bins, k + 1] = 1.0
    return a[columns]


def _mode_offsets(bands: Sequence[tuple[float, float]], mode: float, damping: float, gain: float) -> np.ndarray:
    """log10 of a second-order low-pass mode's power gain averaged over each band (flat spectrum)."""
    out = []
    for lo, hi in bands:
        f = np.linspace(lo, hi, 256)
        r = f / mode
        power = gain ** 2 / ((1 - r * r) ** 2 + (2 * damping * r) ** 2)
        out.append(np.log10(power.mean()))
    return np.asarray(out)


@dataclass(frozen=True)
class SensorPath:
    """Gaussian belief about theta = (g - 1, o_1 .. o_K) (see the module docstring)."""

    mean: tuple[float, ...]
    cov: tuple[tuple[float, ...], ...]
    source: str

    @classmethod
    def prior(cls, spec: FeatureSpec, spread: PathSpread | None = None) -> SensorPath:
        """The prior of an unmeasured path drawn as ``spread`` draws it (default
        :meth:`PathSpread.around` the bands of ``spec``): a structural mode log-uniform in its ``mode``
        (Hz), damping uniform in its ``damping``, sensitivity uniform within +/- its ``sensitivity``
        (moments by quadrature); the curve's content taken at a thirtieth of the lowest mode (the
        test bed's 10 Hz for 300 Hz)."""
        spread = spread or PathSpread.around(spec)
        mode, damping, sensitivity = spread.mode, spread.damping, spread.sensitivity
        curve = mode[0] / 30.0
        fr = np.geomspace(*mode, 41)
        zeta = np.linspace(*damping, 5)
        gains = 1.0 + np.linspace(-sensitivity, sensitivity, 5)
        rows = []
        for f in fr:
            for z in zeta:
                for g in gains:
                    low = g / abs(1 - (curve / f) ** 2 + 2j * z * curve / f)  # the curve's content
                    rows.append(np.concatenate([[low - 1.0], _mode_offsets(spec.bands, f, z, g)]))
        theta = np.asarray(rows)
        cov = np.cov(theta.T) + np.diag(np.full(theta.shape[1], 1e-6))
        return cls(tuple(theta.mean(axis=0)), tuple(map(tuple, cov)),
                   f"prior: a mount/carriage mode {mode[0]:g}-{mode[1]:g} Hz, damping {damping[0]:g}-{damping[1]:g}, "
                   f"sensitivity +/-{100 * sensitivity:g} %")

    @classmethod
    def none(cls, spec: FeatureSpec) -> SensorPath:
        """No band-gain nuisance: the ensembles' own spread (their drawn paths, if any) is all the
        likelihood allows for; earlier versions' likelihood with ensembles without drawn paths."""
        k = 1 + len(spec.bands)
        return cls((0.0,) * k, tuple((0.0,) * k for _ in range(k)), "none: the bench file's sensor path taken as exact")

    @property
    def theta_mean(self) -> np.ndarray:
        return np.asarray(self.mean, dtype=float)

    @property
    def theta_cov(self) -> np.ndarray:
        return np.asarray(self.cov, dtype=float)

    def nuisance(self, spec: FeatureSpec, mean: np.ndarray, columns: slice = slice(None)
                 ) -> tuple[np.ndarray, np.ndarray]:
        """(shift of the state's mean, factor F with F F^T the covariance added) for a state whose
        full feature mean is ``mean``; rows restricted to ``columns``."""
        a = design_matrix(spec, mean, columns)
        vals, vecs = np.linalg.eigh(self.theta_cov)
        factor = a @ (vecs * np.sqrt(np.clip(vals, 0.0, None)))
        return a @ self.theta_mean, factor

    def gains_db(self) -> dict[str, float]:
        """The mean path as printable numbers: the low-frequency gain and each band's gain (dB)."""
        m = self.theta_mean
        return {"gain": float(1.0 + m[0]), **{f"band {k + 1}": float(10.0 * v) for k, v in enumerate(m[1:])}}

    def to_dict(self) -> dict:
        return {"mean": list(self.mean), "cov": [list(r) for r in self.cov], "source": self.source}

    @classmethod
    def from_dict(cls, data: dict) -> SensorPath:
        return cls(tuple(float(v) for v in data["mean"]), tuple(tuple(float(v) for v in r) for r in data["cov"]),
                   str(data["source"]))


def calibrate_path(xbar: np.ndarray, state_mean: np.ndarray, covariance: np.ndarray, spec: FeatureSpec,
                   prior: SensorPath, *, source: str) -> SensorPath:
    """The posterior of theta from a session's mean features ``xbar`` of a KNOWN state (its ensemble
    ``state_mean`` and ``covariance`` of the session mean without sensor nuisance): Gaussian conditioning,
    ``P' = (P^-1 + A^T C^-1 A)^-1``, ``m' = P' (P^-1 m + A^T C^-1 (xbar - mean))``."""
    a = design_matrix(spec, state_mean)
    p_inv = np.linalg.inv(prior.theta_cov)
    ct_a = np.linalg.solve(covariance, a)
    post_cov = np.linalg.inv(p_inv + a.T @ ct_a)
    post_mean = post_cov @ (p_inv @ prior.theta_mean + ct_a.T @ (np.asarray(xbar, dtype=float) - state_mean))
    post_cov = 0.5 * (post_cov + post_cov.T)
    return SensorPath(tuple(post_mean), tuple(map(tuple, post_cov)), source)
