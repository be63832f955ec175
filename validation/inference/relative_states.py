"""State statistics of a calibrated bench: every state relative to the bench's own calibration session.

A calibration session of a known state ``k`` (``calibration.py``) measures, on the bench and mount
of the later sessions, everything that is the same in all its states: the sensor path (a mount or
carriage mode *inside* an impact band too, which reshapes the band across crank angles and is not
a per-band gain, README) and the bench's tolerance offsets (its masses, lengths and friction
against the file). So a later session of state ``s`` is compared with the calibration session
moved by the theory's difference between the states, not with the ensemble of ``s`` alone:

    xbar_s - xbar_cal ~ N(mu_s - mu_k, D_sk + Sw / n + Sw / n_cal)

``D_sk`` is the covariance of how one bench's offset differs between the two states. The ensembles
estimate it directly: realisation ``i`` of every state plays the same drawn bench (its seed), so
the paired differences of realisation means ``m_s,i - m_k,i`` have covariance ``D_sk + 2 Sw / C``
(shrunk, ``statistics.shrunk_covariance``; ``D_kk = 0``). The sensitivity multiplies the state
difference of the low-passed curve (``(g - 1) (mu_s - mu_k)``, the prior's ``g``, marginalised);
the band offsets of the path cancel. Each state becomes a ``StateStatistics`` with mean
``xbar_cal + mu_s - mu_k`` and between-covariance ``D_sk + Sw / n_cal``, so the likelihood, the
consistency test, the window verdicts and the diagnosis of ``identify.py`` apply unchanged; the
temperature and the consistency nulls come from held-out realisations played through the same
procedure (half of a realisation's cycles of ``k`` its calibration, its cycles of every state its
sessions: ``HeldOut``).

``WeightedStatistics`` conditions the ensembles on the calibration session instead: realisation
``i`` of every state is one drawn bench seen through one drawn sensor path, so it weights each by
the calibration session's likelihood under realisation ``i`` of ``k`` (tempered so that at least 8
realisations carry the weight, :func:`tempered_weights`) and uses the weighted means and
between-bench covariance. Neither beat the uncalibrated likelihood on drawn-path ensembles (README,
"The sensor path"), so neither is the default of ``identify``.

Imports validation.identify, statistics, sensor_path.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace

import numpy as np
from scipy import linalg
from wearbench.validation.inference.calibration import Calibration
from wearbench.validation.inference.ensemble import Ensemble
from wearbench.validation.inference.identify import (
    IdentifyOptions,
    StateModels,
    direction_distance2,
    fit_states,
    gamma_by_moments,
    temper,
    variance_floor,
    with_sensor,
)
from wearbench.validation.inference.sensor_path import SensorPath, calibrate_path
from wearbench.validation.inference.statistics import (
    StateStatistics,
    nearest_psd,
    shrunk_covariance,
)
from wearbench.validation.measurement.features import FeatureSpec

__all__ = ["HeldOut", "RelativeStatistics", "WeightedStatistics", "calibrated_models", "fit_calibrated",
           "tempered_weights"]


def _within(features: Mapping[str, np.ndarray]) -> np.ndarray:
    """The cycle-to-cycle covariance pooled over the states' realisations."""
    centred = [(f - f.mean(axis=1, keepdims=True)).reshape(-1, f.shape[-1]) for f in features.values()]
    m, c, _ = next(iter(features.values())).shape
    return shrunk_covariance(np.concatenate(centred)) * (m * c - 1) / (m * (c - 1))


def _paired(features: Mapping[str, np.ndarray], known: str) -> tuple[np.ndarray, dict, dict]:
    """Pooled within-covariance, and per state the mean and covariance ``D_sk`` of the paired
    differences of realisation means from the ``known`` state."""
    within = _within(features)
    c = features[known].shape[1]
    means, cov = {}, []
    for s, f in features.items():
        diff = f.mean(axis=1) - features[known].mean(axis=1)  # realisation i is the same bench in every state
        means[s] = diff.mean(axis=0)
        if s != known:
            cov.append(nearest_psd(shrunk_covariance(diff) - 2.0 * within / c))
    # pooled over the states, the known one included (as the candidates' covariances are pooled): a
    # state of its own, tighter covariance would win every session near the calibration by its determinant
    pooled = np.mean(cov, axis=0) if cov else np.zeros_like(within)
    return within, means, {s: pooled for s in features}


