"""Which candidate state explains a session: posterior probabilities from theory ensembles.

For each candidate state its ensemble gives the statistics of cycle features
(``statistics.StateStatistics``), with the between-bench and cycle-to-cycle covariances pooled
over the candidates (``StateStatistics.pooled``: the states of one bench share its tolerances).
A session's ``n`` complete cycles give the mean feature vector;
its likelihood under each state, tempered by a factor learnt from the ensembles themselves
(leave-one-realisation-out: each held-out realisation plays a session of its ``C`` cycles and
the temperature minimises their log loss), gives the posterior with a uniform prior. The top
state is named only when its probability reaches ``threshold``; otherwise the answer is
"undecided", with the number of cycles that would decide it if the session went on as it began.
Whether a state is consistent with the session at all is a separate test in two parts, each
against the same statistic of the ensemble's own held-out realisations (a gamma fitted by moments):
the session's Mahalanobis distance in all features (is the session anywhere near this state?), and
its distance along the directions from this state to the other candidates only (whitened by the
state's covariance; at most ``K - 1`` of them). The second is what catches a state that is not
among the candidates but lies between or beyond them, as wear stages do: in 72 features an offset
of a few standard deviations drowns in the chi-square spread of the other 70, along the few
directions that separate the candidates it does not. When no state passes both the answer is
"none of the candidates". A state "explains" the session when it is consistent and not ruled out
by another (posterior at least ``1 - threshold``).

The sensor path is a nuisance (``sensor_path.py``): by default the prior of an unmeasured mount
(``IdentifyOptions.sensor_path``), or a bench's calibration (``fit_states(..., sensor=)``), is
marginalised in every state's covariance, so the probabilities, the consistency test and the
estimator (``estimate.py``) all allow for it. When no state is consistent, :func:`diagnose` says
where the session departs from the top state: which blocks and crank angles, and the band gains
that would explain it, so a sensor-path mismatch can be told from a state that is not a candidate.

Validation verdict per state: the fraction of measured cycles inside the theory's cycle band
(single-cycle distance below the 95th percentile of the ensemble's own cycles), and the crank
angles where measured cycles leave the 5-95 % band of a feature more often than one in three.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, replace

import numpy as np
from scipy import linalg, optimize, special, stats
from wearbench.validation.inference.ensemble import Ensemble
from wearbench.validation.inference.sensor_path import (
    PathSpread,
    SensorPath,
    calibrate_path,
    design_matrix,
)
from wearbench.validation.inference.statistics import StateStatistics
from wearbench.validation.measurement.features import CycleFeatures, FeatureSpec

__all__ = ["FLAT", "INDISTINCT", "Identification", "IdentifyOptions", "StateModels", "fit_states", "identify_features",
           "prior_distance", "separates"]

UNDECIDED = "undecided"
NONE = "none of the candidates"
INDISTINCT = "the features cannot tell the candidates apart"
FLAT = 0.1  # total variation from the uniform prior below which a posterior has not moved


def prior_distance(posterior: np.ndarray) -> float:
    """Total variation distance (0-1) of a posterior on a grid or a set of states from the uniform prior
    over the same: how far a session's evidence moved it (0: not at all)."""
    p = np.asarray(posterior, dtype=float).ravel()
    p = p / p.sum()
    return float(0.5 * np.abs(p - 1.0 / p.size).sum())


def separates(held_out: float | None, states: int, count: int) -> bool:
    """Whether ``count`` held-out realisations of ``states`` candidates, named right in a fraction
    ``held_out`` of them, show the features telling the candidates apart: more often than chance
    (1 / ``states``) would name them, at 1 % (one-sided binomial test; None: unknown)."""
    if held_out is None or states < 2 or count < 1:
        return True
    right = round(held_out * count)
    return float(stats.binom.sf(right - 1, count, 1.0 / states)) < 0.01


