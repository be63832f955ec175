"""A bench's wear over its life: sessions at several cycles run give the wear coefficient and the
cycles until a clearance limit, with credible intervals.

The estimator's wear parameter is cycles run along the bench file's Archard trajectory. Archard
wear is linear in the coefficient: a bench whose true coefficient is ``k`` times the file's is, after
``N`` cycles, where the file's bench is after ``k N`` (the contact forces change slowly with the
shallow wear of a few micrometres, so the trajectory is the same, run faster). So sessions of one
bench recorded after ``N_i`` cycles give the joint posterior of the initial clearance ``c`` (shared:
one bench) and ``k``:

    p(c, k | sessions) ∝ prior(c) prior(k) L(c, k)

``prior(k)`` log-uniform in [0.2, 5]. The sessions are NOT independent given (c, k): they share the
bench (its offset from the file, drawn once from the tolerances) and its sensor path. So
``L`` is the Gaussian of the stacked session means ``x_i = mu(c, k N_i) + s + w_i``, with the shared
``s ~ N(0, B)`` (the bench's offset from the file and its sensor path) and each session's own
``w_i ~ N(0, W_i)``: its cycle-to-cycle part ``Sw / n_i`` and the estimator's error at its parameter
value (design mean, emulator, floor), taken as independent between sessions because the emulator's
error changes along the trajectory (taken as shared, it let the differences between sessions pin the
clearance to +/-15 um and missed the truth in half of 20 simulated lives); by Woodbury,

    Q = sum_i r_i' W_i^-1 r_i - u' (B^-1 + sum_i W_i^-1)^-1 u,   u = sum_i W_i^-1 r_i,

tempered as a single session is (``estimate.py``). Multiplying the sessions' own likelihoods instead
counted the shared bench offset once per session: the clearance came out sqrt(sessions) too sure.

The bench's offset is not quite constant over its life: its surfaces wear in its own way, and the
features through its mount respond in their own way. The design measures this, since each of its
seeds is the same bench and mount at every design point: a realisation's offset at the worn points
differs from its offset new by ``d ~ N(0, D)`` (``wear_drift``; on the shipped design, weighted by
the features' variance, the offsets new and worn correlate 0.95-0.97, ``D`` largest in the
400-1000 Hz band), reached by the first design stage (200k cycles) and not growing after it (the
worn points' offsets correlate 0.99-1.0). So the shared part is ``s + g_i d``, ``g_i`` 0 for a session
of the new bench and 1 for a worn one. The design has no point between new and its first stage, so
the drift's course there is not measured; taken as linear in ``k N_i`` up to the first stage, the
determinant (which then changes with ``k``) pulled the factor towards its lower edge (its 90 %
interval held 1.3 in 0.70 of 20 simulated lives, against 0.90 with the step). Without the drift,
those lives read the session differences as the clearance's: its 90 % interval held the truth in
0.70 of them (median error +0.022 mm), 0.85 with the drift (``benchmarks/validation/estimate.py``).
With two or three sessions (0 and 200k; 0, 100k and 200k) the factor rests on the change from new to
worn alone, and there the estimator's error *of that change* decides it. Measured on 20 simulated
lives (``benchmarks/validation/estimate.py --life-sessions 0,200k``): their worn sessions sit less worn, relative
to their new one, than the estimator's mean says, by a nearly constant 10-16 % of the change from
new to 600k cycles at 130k-520k effective cycles (se 5 %): the drift's step shape, with a mean that
is not zero. Along the direction that tells the factor this is -0.6 sd (se 0.2) at 130k-260k; the
factor's median came out 0.62 for a truth of 1.3 and its 90 % interval held 1.3 in 0.60 of the lives.
Not the clearance bias (with the clearance fixed at the truth: 0.70), not the drift's size (D x 2 or
x 4: 0.75, 0.80, medians still 0.60), not the grid's edge (3x there; intervals ended at 1.5x), not
the drift's shape (linear up to 200k: 0.20), not an emulator error along the trajectory per session
(its maximum-likelihood size on the lives: 20k-50k cycles). Lives drawn from this likelihood itself at
the same truths gave 0.80 (median 1.13). The design's mean move is the mean of its M benches' moves,
so it carries an error common to every bench the estimator judges (covariance about ``D / M``); with
five sessions the slope across them tells the factor despite it, with two or three it does not.
:func:`~wearbench.validation.estimation.move.life_move` measures that error on lives of known truth, and
``track_features(move=...)`` carries its mean and its standard error (see ``benchmarks/validation/estimate.py``:
lives scored with a move measured on other lives). The move is stored beside the estimator it was
measured against (``track_move.py``) and ``track`` uses it by default.
A bench's features need not change along its life at the estimator's rate either. On 40 simulated
lives (20 cached, seeds 28000-28019, and 20 fresh, 38000-38019; wear 1.3x the file's, sessions at 0-400k
cycles, 20 cycles each) the slope of the worn sessions' change along the estimator's change from new
was 0.91x the estimator's on average in both sets (sd 0.34 across lives; 0.69 +/- 0.14 at 0.50-0.56 mm,
0.93-1.18 below 0.45 mm), while the sessions' scatter about each life's own line was 0.76 of what the
likelihood's session noise says: the rates vary between lives beyond the session noise. The lives
whose five-session interval missed 1.3 were those (6 of the 20 fresh ones, five of them low at
0.45-0.55 mm; leaving out any one session brought none back, and their wear depth follows the
estimator's trajectory within 1-10 %). So the features see the factor ``k eta``, ``eta`` lognormal
with sd ``rate_spread`` (0.2: the best log posterior density at the truth on the 20 cached lives, of
0, 0.1, 0.2, 0.3), marginalised by a Gaussian kernel along the log-factor grid; the depth keeps ``k``.
The rate depends on the clearance: on the move's 40 lives (default path and drawn mounts) and on 40
held-out ones the lives' rates scatter little below 0.40 mm and fall and scatter more towards
0.55 mm. :func:`life_rate` measures it on the move's lives (its log-mean and sd linear in the
clearance, ``track_move.Rate``), stored with the move; ``track`` then uses it in place of the
constant (the kernel per clearance row). Chosen on the move's lives only, it raised the five-session
coverage on held-out lives (``benchmarks/validation/estimate.py``; the README's numbers).
``mu`` at ``k N_i`` is the estimator's emulated mean; a ``k N_i`` beyond the design's last cycles
run is outside what the estimator knows (zero likelihood there; the rate's kernel is renormalised
over the factors inside).

The wear depth (largest clearance growth of any joint) along the trajectory, extrapolated linearly
beyond the estimator's last design point at its last stage's rate, gives for each (c, k) the cycles
until ``c + depth`` reaches a clearance ``limit``. A bench's own trajectory differs from the
estimator's by a factor ``delta`` on the depth (its staging, and its geometry within tolerances):
lognormal with ``depth_spread`` (default 5 %: simulated lives' depth after 100k-500k cycles differed
from the estimator's trajectory at the same effective cycles by 1-5 % sd, ``benchmarks/validation/estimate.py``),
integrated by Gauss-Hermite quadrature. The cycles-to-limit interval is that of the joint posterior
of (c, k, delta): the clearance's and coefficient's uncertainty and their correlation included. An
interval from new says little when the limit may lie behind the bench already, so the limit is also
seen from the last session (:class:`LimitAhead`, :func:`limit_ahead`): the probability that it was
reached by then; otherwise the cycles that remain (an interval over the rest of the posterior,
one-sided from 0 where it piles there); and the probability that it lies beyond the design's range
of wear (``k`` times the cycles from new past the design's last cycles run: the depth there is
extrapolated, not simulated), said first when it is most of what remains.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace

import numpy as np
import pandas as pd
from scipy import linalg, special, stats
from wearbench.validation.estimation.estimate import EstimatorModel, Interval
from wearbench.validation.estimation.move import Move, Rate
from wearbench.validation.inference.statistics import nearest_psd, shrunk_covariance
from wearbench.validation.measurement.features import CycleFeatures

__all__ = ["CONSISTENCY", "NO_LIFE", "LimitAhead", "Track", "depth_curve", "joint_log_likelihood", "life_consistency",
           "life_rate", "limit_ahead", "session_covariances", "track_features", "wear_drift"]

K_RANGE = (0.2, 5.0)
RATE_SPREAD = 0.2  # lognormal sd of the features' rate along a life (module docstring)
EXTEND = 100.0  # the depth is extrapolated to this many times the design's last cycles run (depth_curve)


@dataclass
class LimitAhead:
    """A clearance limit seen from the last session: the probability that the bench had reached it by
    then; otherwise the cycles that remain after the last session (an interval over the part of the
    posterior that has not reached it), the probability that the limit lies beyond the design's range
    of wear (reached only where the depth is extrapolated from the design's last stage, or never) and
    the probability that it is not reached even within the extrapolation (``EXTEND`` x the design's
    range). Probabilities are of the whole posterior."""

    p_reached: float
    p_beyond_design: float  # not reached by the last session, and reached only past the design's range (or never)
    p_never: float  # not reached within the extrapolation
    remaining: Interval | None  # cycles after the last session, given not reached (None: never, for most of it)
    last: float  # cycles run at the last session

    @property
    def verdict(self) -> str:
        """In words: reached (with its probability), the cycles that remain otherwise, beyond the design."""
        if self.p_reached >= 0.95:
            return f"already reached by the last session (P {self.p_reached:.2f})"
        head = (f"reached by the last session with P {self.p_reached:.2f}; otherwise " if self.p_reached >= 0.05
                else f"not reached by the last session (P reached {self.p_reached:.2f}): ")
        if self.remaining is None:
            return head + (f"not within {EXTEND:g} x the design's range of wear (P {self.p_never:.2f}), the wear past "
                           "it extrapolated from the design's last stage")
        r = self.remaining
        text = f"a further {r.median:,.0f} cycles (90 % {r.text(lambda v: f'{v:,.0f}')})"
        if self.p_beyond_design >= 0.5 * (1.0 - self.p_reached):
            return (head + f"beyond the design's range of wear (P {self.p_beyond_design:.2f}): {text}, the wear past it "
                    "extrapolated from the design's last stage")
        if self.p_beyond_design >= 0.05:
            text += f"; beyond the design's range of wear with P {self.p_beyond_design:.2f}"
        return head + text


def limit_ahead(cycles: np.ndarray, covered: np.ndarray, weights: np.ndarray, last: float) -> LimitAhead:
    """Where a clearance limit lies from the last session: ``cycles`` (from new) at which each point of
    the posterior (``weights``) reaches it (inf: not within the extrapolation), ``covered`` whether that
    lies within the design's range of wear, ``last`` the last session's cycles run; the three
    broadcast alike."""
    cycles, covered, weights = np.broadcast_arrays(np.asarray(cycles, float), np.asarray(covered, bool),
                                                   np.asarray(weights, float))
    total = float(weights.sum())
    if not total > 0:
        raise ValueError("limit_ahead: the posterior's weights sum to no mass")
    reached = cycles <= last
    ahead = ~reached & np.isfinite(cycles)
    p_reached = float(weights[reached].sum()) / total
    p_never = float(weights[~np.isfinite(cycles)].sum()) / total
    remaining = None
    if weights[ahead].sum() > 0 and p_never < 0.5 * (1.0 - p_reached):
        remaining = Interval.from_weights(cycles[ahead] - last, weights[ahead], edges=True)
        if remaining.kind == "upper bound":  # the range's end is the last session itself, not the grid's nearest
            remaining = replace(remaining, lo50=0.0, lo90=0.0)
    return LimitAhead(p_reached, float(weights[~reached & ~covered].sum()) / total, p_never, remaining, float(last))


@dataclass
class Track:
    """Wear over a bench's life (see the module docstring)."""

    sessions: list[str]
    cycles_run: list[float]
    clearance: Interval  # initial clearance, m
    factor: Interval  # wear coefficient / the bench file's
    coefficient: Interval  # wear coefficient, 1/Pa
    depth: list[Interval]  # wear depth at each session's cycles run (m), from the joint posterior
    limit: float | None  # clearance limit, m
    cycles_to_limit: Interval | None  # cycles from new until the limit
    beyond: float  # posterior mass whose limit lies beyond 100 x the estimator's range
    prediction: list[tuple[float, Interval]] = field(default_factory=list)  # (cycles, wear depth m)
    notes: list[str] = field(default_factory=list)
    move: dict | None = None  # the measured move from new to worn used (Move.to_dict), None: none used
    rate_spread: float | None = 0.0  # lognormal sd of the features' rate along the life marginalised (0: none;
    # None: the move's rate against clearance, ``move['rate']``)
    p_value: float = 1.0  # consistency of the sessions, jointly, with one bench at the best (c, k)
    session_p: list[float] = field(default_factory=list)  # each session's own consistency (any c, N)
    ahead: LimitAhead | None = None  # the limit seen from the last session (with ``limit``)
    design_cycles: float | None = None  # the estimator's last cycles run: effective cycles past it are extrapolated

    @property
    def explains(self) -> bool:
        """Whether some (c, k) explains the sessions as one bench's life (and each session alone)."""
        return self.p_value >= CONSISTENCY and all(p >= CONSISTENCY for p in self.session_p)

    @property
    def verdict(self) -> str:
        if self.explains:
            return (f"initial clearance {self.clearance.median * 1e3:.3f} mm, wear coefficient "
                    f"{self.factor.median:.2f} x the bench file's")
        alone = [s for s, p in zip(self.sessions, self.session_p, strict=True) if p < CONSISTENCY]
        if alone:
            return f"{NO_LIFE}: no parameter value explains {', '.join(alone)} even alone"
        return f"{NO_LIFE} as one bench's life (p {self.p_value:.2g})"

    def to_dict(self) -> dict:
        return {**asdict(self), "explains": self.explains, "verdict": self.verdict,
                "limit_verdict": self.ahead.verdict if self.ahead is not None else None}

    def to_dataframe(self) -> pd.DataFrame:
        """One row per session: its cycles run and its wear depth (m), median and 90 % interval."""
        return pd.DataFrame({"session": self.sessions, "cycles_run": self.cycles_run,
                             "wear_depth_m": [d.median for d in self.depth],
                             "wear_depth_m_lo90": [d.lo90 for d in self.depth],
                             "wear_depth_m_hi90": [d.hi90 for d in self.depth]}).set_index("session")


NO_LIFE = "no (c, k) explains these sessions"
CONSISTENCY = 0.001  # p below which a life, or a session in it, is not explained (as estimate's default)


def life_consistency(model: EstimatorModel, xbars: np.ndarray, cycles: Sequence[int], means: np.ndarray,
                     worn: np.ndarray | None, drift: np.ndarray | None) -> tuple[float, list[float]]:
    """The sessions' joint consistency with one bench at the best parameter value, and each session's
    own. Jointly: the stacked sessions' squared distance ``Q`` (the life's likelihood's quadratic form)
    at ``means`` (S, p: the posterior's mode), against the sum of the sessions' nulls (each a single
    session's smallest distance over the design, ``model.null``: a gamma, so their sum is one of
    S times the shape); alone: each session's smallest distance over the grid against ``model.null``.
    A session that no (c, N) explains, and sessions that cannot be one bench (two clearances, one
    recording twice with another, a session at another speed) get small p."""
    shape, scale = model.null
    q = float(joint_log_likelihood(model, xbars, cycles, means, worn, drift, quadratic=True))
    alone = [float(stats.gamma.sf(float(model.distances(x, n).min()), shape, scale=scale))
             for x, n in zip(xbars, cycles, strict=True)]
    return float(stats.gamma.sf(q, len(cycles) * shape, scale=scale)), alone


def depth_curve(model: EstimatorModel, extend: float = EXTEND) -> tuple[np.ndarray, np.ndarray]:
    """Cycles (effective) and wear depth (gc, points) along each grid clearance's trajectory,
    extrapolated linearly to ``extend`` x the last design cycles at the last stage's rate."""
    gn, depth = model.grid_n, np.maximum.accumulate(model.grid_depth, axis=1)
    step = max(1, (gn.size - 1) // (len(model.estimator.design.cycles) - 1))  # grid points per design stage
    rate = (depth[:, -1] - depth[:, -1 - step]) / (gn[-1] - gn[-1 - step])
    far = np.geomspace(gn[-1] * 1.05, gn[-1] * extend, 60)
    return np.concatenate([gn, far]), np.concatenate([depth, depth[:, -1:] + rate[:, None] * (far - gn[-1])], axis=1)


def wear_drift(model: EstimatorModel) -> np.ndarray:
    """Covariance (p, p) of the change of a bench's offset from the design mean between new and worn:
    from the design's own realisations, each seed the same bench and mount at every design point. Per
    design clearance and realisation, its offset from the point's mean averaged over the worn points
    less its offset at 0 cycles; pooled over the clearances (each centred), shrunk as the ensembles'
    covariances are, less the cycle-to-cycle noise of those means, clipped to positive semi-definite."""
    f = model.estimator.features  # (clearances, cycles run, M, C, p)
    nc, nn, _, c, p = f.shape
    xb = f.mean(axis=3)
    b = xb - xb.mean(axis=2, keepdims=True)
    d = (b[:, 1:].mean(axis=1) - b[:, 0]).reshape(-1, p)
    cov = shrunk_covariance(d) * (d.shape[0] - 1) / (d.shape[0] - nc)  # each clearance's mean taken out
    return nearest_psd(cov - model.stats[model.reference].within / c * (1 + 1 / (nn - 1)))


def session_covariances(model: EstimatorModel) -> tuple[np.ndarray, np.ndarray]:
    """(shared, own): the covariance of what one bench's sessions share (its offset from the design
    mean, with the sensor path's band gains) and of what each session has alone besides its
    cycle-to-cycle noise (the estimator's error at its parameter values)."""
    st = model.stats[model.reference]
    shared = st.between + (st.nuisance @ st.nuisance.T if st.nuisance is not None else 0.0)
    return shared, st.covariance(np.inf, nuisance=False) - st.between + np.diag(model.discrepancy)


def _sqrt_psd(a: np.ndarray) -> np.ndarray:
    vals, vecs = np.linalg.eigh(0.5 * (a + a.T))
    return vecs * np.sqrt(np.clip(vals, 0.0, None))


def joint_log_likelihood(model: EstimatorModel, xbars: np.ndarray, cycles: Sequence[float],
                         means: np.ndarray, worn: np.ndarray | None = None,
                         drift: np.ndarray | None = None, *, quadratic: bool = False) -> np.ndarray:
    """Untempered log likelihood of one bench's session means ``xbars`` (S, p) over ``cycles`` (S,)
    cycles each, at parameter values whose emulated means are ``means`` (..., S, p): the sessions
    share the bench and its sensor path (see the module docstring). ``worn`` (..., S) in [0, 1]: how
    far each session's bench offset has moved along its new-to-worn change (covariance ``drift``,
    :func:`wear_drift`); then the log density with its determinant (it changes with ``worn``), up to
    ``-S p log(2 pi) / 2``. Without ``worn``: the quadratic form only (the determinant is constant).
    ``quadratic``: the quadratic form ``Q`` itself (the squared Mahalanobis distance of the stacked
    sessions, what the life's consistency test reads), not the log density."""
    st = model.stats[model.reference]
    shared, estimator = session_covariances(model)
    r = np.asarray(xbars, float) - means  # (..., S, p)
    flat = r.reshape(-1, *r.shape[-2:])  # (G, S, p)
    p = flat.shape[-1]
    own = np.zeros(flat.shape[0])
    wr = np.zeros_like(flat)  # W_i^-1 r_i
    inverses, logdet = [], 0.0
    for i, n in enumerate(cycles):
        w = linalg.cho_factor(st.within / n + estimator, lower=True)
        wr[:, i] = linalg.cho_solve(w, flat[:, i].T).T
        own += np.sum(flat[:, i] * wr[:, i], axis=1)
        inverses.append(linalg.cho_solve(w, np.eye(p)))
        logdet += 2.0 * np.log(np.diag(w[0])).sum()
    u = wr.sum(axis=1)
    if worn is None:
        g = linalg.cho_factor(linalg.inv(shared + 1e-12 * np.eye(p)) + sum(inverses), lower=True)
        q = own - np.sum(u * linalg.cho_solve(g, u.T).T, axis=1)
        return (q if quadratic else -0.5 * q).reshape(r.shape[:-2])
    # shared latent (bench offset b, drift d): x_i = mean_i + b + worn_i d + w_i; with A = P^(1/2),
    # Q = sum r_i' W_i^-1 r_i - v' M^-1 v, M = I + A' L' W^-1 L A, v = A' L' W^-1 r, log|cov| = log|W| + log|M|
    a_s, a_d = _sqrt_psd(shared), _sqrt_psd(drift)
    loads = np.broadcast_to(np.asarray(worn, float), r.shape[:-1]).reshape(flat.shape[:2])
    rows, which = np.unique(loads, axis=0, return_inverse=True)
    v = np.concatenate([u @ a_s, np.einsum("gs,gsp->gp", loads, wr) @ a_d], axis=1)  # (G, 2p)
    ss = sum(a_s.T @ m @ a_s for m in inverses)
    sd, dd = np.stack([a_s.T @ m @ a_d for m in inverses]), np.stack([a_d.T @ m @ a_d for m in inverses])
    out = np.empty(flat.shape[0])
    for k, g in enumerate(rows):
        sel = np.flatnonzero(which.ravel() == k)
        cross = np.tensordot(g, sd, axes=1)
        m = np.eye(2 * p) + np.block([[ss, cross], [cross.T, np.tensordot(g * g, dd, axes=1)]])
        mc = linalg.cho_factor(m, lower=True)
        q = own[sel] - np.sum(v[sel] * linalg.cho_solve(mc, v[sel].T).T, axis=1)
        out[sel] = q if quadratic else -0.5 * (q + logdet + 2.0 * np.log(np.diag(mc[0])).sum())
    return out.reshape(r.shape[:-2])


def _spread_rate(log_lik: np.ndarray, inside: np.ndarray, step: float, spread: float | np.ndarray,
                 centre: np.ndarray | None = None) -> np.ndarray:
    """The log likelihood (c, k) marginalised over the features' rate ``eta`` (lognormal, sd ``spread``):
    ``L(c, k) = E[L(c, k eta)]``, a Gaussian kernel along the log-factor grid (spacing ``step``), over
    the factors inside the estimator's range only (renormalised there: beyond it the likelihood is not
    known, not zero); -inf outside the range as before. ``spread`` and ``centre`` (the log-mean of
    ``eta``) may be given per clearance row (c,): a clearance-dependent rate (``track_move.Rate``)."""
    if centre is not None or np.ndim(spread):
        return _spread_rate_rows(log_lik, inside, step, np.broadcast_to(spread, log_lik.shape[:1]),
                                 np.broadcast_to(0.0 if centre is None else centre, log_lik.shape[:1]))
    if spread <= 0:
        return log_lik
    from scipy import ndimage

    m = int(np.ceil(4.0 * spread / step))
    kernel = np.exp(-0.5 * (np.arange(-m, m + 1) * step / spread) ** 2)
    top = log_lik[:, inside].max()
    lik = np.where(inside, np.exp(log_lik - top), 0.0)
    num = ndimage.convolve1d(lik, kernel, axis=1, mode="constant", cval=0.0)
    den = ndimage.convolve1d(inside.astype(float), kernel, mode="constant", cval=0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(inside, np.log(num / den) + top, -np.inf)


def _spread_rate_rows(log_lik: np.ndarray, inside: np.ndarray, step: float, spread: np.ndarray,
                      centre: np.ndarray, kernel: np.ndarray | None = None) -> np.ndarray:
    """:func:`_spread_rate` with the rate's sd and log-mean per clearance row: per row the kernel matrix
    ``w[j, j'] = exp(-(log k_j' - log k_j - centre)^2 / (2 spread^2))`` over the factors inside
    (``kernel``: these matrices (c, k, k), :func:`_rate_kernel`, when already made)."""
    w = _rate_kernel(step, inside.size, spread, centre) if kernel is None else kernel
    top = log_lik[:, inside].max()
    lik = np.where(inside, np.exp(log_lik - top), 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.log(np.einsum("ijk,ik->ij", w, lik) / (w @ inside.astype(float))) + top
    return np.where(inside, out, -np.inf)


def _rate_kernel(step: float, size: int, spread: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """(c, k, k): each clearance row's Gaussian kernel in log factor (:func:`_spread_rate_rows`); the
    identity where the rate neither spreads nor moves."""
    spread, centre = np.asarray(spread, float), np.asarray(centre, float)
    if np.any((spread <= 0) & (centre != 0)):
        raise ValueError("track: a rate with a log-mean other than 0 needs a spread > 0 (the factor grid is discrete)")
    d = (np.arange(size)[None, :] - np.arange(size)[:, None]) * step  # [j, j']: log(k_j' / k_j)
    s = np.where(spread > 0, spread, 1.0)[:, None, None]
    w = np.exp(-0.5 * ((d[None] - centre[:, None, None]) / s) ** 2)
    w[spread <= 0] = np.eye(size)
    return w


def _life_log_likelihood(xbars: np.ndarray, n_cycles: Sequence[int], runs: np.ndarray, model: EstimatorModel,
                         ks: np.ndarray, drift: bool, move: Move | None) -> tuple[np.ndarray, np.ndarray]:
    """The tempered log likelihood (c, k) of one bench's session means ``xbars`` (S, p) on the grid of
    clearances and wear factors ``ks`` before the features' rate (-inf where ``k`` x the last cycles run
    leaves the estimator's range), and which factors lie inside it."""
    gc, gn = model.grid_c, model.grid_n
    eff = ks[:, None] * runs[None, :]  # (k, S) effective cycles along the file's trajectory
    inside = np.all(eff <= gn[-1] + 1e-9, axis=1)
    if not inside.any():
        raise ValueError("track: the cycles run exceed the estimator's range for every wear coefficient")
    log_lik = np.full((gc.size, ks.size), -np.inf)
    means = np.stack([model.mean(np.full(eff[inside].shape, c), eff[inside]) for c in gc])  # (c, k inside, S, p)
    moved = ()
    if drift:
        cov = wear_drift(model)
        if move is not None:
            if move.mean.shape != means.shape[-1:]:
                raise ValueError(f"track: the move has {move.mean.size} features, the estimator {means.shape[-1]}")
            means = means + (runs > 0)[:, None] * move.mean
            cov = cov + move.covariance
        moved = (np.broadcast_to((runs > 0).astype(float), means.shape[:-1]), cov)
    log_lik[:, inside] = joint_log_likelihood(model, xbars, n_cycles, means, *moved) / model.temperature
    return log_lik, inside


def track_features(features: Sequence[CycleFeatures], cycles_run: Sequence[float], model: EstimatorModel, *,
                   coefficient: float, limit: float | None = None, labels: Sequence[str] | None = None,
                   factors: int = 161, depth_spread: float = 0.05, drift: bool = True,
                   move: Move | None = None, rate_spread: float | None = None) -> Track:
    """Wear over life from sessions' cycle ``features`` recorded after ``cycles_run`` cycles.

    coefficient: the bench file's wear coefficient K_n (1/Pa); limit: a clearance limit (m);
    depth_spread: lognormal sd of a bench's wear depth about the estimator's trajectory; drift: the
    worn sessions share the bench's move from new (:func:`wear_drift`; False: the offset is constant
    over the life, as before it was measured); move: the worn sessions' move beyond the estimator's mean
    change (``track_move.life_move``, measured on lives of known truth, or ``track_move.stored_move``):
    the worn sessions' expected means move by its mean and its covariance joins the drift's;
    rate_spread: lognormal sd of the rate at which a bench's features change along the life about the
    estimator's (its ``k`` for the features is ``k eta``, ``eta`` lognormal; 0: none; see the module
    docstring); None: the move's rate against clearance when it has one (``track_move.Rate``, measured
    with it by :func:`life_rate`), else ``RATE_SPREAD`` at every clearance."""
    if len(features) != len(cycles_run) or len(features) < 2:
        raise ValueError(f"track: {len(features)} sessions and {len(cycles_run)} cycles-run values: expected one "
                         "value per session and at least two sessions")
    if any(n < 0 for n in cycles_run) or len(set(cycles_run)) < 2:
        raise ValueError(f"track: cycles run {list(cycles_run)}: expected values >= 0, at least two different")
    if any(f.cycles < 1 for f in features):
        raise ValueError("track: a session holds no complete crank cycle")
    first_stage = model.estimator.design.cycles[1]
    if max(cycles_run) * K_RANGE[1] < 0.05 * first_stage:
        raise ValueError(f"track: cycles run {min(cycles_run):,.0f}-{max(cycles_run):,.0f}: at most "
                         f"{max(cycles_run) * K_RANGE[1]:,.0f} cycles of the bench file's wear even at {K_RANGE[1]:g} x "
                         f"its rate, under 5 % of the estimator's first wear stage ({first_stage:,.0f} cycles): no wear "
                         "it can tell; expected whole cycles (were they typed in thousands?)")
    if move is not None and not drift:
        raise ValueError("track: a measured move (move=...) is part of the drift: drift=False leaves it nowhere")
    if not 0 <= depth_spread < 1:
        raise ValueError(f"track: depth_spread = {depth_spread}: expected a lognormal sd in [0, 1)")
    if rate_spread is not None and not 0 <= rate_spread < 1:
        raise ValueError(f"track: rate_spread = {rate_spread}: expected a lognormal sd in [0, 1)")
    rate = move.rate if rate_spread is None and move is not None else None
    rate_spread = None if rate is not None else RATE_SPREAD if rate_spread is None else float(rate_spread)
    labels = list(labels or [f"session {i + 1}" for i in range(len(features))])
    gc = model.grid_c
    ks = np.geomspace(*K_RANGE, factors)
    runs = np.asarray(cycles_run, float)
    xbars = np.stack([f.values.mean(axis=0) for f in features])
    # uniform in c, log-uniform in k (uniform on this grid)
    log_post, inside = _life_log_likelihood(xbars, [f.cycles for f in features], runs, model, ks, drift, move)
    step = np.log(ks[1] / ks[0])
    log_post = (_spread_rate(log_post, inside, step, rate_spread) if rate is None
                else _spread_rate(log_post, inside, step, rate.at(gc)[1], rate.at(gc)[0]))
    post = np.exp(log_post - special.logsumexp(log_post))
    p_life, p_alone = _consistency_at_mode(post, xbars, [f.cycles for f in features], runs, model, ks, drift, move)
    c_int = Interval.from_weights(gc, post.sum(axis=1))
    k_int = Interval.from_weights(np.log(ks), post.sum(axis=0)).map(np.exp)
    coef = k_int.map(lambda v: v * coefficient)
    n_curve, d_curve = depth_curve(model)
    nodes, qw = np.polynomial.hermite_e.hermegauss(9 if depth_spread > 0 else 1)
    deltas, qw = np.exp(depth_spread * nodes), qw / qw.sum()  # the bench's depth / the trajectory's
    weights = post[:, :, None] * qw  # (c, k, delta)

    def depth_at(n: float) -> Interval:
        d = np.stack([np.interp(ks * n, n_curve, d_curve[i]) for i in range(gc.size)])
        return Interval.from_weights((d[:, :, None] * deltas).ravel(), weights.ravel())

    depth = [depth_at(n) for n in cycles_run]
    to_limit, beyond, notes, ahead = None, 0.0, [], None
    if limit is not None:
        need = (limit - gc)[:, None] / deltas[None, :]  # (c, delta) trajectory depth that reaches the limit
        eff_limit = np.array([[np.interp(v, d_curve[i], n_curve, right=np.inf) if v > 0 else 0.0 for v in need[i]]
                              for i in range(gc.size)])
        cycles = eff_limit[:, None, :] / ks[None, :, None]  # (c, k, delta)
        finite = np.isfinite(cycles)
        beyond = float(weights[~finite].sum())
        if beyond < 0.5:
            to_limit = Interval.from_weights(cycles[finite], weights[finite])
        if beyond > 0.05:
            notes.append(f"{beyond:.0%} of the posterior reaches the limit beyond {n_curve[-1]:,.0f} effective cycles "
                         f"({EXTEND:g}x the estimator's range): the interval's upper end is a lower bound")
        ahead = limit_ahead(cycles, eff_limit[:, None, :] <= model.grid_n[-1], weights, max(cycles_run))
    horizon = max(1.5 * max(cycles_run), 1.2 * to_limit.hi90 if to_limit else 0.0)
    prediction = [(float(n), depth_at(n)) for n in np.linspace(0.0, horizon, 41)]
    worn = int(np.sum(np.unique(runs) > 0))
    if worn < 3 and (runs == 0).any() and move is None:
        notes.append(f"{worn} worn cycles-run value{'s' if worn > 1 else ''} and no measured move from new to worn: the "
                     "wear coefficient rests on the change from new alone, where the estimator's own error of that "
                     "change biases it (on simulated lives its 90 % interval held the truth in 0.60-0.75 of them); "
                     "an estimator with a measured move ('wearbench estimator --lives N') corrects it, sessions at "
                     "four or more cycles-run values tell it from the slope")
    edge = post[:, :3].sum() + post[:, inside][:, -3:].sum()  # the lowest and the highest factors allowed
    if edge > 0.1:
        notes.append(f"the wear coefficient's posterior reaches the edge of {K_RANGE[0]}-"
                     f"{min(K_RANGE[1], float(ks[inside][-1])):.3g} x the file's (the last session's cycles run times "
                     "the factor must lie within the estimator's range)")
    return Track(labels, [float(n) for n in cycles_run], c_int, k_int, coef, depth, limit, to_limit, beyond,
                 prediction, notes, move.to_dict() if move is not None else None, rate_spread, p_life, p_alone,
                 ahead, float(model.grid_n[-1]))


def _consistency_at_mode(post: np.ndarray, xbars: np.ndarray, cycles: Sequence[int], runs: np.ndarray,
                         model: EstimatorModel, ks: np.ndarray, drift: bool, move: Move | None
                         ) -> tuple[float, list[float]]:
    """:func:`life_consistency` at the posterior's mode (c, k) with the likelihood's drift and move."""
    i, j = np.unravel_index(int(np.argmax(post)), post.shape)
    means = model.mean(np.full(runs.shape, model.grid_c[i]), ks[j] * runs)
    worn, cov = None, None
    if drift:
        worn, cov = (runs > 0).astype(float), wear_drift(model)
        if move is not None:
            means, cov = means + (runs > 0)[:, None] * move.mean, cov + move.covariance
    return life_consistency(model, xbars, cycles, means, worn, cov)


def life_rate(model: EstimatorModel, lives: Sequence[tuple[np.ndarray, Sequence[float], float, float]],
              move: Move | None, *, cycles: int, factors: int = 161) -> Rate:
    """The features' rate along a life against the initial clearance (:class:`~track_move.Rate`),
    measured on lives of known truth, each ``(session means (S, p), cycles run (S,), initial clearance,
    wear factor)`` with sessions of ``cycles`` cycles, tracked with ``move``: of a small family, the
    rate under which ``track`` gives the true factor the highest mean log posterior density over the
    lives (how ``RATE_SPREAD`` was chosen). The family: knots at the lives' lowest, middle and highest
    clearance; the log-mean 0 at the lowest (the estimator's rate) and 0 to -0.2 at the middle, 0 to
    -0.6 at the highest; the sd 0.1-0.25 at the lowest, growing by 0-0.2 to the highest (linear). The
    constant ``RATE_SPREAD`` is its first member and wins ties."""
    if len(lives) < 3:
        raise ValueError(f"life_rate: {len(lives)} lives: at least three are needed")
    ks = np.geomspace(*K_RANGE, factors)
    step, gc = np.log(ks[1] / ks[0]), model.grid_c
    grids = [(*_life_log_likelihood(np.asarray(x, float), [cycles] * len(runs), np.asarray(runs, float), model, ks,
                                    True, move), np.log(k)) for x, runs, _, k in lives]
    cs = np.array([c for *_, c, _ in lives])
    knots = (float(cs.min()), float(0.5 * (cs.min() + cs.max())), float(cs.max()))
    if knots[0] == knots[-1]:
        raise ValueError(f"life_rate: every life starts at {knots[0] * 1e3:.3f} mm: the rate against clearance "
                         "needs lives at several clearances")
    family = [Rate(knots, (0.0, 0.0, 0.0), (RATE_SPREAD,) * 3)]
    for s0, ds, m1, m2 in itertools.product((0.1, 0.15, 0.2, 0.25), (0.0, 0.1, 0.2), (0.0, -0.1, -0.2),
                                            (0.0, -0.2, -0.4, -0.6)):
        family.append(Rate(knots, (0.0, m1, m2), (s0, s0 + ds / 2, s0 + ds)))
    best, best_score = family[0], -np.inf
    for rate in family:
        mean, sd = rate.at(gc)
        kernel = _rate_kernel(step, ks.size, sd, mean)
        score = 0.0
        for log_lik, inside, truth in grids:
            post = _spread_rate_rows(log_lik, inside, step, sd, mean, kernel)
            pk = np.exp(post - special.logsumexp(post)).sum(axis=0)
            score += np.log(max(np.interp(truth, np.log(ks), pk) / step, 1e-300))
        if score > best_score + 1e-9:
            best, best_score = rate, score
    return best