def tempered_weights(log_likelihood: np.ndarray, ess: float) -> tuple[np.ndarray, float]:
    """Weights ``w_i ~ L_i ** beta`` of realisations with log likelihoods ``log_likelihood`` of a
    calibration session, and ``beta``: the largest ``beta`` in [0, 1] whose effective sample size
    ``1 / sum w^2`` is at least ``ess`` (all of them when fewer), so a few realisations never carry
    the whole weight (bisection; the effective size falls as ``beta`` grows)."""
    ll = np.asarray(log_likelihood, dtype=float)
    target = min(float(ess), float(ll.size))

    def weights(beta: float) -> np.ndarray:
        z = beta * (ll - ll.max())
        w = np.exp(z)
        return w / w.sum()

    def size(w: np.ndarray) -> float:
        return 1.0 / float(np.sum(w * w))

    if size(weights(1.0)) >= target:
        return weights(1.0), 1.0
    lo, hi = 0.0, 1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if size(weights(mid)) >= target else (lo, mid)
    return weights(lo), lo


@dataclass(frozen=True)
class HeldOut:
    """What the procedure of a calibrated bench gives held-out realisations, each playing a bench:
    half of its cycles of the known state its calibration, its other cycles its sessions (the
    temperature, the consistency nulls of ``identify.StateModels``, and the cycles about each state's
    ensemble mean for the cycle bands)."""

    temperature: float
    null: Mapping[str, tuple[float, float]]
    null_direction: Mapping[str, tuple[float, float]]
    window_null: Mapping[str, np.ndarray]
    window_cycles: int
    spread: Mapping[str, np.ndarray]

    @classmethod
    def play(cls, features: Mapping[str, np.ndarray], known: str, window_cycles: int,
             fit: Callable[[Mapping[str, np.ndarray]], _Calibrated]) -> HeldOut:
        """Realisation ``r`` of every state (the same bench) left out in turn: ``fit`` the statistics
        on the others, calibrate them on its first half of ``known`` cycles, judge its sessions."""
        names = tuple(features)
        m, c, _ = features[known].shape
        half = c // 2
        lls, truth = [], []
        d2, t2, wn = ({s: [] for s in names} for _ in range(3))
        for r in range(m):
            models = fit({s: np.delete(f, r, axis=0) for s, f in features.items()}).states(
                features[known][r, :half].mean(axis=0), half)
            for si, s in enumerate(names):
                cycles = features[s][r, half:] if s == known else features[s][r]
                xbar, n = cycles.mean(axis=0), cycles.shape[0]
                st, others = models[s], [models[t].mean for t in names if t != s]
                d2[s].append(st.distance2(xbar, n))
                t2[s].append(direction_distance2(st, others, xbar, n))
                lls.append([models[t].log_likelihood(xbar, n) for t in names])
                truth.append(si)
                w = min(window_cycles, n)
                for k in range(n - w + 1):
                    wbar = cycles[k:k + w].mean(axis=0)
                    wn[s].append((st.distance2(wbar, w), direction_distance2(st, others, wbar, w)))
        return cls(temper(np.asarray(lls), np.asarray(truth)) if len(names) > 1 else 1.0,
                   {s: gamma_by_moments(d2[s]) for s in names},
                   {s: gamma_by_moments(t2[s]) if len(names) > 1 else (1.0, 1.0) for s in names},
                   {s: np.asarray(wn[s]).reshape(-1, 2) for s in names}, window_cycles,
                   {s: (f - f.mean(axis=(0, 1))).reshape(-1, f.shape[-1]) for s, f in features.items()})


def _checked(ensembles: Mapping[str, Ensemble], known: str) -> dict[str, np.ndarray]:
    """The ensembles' features, when they are paired (same realisation seeds, none failed) and
    ``known`` is among them; else ValueError."""
    if known not in ensembles:
        raise ValueError(f"calibration state {known!r} is not among the candidates {list(ensembles)}")
    sizes = {s: e.features.shape[:2] for s, e in ensembles.items()}
    if len(set(sizes.values())) != 1 or any(e.failures for e in ensembles.values()) or len(
            {e.settings.seed for e in ensembles.values()}) != 1:
        raise ValueError(f"calibrated identification needs paired ensembles (same realisation seeds, none "
                         f"failed); got shapes {sizes} and failures "
                         f"{ {s: len(e.failures) for s, e in ensembles.items()} }")
    return {s: e.features for s, e in ensembles.items()}