@dataclass(frozen=True)
class IdentifyOptions:
    """Decision rules. Floors are standard deviations added to every feature (see statistics.py)."""

    threshold: float = 0.9          # name the top state at posterior >= threshold
    consistency: float = 0.001      # a state is consistent when its all-feature p-value >= this
    consistency_direction: float = 0.01  # ... and its p-value along the candidates' directions >= this
    floor_curve: float = 0.5        # m/s^2, low-passed curve bins
    floor_energy: float = 0.05      # log10 units, impact-band energy bins
    max_cycles: int = 500           # horizon of "cycles needed"
    pooled: bool = True             # one within- and between-covariance for all candidates (see statistics.py)
    sensor_path: str = "prior"      # "prior": marginalise an unmeasured mount's path; "none": take it as exact

    def __post_init__(self) -> None:
        if not 0.5 <= self.threshold < 1:
            raise ValueError(f"threshold = {self.threshold}: expected a probability in [0.5, 1)")
        for name in ("consistency", "consistency_direction"):
            if not 0 < getattr(self, name) < 0.5:
                raise ValueError(f"{name} = {getattr(self, name)}: expected a p-value in (0, 0.5)")
        if self.sensor_path not in ("prior", "none"):
            raise ValueError(f"sensor_path = {self.sensor_path!r}: expected 'prior' or 'none'")


@dataclass(frozen=True)
class StateModels:
    """Fitted statistics of every candidate state, their calibration, and their own distances."""

    states: tuple[str, ...]
    stats: Mapping[str, StateStatistics]
    temperature: float
    null: Mapping[str, tuple[float, float]]  # state -> (gamma shape, scale) of held-out distances
    null_direction: Mapping[str, tuple[float, float]]  # the same along the directions to the other states
    cycle_limit: Mapping[str, float]  # state -> 95th percentile of single-cycle distances
    lo: Mapping[str, np.ndarray]  # state -> per-feature 5th percentile over cycles
    hi: Mapping[str, np.ndarray]
    options: IdentifyOptions
    columns: slice = field(default_factory=lambda: slice(None))  # the features used
    # state -> (windows, 3): (all-feature, along-the-candidates) squared distances and the likelihood
    # ratio toward the best other candidate (``candidate_ratio``) of the held-out realisations'
    # windows of ``window_cycles`` consecutive cycles (validation.windows' null; 2 columns from
    # ``calibrated.py``, which holds no ratio)
    window_null: Mapping[str, np.ndarray] = field(default_factory=dict)
    window_cycles: int = 5
    spec: FeatureSpec = field(default_factory=FeatureSpec)
    sensor: SensorPath | None = None  # the sensor path marginalised (None: taken as exact)
    reference: str = ""  # a calibration the states are relative to (``calibrated.py``), "" for none
    held_out: float | None = None  # fraction of held-out realisations whose top state is their own
    held_out_count: int = 0  # how many realisations were held out


@dataclass
class Identification:
    """The answer for one session (see the module docstring)."""

    session: str
    cycles: int
    posterior: dict[str, float]
    verdict: str
    p_top: float
    consistent: dict[str, bool]  # the state's distance test passes (absolute)
    explains: dict[str, bool]  # consistent and not ruled out by another state (posterior >= 1 - threshold)
    p_value: dict[str, float]  # all features
    p_direction: dict[str, float]  # along the directions to the other candidates
    cycles_needed: int | None  # cycles in all that would decide it (None: not within max_cycles)
    inside: dict[str, float]  # fraction of cycles inside each state's cycle band
    leaves: dict[str, list[str]]  # crank-angle ranges where cycles leave each state's band
    clipped: int = 0
    notes: list[str] = field(default_factory=list)
    sensor_path: str = ""  # the sensor path the likelihood allowed for (prior or which calibration)
    diagnosis: dict | None = None  # where the session departs from the top state (when none explains it)
    # how far the session moved the posterior from the uniform prior (total variation, 0-1) and whether
    # that is too little to say anything (``FLAT``); the theory's own held-out top-1 rate
    evidence: float = 1.0
    flat: bool = False
    held_out: float | None = None

    def to_dict(self) -> dict:
        return asdict(self)

    def row(self) -> dict:
        """One table row: the session, its cycles, each state's posterior probability, the verdict."""
        return {"session": self.session, "cycles": self.cycles, **{f"p[{s}]": p for s, p in self.posterior.items()},
                "verdict": self.verdict}


def variance_floor(spec: FeatureSpec, options: IdentifyOptions) -> np.ndarray:
    return np.concatenate([np.full(spec.bins, options.floor_curve ** 2),
                           np.full(spec.size - spec.bins, options.floor_energy ** 2)])


def _posterior(ll: np.ndarray, temperature: float) -> np.ndarray:
    z = ll / temperature
    return np.exp(z - special.logsumexp(z))


def gamma_by_moments(values: list[float]) -> tuple[float, float]:
    """Gamma (shape, scale) with the mean and variance of ``values``."""
    v = np.asarray(values)
    mean, var = float(v.mean()), float(v.var(ddof=1))
    return mean * mean / var, var / mean


def whitened_offsets(st: StateStatistics, others: list[np.ndarray], xbar: np.ndarray,
                     n: float) -> tuple[np.ndarray, np.ndarray]:
    """(u, z): the offsets of the means ``others`` (columns of ``u``) and of ``xbar`` from state
    ``st``'s mean, whitened by its covariance of an ``n``-cycle mean."""
    chol = st.whitener(n)
    u = np.stack([linalg.solve_triangular(chol, m - st.mean, lower=True) for m in others], axis=1)
    z = linalg.solve_triangular(chol, np.asarray(xbar, dtype=float) - st.mean, lower=True)
    return u, z


def direction_distance2(st: StateStatistics, others: list[np.ndarray], xbar: np.ndarray, n: float) -> float:
    """Squared Mahalanobis distance of a session's mean over ``n`` cycles from state ``st`` along the
    directions to the means ``others`` only (0 when there are none)."""
    if not others:
        return 0.0
    u, z = whitened_offsets(st, others, xbar, n)
    q, _ = np.linalg.qr(u)
    return float(np.sum((q.T @ z) ** 2))


def candidate_ratio(st: StateStatistics, others: list[np.ndarray], xbar: np.ndarray, n: float) -> float:
    """The generalised likelihood ratio of "the best other candidate" against state ``st`` for a
    session's mean over ``n`` cycles: max over the means ``others`` of log N(xbar; other, C) - log
    N(xbar; st.mean, C), with C ``st``'s covariance of an ``n``-cycle mean (0 when there are none).
    Whitened by C it is max_j (z . u_j - |u_j|^2 / 2): one-sided, toward the candidates only."""
    if not others:
        return 0.0
    u, z = whitened_offsets(st, others, xbar, n)
    return float(np.max(z @ u - 0.5 * np.sum(u * u, axis=0)))


def with_sensor(st: StateStatistics, spec: FeatureSpec, sensor: SensorPath | None,
                columns: slice = slice(None)) -> StateStatistics:
    """``st`` (fitted on ``columns`` of ``spec``'s features) with the ``sensor`` path marginalised."""
    if sensor is None:
        return st
    full = np.zeros(spec.size)
    full[columns] = st.mean
    return st.with_nuisance(*sensor.nuisance(spec, full, columns))


def state_statistics(fits: dict[str, StateStatistics], pooled: bool, spec: FeatureSpec, sensor: SensorPath | None,
            columns: slice) -> dict[str, StateStatistics]:
    models = dict(zip(fits, StateStatistics.pooled(list(fits.values())), strict=True)) if pooled else fits
    return {s: with_sensor(m, spec, sensor, columns) for s, m in models.items()}


def default_sensor(spec: FeatureSpec, options: IdentifyOptions) -> SensorPath | None:
    """The sensor path marginalised when no calibration is given (``options.sensor_path``)."""
    return SensorPath.prior(spec) if options.sensor_path == "prior" else None


def temper(lls: np.ndarray, truth: np.ndarray) -> float:
    """The temperature minimising the log loss of held-out sessions: ``lls`` (sessions, states) their
    log likelihoods, ``truth`` (sessions,) the index of each one's state."""

    def log_loss(log_t: float) -> float:
        z = lls / np.exp(log_t)
        return float(-np.mean(z[np.arange(len(truth)), truth] - special.logsumexp(z, axis=1)))

    return float(np.exp(optimize.minimize_scalar(log_loss, bounds=(0.0, np.log(1e4)), method="bounded").x))