class _Calibrated:
    """State statistics placed at a bench's calibration session: ``states`` (per subclass) and
    ``models`` (shared); subclasses hold ``names``, ``spec``, ``options`` and ``held`` (``HeldOut``)."""

    names: tuple[str, ...]
    spec: FeatureSpec
    options: IdentifyOptions
    held: HeldOut | None

    def states(self, xbar_cal: np.ndarray, n_cal: float) -> dict[str, StateStatistics]:
        raise NotImplementedError

    def models(self, xbar_cal: np.ndarray, n_cal: float, reference: str = "") -> StateModels:
        """``StateModels`` of a bench whose calibration sessions of the known state had mean features
        ``xbar_cal`` (all the spec's features) over ``n_cal`` cycles; ``reference`` names them in results."""
        xbar_cal = np.asarray(xbar_cal, dtype=float)
        if xbar_cal.shape != (self.spec.size,):
            raise ValueError(f"calibration features: expected {self.spec.size} values of the ensembles' feature "
                             f"spec, got {xbar_cal.shape}")
        held = self.held
        fitted = self.states(xbar_cal, n_cal)
        limit, lo, hi = {}, {}, {}
        for s, st in fitted.items():
            d = held.spread[s]
            limit[s] = float(np.percentile(np.einsum("ij,jk,ik->i", d, np.linalg.inv(st.covariance(1)), d), 95))
            lo[s], hi[s] = st.mean + np.percentile(d, 5, axis=0), st.mean + np.percentile(d, 95, axis=0)
        return StateModels(self.names, fitted, held.temperature, held.null, held.null_direction, limit, lo, hi,
                           self.options, window_null=held.window_null, window_cycles=held.window_cycles,
                           spec=self.spec, sensor=None, reference=reference)


@dataclass(frozen=True)
class RelativeStatistics(_Calibrated):
    """What a calibration's models need from the ensembles, whatever the calibration session: the
    paired state differences from the ``known`` state and the held-out nulls and temperature
    (see the module docstring); :meth:`models` places them at a calibration session."""

    names: tuple[str, ...]
    known: str
    within: np.ndarray
    means: Mapping[str, np.ndarray]   # mu_s - mu_k
    paired: Mapping[str, np.ndarray]  # D_sk
    floor: np.ndarray
    gain_var: float                   # variance of the sensitivity (the sensor-path prior's)
    realisations: int
    cycles: int
    options: IdentifyOptions
    spec: FeatureSpec
    held: HeldOut | None = None

    @classmethod
    def fit(cls, ensembles: Mapping[str, Ensemble], known: str, options: IdentifyOptions | None = None, *,
            window_cycles: int = 5) -> RelativeStatistics:
        """From paired ensembles (the same realisation seeds in every state, none failed: ValueError
        otherwise) of the candidate states, ``known`` among them."""
        options = options or IdentifyOptions()
        features = _checked(ensembles, known)
        spec = ensembles[known].settings.features
        floor = variance_floor(spec, options)
        gain_var = float(SensorPath.prior(spec).theta_cov[0, 0])

        def fit(f: Mapping[str, np.ndarray]) -> RelativeStatistics:
            m, c, _ = f[known].shape
            return cls(tuple(f), known, *_paired(f, known), floor, gain_var, m, c, options, spec)

        return replace(fit(features), held=HeldOut.play(features, known, window_cycles, fit))

    def states(self, xbar_cal: np.ndarray, n_cal: float) -> dict[str, StateStatistics]:
        """Each state's statistics relative to a calibration mean ``xbar_cal`` of ``n_cal`` cycles."""
        out = {}
        for s in self.names:
            st = StateStatistics(xbar_cal + self.means[s], self.within, self.paired[s] + self.within / n_cal,
                                 self.floor, self.realisations, self.cycles)
            gain = np.zeros((st.mean.size, 1))  # the sensitivity scales the states' difference of the curve
            gain[:self.spec.bins, 0] = self.means[s][:self.spec.bins] * np.sqrt(self.gain_var)
            out[s] = replace(st, nuisance=gain)
        return out