def fit_states(ensembles: Mapping[str, Ensemble], options: IdentifyOptions = IdentifyOptions(), *,
               columns: slice = slice(None), window_cycles: int = 5,
               sensor: SensorPath | None = None) -> StateModels:
    """Fit each state's statistics and calibrate the temperature and the consistency test.

    columns: which features to use (all by default; a block for comparing statistics).
    window_cycles: length of the windows whose held-out distances are kept (``window_null``).
    sensor: the bench's calibrated sensor path (default: ``options.sensor_path``'s)."""
    if len(ensembles) < 1:
        raise ValueError("identify: no candidate ensembles")
    names = tuple(ensembles)
    spec = next(iter(ensembles.values())).settings.features
    sensor = sensor or default_sensor(spec, options)
    floor = variance_floor(spec, options)[columns]
    features = {s: e.features[:, :, columns] for s, e in ensembles.items()}
    own = {s: StateStatistics.fit(f, floor) for s, f in features.items()}
    fitted = state_statistics(own, options.pooled, spec, sensor, columns)
    # held-out realisations: their distance to their own state (refit without them, and so the
    # pooled covariances), and their log likelihood under every state, for the null distributions
    # and the temperature
    lls, truth, null, null_direction, window_null = [], [], {}, {}, {}
    for si, (s, f) in enumerate(features.items()):
        d2, t2, wn = [], [], []
        others = [fitted[t].mean for t in names if t != s]
        for r in range(f.shape[0]):
            models = state_statistics({**own, s: StateStatistics.fit(np.delete(f, r, axis=0), floor)}, options.pooled,
                             spec, sensor, columns)
            xbar, n = f[r].mean(axis=0), f.shape[1]
            d2.append(models[s].distance2(xbar, n))
            t2.append(direction_distance2(models[s], others, xbar, n))
            lls.append([models[t].log_likelihood(xbar, n) for t in names])
            truth.append(si)
            for k in range(max(0, n - window_cycles + 1)):
                wbar = f[r, k:k + window_cycles].mean(axis=0)
                wn.append((models[s].distance2(wbar, window_cycles),
                           direction_distance2(models[s], others, wbar, window_cycles),
                           candidate_ratio(models[s], others, wbar, window_cycles)))
        window_null[s] = np.asarray(wn).reshape(-1, 3)
        null[s] = gamma_by_moments(d2)
        null_direction[s] = gamma_by_moments(t2) if others else (1.0, 1.0)  # one candidate: distance 0, p 1
    temperature = temper(np.asarray(lls), np.asarray(truth)) if len(names) > 1 else 1.0
    held_out = float(np.mean(np.argmax(np.asarray(lls), axis=1) == np.asarray(truth)))
    limit, lo, hi = {}, {}, {}
    for s, f in features.items():
        flat = f.reshape(-1, f.shape[-1])
        cov1 = fitted[s].covariance(1)
        inv = np.linalg.inv(cov1)
        d = flat - fitted[s].mean
        limit[s] = float(np.percentile(np.einsum("ij,jk,ik->i", d, inv, d), 95))
        lo[s], hi[s] = np.percentile(flat, 5, axis=0), np.percentile(flat, 95, axis=0)
    return StateModels(names, fitted, temperature, null, null_direction, limit, lo, hi, options, columns,
                       window_null=window_null, window_cycles=window_cycles, spec=spec, sensor=sensor,
                       held_out=held_out, held_out_count=len(truth))


def angle_ranges(flags: np.ndarray, bins: int) -> list[str]:
    """Crank-angle ranges (deg) of the runs of True in a per-bin flag array."""
    width = 360.0 / bins
    out, i = [], 0
    while i < bins:
        if flags[i]:
            j = i
            while j + 1 < bins and flags[j + 1]:
                j += 1
            out.append(f"{i * width:.0f}-{(j + 1) * width:.0f} deg")
            i = j + 1
        else:
            i += 1
    return out


def feature_ranges(flags: np.ndarray, spec: FeatureSpec) -> list[str]:
    """Crank-angle ranges of the flagged features (``spec.size`` flags), e.g. "impacts 50-150 Hz 40-60 deg"."""
    blocks = np.asarray(flags, dtype=bool).reshape(-1, spec.bins)
    return [f"curve {r}" for r in angle_ranges(blocks[0], spec.bins)] + [
        f"impacts {lo:g}-{hi:g} Hz {r}" for (lo, hi), flags in zip(spec.bands, blocks[1:], strict=True)
        for r in angle_ranges(flags, spec.bins)]


def identify_features(features: CycleFeatures, models: StateModels, *, label: str = "session") -> Identification:
    """Posterior, verdict, consistency and bands for a session's cycle ``features``."""
    opts = models.options
    x = features.values[:, models.columns]
    n = features.cycles
    if n < 1:
        raise ValueError(f"identify {label}: the session holds no complete crank cycle")
    xbar = x.mean(axis=0)
    names = models.states
    ll = np.array([models.stats[s].log_likelihood(xbar, n) for s in names])
    post = _posterior(ll, models.temperature)
    top = int(np.argmax(post))
    p_value, p_direction, consistent = {}, {}, {}
    for s in names:
        st = models.stats[s]
        shape, scale = models.null[s]
        p_value[s] = float(stats.gamma.sf(st.distance2(xbar, n), shape, scale=scale))
        others = [models.stats[t].mean for t in names if t != s]
        shape, scale = models.null_direction[s]
        p_direction[s] = float(stats.gamma.sf(direction_distance2(st, others, xbar, n), shape, scale=scale))
        consistent[s] = p_value[s] >= opts.consistency and p_direction[s] >= opts.consistency_direction
    evidence = prior_distance(post) if len(names) > 1 else 1.0
    blind = not separates(models.held_out, len(names), models.held_out_count)
    if not any(consistent.values()):
        verdict = NONE
    elif blind:
        verdict = INDISTINCT
    elif post[top] >= opts.threshold and consistent[names[top]]:
        verdict = names[top]
    else:
        verdict = UNDECIDED
    needed = None
    if verdict == UNDECIDED and any(consistent.values()) and evidence >= FLAT:
        for m in np.unique(np.geomspace(n + 1, opts.max_cycles, 60).astype(int)):
            p = _posterior(np.array([models.stats[s].log_likelihood(xbar, m) for s in names]), models.temperature)
            if p.max() >= opts.threshold:
                needed = int(m)
                break
    elif verdict not in (NONE, INDISTINCT, UNDECIDED):
        needed = n
    spec = features.spec
    inside, leaves = {}, {}
    for s in names:
        st = models.stats[s]
        d = x - st.mean
        d2 = np.einsum("ij,jk,ik->i", d, np.linalg.inv(st.covariance(1)), d)
        inside[s] = float(np.mean(d2 <= models.cycle_limit[s]))
        out = (x < models.lo[s]) | (x > models.hi[s])
        often = np.zeros(spec.size, dtype=bool)
        often[models.columns] = out.mean(axis=0) > 1 / 3
        leaves[s] = feature_ranges(often, spec)
    notes = []
    if blind:
        notes.append(f"the candidates' own realisations, held out, are named right in {100 * models.held_out:.0f} % "
                     f"of {models.held_out_count}, no more often than chance ({100 / len(names):.0f} %) would: these "
                     "features cannot tell the candidates apart at this crank speed and sensor chain; no session can "
                     "decide between them")
    elif len(names) > 1 and evidence < FLAT:
        notes.append(f"the session's evidence hardly moves the posterior from the uniform prior (total variation "
                     f"{evidence:.2f}): it lies between the candidates or the features do not see what tells them apart")
    clipped = int(features.clipped.sum())
    if clipped:
        notes.append(f"{clipped} samples at the sensor's range (clipped): impact energies are underestimated")
    explains = {s: consistent[s] and float(p) >= 1 - opts.threshold for s, p in zip(names, post, strict=True)}
    diagnosis = None
    if verdict == NONE:
        diagnosis = diagnose(xbar, n, models, names[top])
        notes.append(diagnosis["summary"])
    return Identification(label, n, {s: float(p) for s, p in zip(names, post, strict=True)}, verdict,
                          float(post[top]), consistent, explains, p_value, p_direction, needed, inside, leaves,
                          clipped, notes, models.reference or (models.sensor.source if models.sensor else "none"), diagnosis,
                          evidence, len(names) > 1 and evidence < FLAT, models.held_out)