@dataclass(frozen=True)
class WeightedStatistics(_Calibrated):
    """The ensembles conditioned on a calibration session: realisation ``i`` of every state is one
    drawn bench seen through one drawn sensor path, so how well realisation ``i`` of the known state
    explains the calibration session says how much that bench and path resemble the real ones.
    Each realisation is weighted by that likelihood, tempered (:func:`tempered_weights`) so that at
    least ``ess`` realisations carry the weight, and every state's mean and between-bench covariance
    are the weighted ones (the cycle-to-cycle covariance stays pooled over all). The band gains
    left are fitted to the calibration session against the conditioned known state
    (``sensor_path.calibrate_path``, from the prior of ``options.sensor_path``) and marginalised in
    every state."""

    names: tuple[str, ...]
    known: str
    within: np.ndarray
    realisation_means: Mapping[str, np.ndarray]  # (M, p) per state
    floor: np.ndarray
    cycles: int
    options: IdentifyOptions
    spec: FeatureSpec
    ess: float = 8.0
    held: HeldOut | None = None

    @classmethod
    def fit(cls, ensembles: Mapping[str, Ensemble], known: str, options: IdentifyOptions | None = None, *,
            window_cycles: int = 5, ess: float = 8.0) -> WeightedStatistics:
        """From paired ensembles (as :meth:`RelativeStatistics.fit`); ``ess``: the effective number of
        realisations the weights keep at least."""
        options = options or IdentifyOptions()
        features = _checked(ensembles, known)
        spec = ensembles[known].settings.features
        floor = variance_floor(spec, options)

        def fit(f: Mapping[str, np.ndarray]) -> WeightedStatistics:
            return cls(tuple(f), known, _within(f), {s: v.mean(axis=1) for s, v in f.items()}, floor,
                       f[known].shape[1], options, spec, ess)

        return replace(fit(features), held=HeldOut.play(features, known, window_cycles, fit))

    def _prior(self) -> SensorPath | None:
        return SensorPath.prior(self.spec) if self.options.sensor_path == "prior" else None

    def weights(self, xbar_cal: np.ndarray, n_cal: float) -> np.ndarray:
        """Each realisation's weight given a calibration mean ``xbar_cal`` of ``n_cal`` cycles: its
        Gaussian likelihood under the realisation's known-state mean with the cycles' noise of both
        (``Sw / n_cal + Sw / C``), the floor and the prior's band gains (what the fit absorbs later)."""
        means = self.realisation_means[self.known]
        cov = self.within * (1.0 / n_cal + 1.0 / self.cycles) + np.diag(self.floor)
        prior = self._prior()
        if prior is not None:
            shift, factor = prior.nuisance(self.spec, means.mean(axis=0))
            cov = cov + factor @ factor.T
            means = means + shift
        chol = linalg.cholesky(cov, lower=True)
        z = linalg.solve_triangular(chol, (np.asarray(xbar_cal, dtype=float) - means).T, lower=True)
        return tempered_weights(-0.5 * np.sum(z * z, axis=0), self.ess)[0]

    def states(self, xbar_cal: np.ndarray, n_cal: float) -> dict[str, StateStatistics]:
        """Each state's statistics conditioned on a calibration mean ``xbar_cal`` of ``n_cal`` cycles."""
        w = self.weights(xbar_cal, n_cal)
        c = self.cycles
        between = np.mean([nearest_psd(shrunk_covariance(v, w) - self.within / c)
                           for v in self.realisation_means.values()], axis=0)
        size = max(3, round(1.0 / float(np.sum(w * w))))
        out = {s: StateStatistics(w @ v, self.within, between, self.floor, size, c)
               for s, v in self.realisation_means.items()}
        prior = self._prior()
        if prior is None:
            return out
        k = out[self.known]
        path = calibrate_path(xbar_cal, k.mean, k.covariance(n_cal), self.spec, prior, source="calibration")
        return {s: with_sensor(st, self.spec, path) for s, st in out.items()}


def fit_calibrated(ensembles: Mapping[str, Ensemble], known: str, xbar_cal: np.ndarray, n_cal: int,
                   options: IdentifyOptions | None = None, *, window_cycles: int = 5,
                   reference: str = "") -> StateModels:
    """``StateModels`` of a bench calibrated on ``n_cal`` cycles of the ``known`` state with mean
    features ``xbar_cal``: ``RelativeStatistics.fit(...).models(...)``."""
    return RelativeStatistics.fit(ensembles, known, options, window_cycles=window_cycles).models(
        xbar_cal, n_cal, reference)


def calibrated_models(ensembles: Mapping[str, Ensemble], calibration: Calibration,
                      options: IdentifyOptions | None = None, *, window_cycles: int = 5) -> StateModels:
    """The state statistics a session of a calibrated bench is judged with: relative to the
    ``calibration``'s sessions (:func:`fit_calibrated`) when it holds their features, its known state is
    a candidate and the ensembles are paired; else its fitted sensor path marginalised
    (``identify.fit_states(..., sensor=)``, calibrations of earlier versions)."""
    options, ref = options or IdentifyOptions(), calibration.describe()
    if calibration.features and calibration.state in ensembles:
        try:
            return fit_calibrated(ensembles, calibration.state, np.asarray(calibration.features), calibration.cycles,
                                  options, window_cycles=window_cycles, reference=ref)
        except ValueError:
            pass
    return replace(fit_states(ensembles, options, window_cycles=window_cycles, sensor=calibration.path),
                   reference=f"{ref}, its sensor path only")