def diagnose(xbar: np.ndarray, n: int, models: StateModels, state: str) -> dict:
    """Where a session's mean ``xbar`` over ``n`` cycles departs from ``state``: the rms standardised
    departure of each block (curve, each band), the crank angles where a feature is more than 3
    standard deviations off, and the sensor path (low-frequency gain, band gains in dB) fitted to the
    departure with a broad prior, with the consistency p-value left once it is removed."""
    spec, cols = models.spec, models.columns
    st = models.stats[state]
    shift = np.zeros_like(st.mean)
    if models.sensor is not None:
        full = np.zeros(spec.size)
        full[cols] = st.mean
        shift = models.sensor.nuisance(spec, full, cols)[0]
    base = st.mean - shift  # the state's own mean, the sensor path's prior mean removed
    cov0 = st.covariance(n, nuisance=False)
    z_full = np.full(spec.size, np.nan)
    z_full[cols] = (xbar - base) / np.sqrt(np.diag(cov0))
    blocks = z_full.reshape(-1, spec.bins)
    names = ["curve"] + [f"impacts {lo:g}-{hi:g} Hz" for lo, hi in spec.bands]
    rms = {nm: float(np.sqrt(np.nanmean(b ** 2))) for nm, b in zip(names, blocks, strict=True)
           if np.isfinite(b).any()}
    angles = [f"{nm} {r}" for nm, b in zip(names, blocks, strict=True) for r in angle_ranges(np.abs(b) > 3, spec.bins)]
    broad = SensorPath.prior(spec, replace(PathSpread.around(spec, 0.1, 10.0), damping=(0.01, 0.3), sensitivity=0.3))
    full_x, full_m = np.zeros(spec.size), np.zeros(spec.size)
    full_x[cols], full_m[cols] = xbar, base
    full_c = np.eye(spec.size) * 1e6  # features not used carry no information
    full_c[cols, cols] = cov0
    fit = calibrate_path(full_x, full_m, full_c, spec, broad, source="diagnosis")
    resid = xbar - base - design_matrix(spec, full_m, cols) @ fit.theta_mean
    d2 = float(resid @ np.linalg.solve(cov0, resid))
    p_fit = float(stats.gamma.sf(d2, models.null[state][0], scale=models.null[state][1]))
    gains = fit.gains_db()
    bands = ", ".join(f"{lo:g}-{hi:g} Hz {gains[f'band {k + 1}']:+.1f} dB" for k, (lo, hi) in enumerate(spec.bands))
    worst = max(rms, key=rms.get)
    explained = p_fit >= models.options.consistency
    summary = (f"departs from {state!r} most in {worst} (rms {rms[worst]:.1f} sd)"
               + (f" at {', '.join(angles[:4])}" if angles else "")
               + f"; a sensor path with gain {gains['gain']:.3f} and band gains {bands} "
               + (f"would explain it (p {p_fit:.2g}): suspect the sensor path, calibrate the bench "
                  "('wearbench calibrate')" if explained else
                  f"would not explain it (p {p_fit:.2g}): the session differs in crank-angle shape, not only in "
                  "level: a state that is not among the candidates, or a sensor resonance inside a band"))
    return {"state": state, "blocks": rms, "angles": angles, "gain": gains["gain"],
            "band_gain_db": {f"{lo:g}-{hi:g} Hz": gains[f"band {k + 1}"] for k, (lo, hi) in enumerate(spec.bands)},
            "p_with_gains": p_fit, "sensor_path_explains": explained, "summary": summary}

